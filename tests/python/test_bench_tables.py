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


def test_each_real_time_row_carries_the_platform_timer_of_its_own_run():
    """A real-time figure stands beside the platform timer measured in the same invocation: the
    haptic loop's row takes its p99 from the haptic run's JSON, not another run's."""
    bt = load_tool()
    rt = json.loads((TOP / "docs" / "bench" / "realtime.json").read_text())
    changed = copy.deepcopy(rt)
    changed["runs"]["haptic"]["platform_timer"]["p99_us"] = 987.6
    rows = [line for line in bt.realtime(changed).splitlines() if "hapticloth-bench haptic --json" in line]
    assert len(rows) == 1 and "/ 987.6 /" in rows[0], rows
    timer_row = next(line for line in bt.realtime(changed).splitlines() if "timer --json" in line)
    assert "987.6" not in timer_row


def test_stability_rows_count_restored_steps_and_failed_runs():
    bt = load_tool()
    st = json.loads((TOP / "docs" / "bench" / "stability.json").read_text())
    changed = copy.deepcopy(st)
    changed["random"][0].update(restores=3, max_penetration_mm=7.4, **{"pass": False})
    row = next(line for line in bt.stability(changed).splitlines() if "random run, seed" in line)
    assert "| 1 | 0 | 3 | deepest 7.400 mm |" in row, row


def test_peers_rows_mark_unstable_runs_and_name_the_server_commit():
    bt = load_tool()
    peers = json.loads((TOP / "docs" / "bench" / "peers.json").read_text())
    changed = copy.deepcopy(peers)
    changed["commit"] = "abc1234"
    first = changed["results"][0]
    at_1ms = next(r for r in first["runs"] if abs(r["dt_ms"] - 1.0) < 1e-9)
    at_1ms.update(stable=False, cpu_s_per_sim_s=9.87)
    text = bt.peers(changed)
    row = text.splitlines()[2]
    assert row.startswith(f"| {first['simulator']} {first['variant']} |"), row
    assert "(9.87, unstable)" in row, row
    assert "our server at abc1234" in text


def test_fine_cloth_rows_follow_each_cloth():
    bt = load_tool()
    fine = json.loads((TOP / "docs" / "bench" / "fine-cloth.json").read_text())
    rows = bt.fine_cloth(fine).splitlines()[2:]
    assert [r.split(" |")[0] for r in rows] == [f"| {n} triangles" for n in sorted(fine["runs"], key=int)]
    changed = copy.deepcopy(fine)
    response = next(r for r in changed["runs"]["968"]["runs"] if r["run"] == "multirate response")
    response.update(force_err_rel=0.4321, max_gap_mm=9.87)
    assert "43.2% / 9.87 mm" in bt.fine_cloth(changed).splitlines()[2]
