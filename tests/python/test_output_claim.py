"""Two servers given the same output files (server/app/output_claim.cpp, issue 36 item 1): the
second stops at once, before its preroll, with exit 2 and an error naming the option and the
path, and the first session's LCM log and device record are left whole: lcm.EventLog reads the
log to its last byte, from `started` to `stopped`, and the record's time never runs backwards.
The same holds for the default log path, out/<scene>.lcm, which two servers in one folder share.

Network: 127.0.0.1 only; every wait bounded.
"""

from __future__ import annotations

import csv
import signal
import time
from pathlib import Path

from server_session import RECORD_HEADER, Server, read_lcm_log

MOCK = ("--device", "mock", "--duration", "20", "--no-zenoh")


def record_rows(path: Path) -> list[list[str]]:
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    assert rows and rows[0] == RECORD_HEADER, f"{path}: header {rows[:1]}"
    return rows[1:]


def refused(server: Server, what: str) -> None:
    """The second server exits 2 within a few seconds (the first's preroll takes 6 s) and says
    which of its files another session is writing."""
    t0 = time.monotonic()
    rc = server.finish(seconds=30)
    took = time.monotonic() - t0
    assert rc == 2, f"exit {rc}:\n{server.stdout}\n{server.stderr}"
    assert f"{what}: another running session is writing it" in server.stderr, server.stderr
    # A safety limit (the claim comes before a preroll of seconds; the missing stage line below says so)
    assert took < 5.0, f"refused only after {took:.1f} s (after its preroll)"
    assert "stage" not in server.stdout


def test_a_second_server_is_refused_the_log_and_record_the_first_writes(tmp_path):
    log, rec = tmp_path / "shared.lcm", tmp_path / "shared.csv"
    with Server(*MOCK, "--record", rec, cwd=tmp_path, lcm_log=log) as first:
        first.wait_ready()
        time.sleep(0.5)
        with Server(*MOCK, "--record", rec, cwd=tmp_path, lcm_log=log) as second:
            refused(second, f"--lcm-log {log}")
        with Server(*MOCK, "--record", rec, cwd=tmp_path, lcm_log=tmp_path / "own.lcm") as third:
            refused(third, f"--record {rec}")
        time.sleep(0.5)
        first.signal(signal.SIGINT)
        assert first.finish() == 0, first.stderr
    events = read_lcm_log(log)  # whole: every event decodes, none cut
    kinds = [m.kind for topic, m in events if topic == "events"]
    assert kinds[0] == "started" and kinds[-1] == "stopped", kinds
    rows = record_rows(rec)
    assert len(rows) > 1000
    for finger in ("0", "1"):
        times = [float(r[0]) for r in rows if r[1] == finger]
        assert all(b >= a for a, b in zip(times, times[1:])), f"finger {finger}: time runs backwards"


def test_two_servers_in_one_folder_do_not_share_the_default_log(tmp_path):
    with Server(*MOCK, cwd=tmp_path) as first:
        first.wait_ready()
        with Server(*MOCK, cwd=tmp_path) as second:
            refused(second, "the LCM log (--lcm-log) out/hanging_square.lcm")
        first.signal(signal.SIGINT)
        assert first.finish() == 0, first.stderr
    read_lcm_log(tmp_path / "out" / "hanging_square.lcm")
