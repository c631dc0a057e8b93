"""tools/bench-tables: BENCHMARKS.md's marked tables are what the benchmarks' JSON in docs/bench/
gives, row for row; a changed figure in the JSON changes the table; a broken marker or a missing
JSON is refused with the file named."""

from __future__ import annotations

import copy
import importlib.machinery
import importlib.util
import json
import pathlib
import subprocess
import sys

import pytest

TOP = pathlib.Path(__file__).resolve().parents[2]
TOOL = TOP / "tools" / "bench-tables"


def load_tool():
    loader = importlib.machinery.SourceFileLoader("bench_tables", str(TOOL))
    spec = importlib.util.spec_from_loader("bench_tables", loader)
    module = importlib.util.module_from_spec(spec)
    loader.exec_module(module)
    return module


def test_benchmarks_md_is_what_the_json_gives():
    r = subprocess.run([sys.executable, str(TOOL), "--check"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr


def test_a_changed_figure_changes_its_row():
    bt = load_tool()
    fidelity = json.loads((TOP / "docs" / "bench" / "fidelity.json").read_text())
    before = bt.fidelity_drum(fidelity)
    changed = copy.deepcopy(fidelity)
    changed["drum"][0]["points"][0]["error"] = 0.1234
    after = bt.fidelity_drum(changed)
    assert "+12.34%" in after and "+12.34%" not in before
    assert after.count("\n") == before.count("\n")  # the same rows


def test_late_ticks_rows_follow_the_cases():
    bt = load_tool()
    late = json.loads((TOP / "docs" / "bench" / "late-ticks.json").read_text())
    rows = bt.late_ticks(late).splitlines()[2:]
    assert len(rows) == len(late["cases"])
    first = late["cases"][0]
    assert rows[0].startswith(f"| {first['name']} | {first['late_ms']:g} |")


def test_a_broken_marker_is_refused_naming_the_file(tmp_path):
    bt = load_tool()
    text = (TOP / "BENCHMARKS.md").read_text()
    with pytest.raises(SystemExit) as e:
        bt.render(text.replace("<!-- table late-ticks -->", "<!-- table late-tick -->"), doc="B.md")
    assert "B.md" in str(e.value) and "late-tick" in str(e.value)
    with pytest.raises(SystemExit) as e:
        bt.render(text.replace("<!-- table late-ticks -->", ""), doc="B.md")
    assert "B.md" in str(e.value)
