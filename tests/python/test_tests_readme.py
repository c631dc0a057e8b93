"""Every source in server/ and devices/ has a test named after it (tests/*/test_NAME.cpp or
tests/python/test_NAME.py), or a line in tests/README.md saying which test covers it; and every
test that README names exists."""

from __future__ import annotations

import pathlib
import re

TOP = pathlib.Path(__file__).resolve().parents[2]
README = TOP / "tests" / "README.md"


def sources() -> list[pathlib.Path]:
    found = []
    for folder in ("server", "devices"):
        found += [p for p in (TOP / folder).rglob("*.cpp") if "zenoh_bridge" not in p.parts]
    return sorted(found)


def own_test(src: pathlib.Path) -> bool:
    name = src.stem
    return any((TOP / "tests").glob(f"*/test_{name}.cpp")) or (TOP / "tests" / "python" / f"test_{name}.py").exists()


def readme_rows() -> dict[str, str]:
    rows = {}
    for line in README.read_text().splitlines():
        m = re.match(r"\| ((?:server|devices)/\S+\.cpp) \| (.+) \|$", line)
        if m:
            rows[m.group(1)] = m.group(2)
    return rows


def test_every_source_has_a_test_or_a_readme_line():
    rows = readme_rows()
    missing = [str(s.relative_to(TOP)) for s in sources() if not own_test(s) and str(s.relative_to(TOP)) not in rows]
    assert not missing, f"no test_NAME and no line in {README}: {missing}"


def test_every_readme_line_names_a_source_and_tests_that_exist():
    tests = {p.name for p in (TOP / "tests").rglob("test_*") if p.suffix in (".cpp", ".py")}
    tests |= {p.name for p in (TOP / "tests" / "fuzz").glob("*.cpp")}
    rows = readme_rows()
    assert len(rows) > 20
    for src, covered in rows.items():
        assert (TOP / src).exists(), f"{README}: {src} does not exist"
        named = re.findall(r"\b((?:test|fuzz)_\w+\.(?:cpp|py))", covered)
        assert named, f"{README}: {src} names no test"
        for t in named:
            assert t in tests, f"{README}: {src}: {t} does not exist"
