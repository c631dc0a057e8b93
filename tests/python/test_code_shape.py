"""The shape the code and docs are held to (issue 38): no function over 80 lines in server/,
devices/, clients/ or tools/ (tools/function-lengths), no file in server/ over 600 lines, and
BENCHMARKS.md and docs/performance.md within 25 and 20 KB. And that the counter finds a long
function when there is one, in C++ and in Python."""

from __future__ import annotations

import pathlib
import subprocess
import sys

TOP = pathlib.Path(__file__).resolve().parents[2]
TOOL = TOP / "tools" / "function-lengths"


def lengths(*args: str, cwd: pathlib.Path = TOP) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(TOOL), *args], cwd=cwd, capture_output=True, text=True, timeout=120)


def test_no_function_over_80_lines():
    r = lengths()
    assert r.returncode == 0, r.stdout
    assert r.stdout.strip().endswith("0 functions over 80 lines")


def test_the_counter_finds_long_functions(tmp_path):
    body = "\n".join(f"  x += {i};" for i in range(85))
    (tmp_path / "long.cpp").write_text(
        "namespace a {\nstruct S {\n  int f() const {\n    return 1;\n  }\n};\n"
        f"int S_g(int x) {{\n{body}\n  return x;\n}}\n}}  // namespace a\n")
    (tmp_path / "long.py").write_text("def f(x):\n" + "\n".join(f"    x += {i}" for i in range(90)) + "\n    return x\n")
    (tmp_path / "short.rs").write_text("fn f(a: &'static str) -> usize {\n    a.len()\n}\n")
    r = lengths(str(tmp_path), "--max", "80", "--json")
    assert r.returncode == 1
    import json
    found = {(pathlib.Path(x["file"]).name, x["function"], x["lines"]) for x in json.loads(r.stdout)}
    assert found == {("long.cpp", "S_g", 88), ("long.py", "f", 92)}, found


def test_no_server_file_over_600_lines():
    long = {str(p.relative_to(TOP)): n for p in (TOP / "server").rglob("*")
            if p.suffix in (".cpp", ".hpp", ".rs") and "target" not in p.parts
            and (n := len(p.read_text().splitlines())) > 600}
    assert not long, long


def test_benchmark_docs_are_short_enough_to_read():
    assert (TOP / "BENCHMARKS.md").stat().st_size <= 25_000
    assert (TOP / "docs" / "performance.md").stat().st_size <= 20_000
