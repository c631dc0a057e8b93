"""hapticloth-server stopped by SIGINT or SIGTERM (issue 14): at a seeded random moment of a
real-time mock session, a `--fast` mock session and a real-time UDP session with the fake rig
pressing the cloth, the server ends the session at its next haptic tick and exits 0 within a
few seconds, with

- its summary, ending in `stopped  by SIG... after X s of Y s` (JSON: "stopped");
- the LCM log readable by lcm.EventLog to its last byte, every haptic tick of the session in
  it, and the `started`, `stopping` (naming the signal) and final `stopped` events;
- the device record CSV complete: every row well-formed, as many rows as the summary counts,
  the last within 10 ms of the stop (the session time, haptic ticks / rate, which X gives to 4
  significant digits), the last command zero force (mock);
- for the UDP rig: exactly zero force in the last packet it received.

A second signal while the first is being handled exits at once with 128 + signal and no
summary; a server started with SIGINT ignored (a background job of a non-interactive shell)
still stops on SIGINT.

The moment is random.Random(seed) per case, 1.0-3.0 s after the preroll (the first `stage`
line); HAPTICLOTH_TEST_SEED changes the seed. Network: 127.0.0.1 only.
"""

from __future__ import annotations

import csv
import json
import math
import os
import random
import re
import signal
import shutil
import socket
import subprocess
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

from server_session import (RECORD_HEADER, Rig, Server, free_port, haptic_samples, read_lcm_log,
                            wait_for_program, wait_until, write_trajectory)

REPO = Path(__file__).resolve().parents[2]

SEED = int(os.environ.get("HAPTICLOTH_TEST_SEED", "14"))
FINGERS = 2
RECORD_SLACK_S = 0.010  # the record is complete to within 10 ms of the stop (issue 14)
HAPTIC_RATE = 1000.0    # Hz, the scene's [haptics] rate: the session time is ticks / rate

# The rig's press (device frame: the hanging cloth in the y = 0 plane, fingertip radius 8 mm):
# finger 0 from 4 cm in front of the cloth to 6 mm into it by 0.8 s, then held; finger 1 stays
# 5 cm behind. The signal comes 1.0-3.0 s after the rig starts, while it presses.
PRESS = {0: [(0.0, (-0.02, -0.04, 0.0)), (0.3, (-0.02, -0.04, 0.0)), (0.8, (-0.02, -0.002, 0.0))],
         1: [(0.0, (0.06, 0.05, 0.0))]}
RIG_SECONDS = 4.5

# Each case: the server's options (besides the scene, the LCM log and the record), whether the
# rig is attached, and whether the session runs in real time.
CASES = {
    "mock-realtime": dict(args=["--device", "mock", "--duration", "20"], rig=False, realtime=True),
    "mock-fast-json": dict(args=["--device", "mock", "--duration", "1000", "--fast", "--json"],
                           rig=False, realtime=False),
    "udp-realtime-rig": dict(args=["--device", "udp", "--duration", "20"], rig=True, realtime=True),
}
SIGNALS = {"SIGINT": signal.SIGINT, "SIGTERM": signal.SIGTERM}

TEXT_LINES = ("haptic ticks", "sim steps", "contact ticks", "out of reach", "fingertip contact",
              "scheduling", "device counters", "safety gate", "cloth events", "trajectory cmds",
              "device record", "stopped")
JSON_KEYS = ("haptic_ticks", "sim_steps", "contact_ticks", "contact_samples", "max_force_n",
             "device_counters", "gate", "integrator_events", "trajectory_commands", "record",
             "stopped")
STOPPED = re.compile(r"by (SIGINT|SIGTERM) after (\S+) s of (\S+) s")


def option(args, name):
    return args[args.index(name) + 1]


def parse_summary(stdout: str, as_json: bool) -> dict:
    """The figures these tests need from either summary format, after checking that its usual
    lines (keys) are all there once."""
    if as_json:
        j = json.loads(stdout.strip().splitlines()[-1])
        missing = [k for k in JSON_KEYS if k not in j]
        assert not missing, f"summary without {missing}: {j}"
        stopped, rec = j["stopped"], j["record"]
        assert rec["error"] is None, rec
        ticks, rec_path, rows, dropped = j["haptic_ticks"], rec["path"], rec["rows"], rec["dropped"]
        missed = j["missed_deadlines"]
    else:
        lines = stdout.splitlines()
        for name in TEXT_LINES:
            n = sum(1 for ln in lines if ln.startswith(name + " "))
            assert n == 1, f"{n} '{name}' lines in the summary:\n{stdout}"
        assert lines[-1].startswith("stopped "), f"no `stopped` line last:\n{stdout}"
        stopped = lines[-1][len("stopped"):].strip()
        m = re.search(r"^haptic ticks +(\d+) \((\d+) missed deadlines\)", stdout, re.M)
        ticks, missed = int(m.group(1)), int(m.group(2))
        m = re.search(r"^device record +(.+): (\d+) rows, (\d+) dropped \(buffer full\)$", stdout,
                      re.M)
        assert m, f"no device record line:\n{stdout}"
        rec_path, rows, dropped = m.group(1), int(m.group(2)), int(m.group(3))
    assert isinstance(stopped, str), f"no `stopped` in the summary:\n{stdout}"
    m = STOPPED.fullmatch(stopped)
    assert m, f"stopped: '{stopped}'"
    # The session time at the stop: the deadlines passed, the ticks run and those a late wake-up
    # skipped (counted among the missed deadlines), printed in ms.
    return {"signal": m.group(1), "after": float(m.group(2)), "of": float(m.group(3)),
            "ticks": ticks, "missed": missed, "stop": float(m.group(2)),
            "record_path": rec_path, "record_rows": rows, "record_dropped": dropped}


def check_record(path: Path, stop_time: float, rows_counted: int) -> list[list[str]]:
    """The device record is complete: a newline-terminated CSV with the documented header, one
    row per finger per sample (fingers in order, one time), every field a finite number, times
    never going back, as many rows as the summary counted, the last within 10 ms of the stop."""
    text = path.read_text()
    assert text.endswith("\n"), f"{path}: the last row is cut: {text[-200:]!r}"
    rows = list(csv.reader(text.splitlines()))
    assert rows[0] == RECORD_HEADER, rows[0]
    data = rows[1:]
    assert len(data) == rows_counted, f"{path}: {len(data)} rows, the summary says {rows_counted}"
    assert data and len(data) % FINGERS == 0, len(data)
    last_t = -math.inf
    for i, r in enumerate(data):
        where = f"{path}:{i + 2}: {r}"
        assert len(r) == len(RECORD_HEADER), where
        values = [float(v) for v in r]  # ValueError: not a number
        assert all(math.isfinite(v) for v in values), where
        assert int(r[1]) == i % FINGERS and int(r[8]) >= 0, where
        t = values[0]
        if i % FINGERS:
            assert t == float(data[i - 1][0]), where  # the fingers of one sample
        assert t >= last_t, where
        last_t = t
    assert abs(last_t - stop_time) <= RECORD_SLACK_S, \
        f"{path}: last row at {last_t} s, the session stopped at {stop_time} s"
    return data


def check_lcm_log(path: Path, summary: dict) -> list[dict]:
    """Readable to its end; every haptic tick of the session in it (ticks 1..N, the last within
    10 ms of the stop), then the wind-down's ticks (at most 200, Session::kWindDownTicks) that
    fade the force to zero through the safety gate, the last of them within the gate's ramp
    (20 ms) of the stop and commanding exactly zero force on every finger (issue 36 item 4);
    `started`, then `stopping` naming the signal, and `stopped` last."""
    events = read_lcm_log(path)
    samples = haptic_samples(events)
    assert samples, f"{path}: no event on the haptics channel"
    ticks = [s["tick"] for s in samples]
    n = summary["ticks"]
    assert n < len(ticks) <= n + 200 and ticks == list(range(1, len(ticks) + 1)), \
        f"{path}: haptic ticks {ticks[:3]}..{ticks[-3:]} ({len(ticks)}), " \
        f"the summary counts {n}"
    assert abs(samples[n - 1]["time"] - summary["stop"]) <= RECORD_SLACK_S, \
        (samples[n - 1]["time"], summary)
    assert samples[-1]["time"] - summary["stop"] <= RECORD_SLACK_S + 0.020, (samples[-1], summary)
    assert all(c == (0.0, 0.0, 0.0) for c in samples[-1]["command"][:FINGERS]), samples[-1]
    kinds = [(m.kind, m.text) for topic, m in events if topic == "events"]
    assert kinds[0][0] == "started", kinds
    stopping = [text for kind, text in kinds if kind == "stopping"]
    assert len(stopping) == 1 and f"by {summary['signal']} after" in stopping[0], kinds
    assert kinds[-1][0] == "stopped", kinds
    return samples


def record_clock_offset(case: dict, samples: list[dict]) -> float:
    """Loop time of the record's time 0. The UDP driver records on the loop clock; the mock
    records its script time, 0 at its first read, the first haptic tick, which in real time
    starts late by up to tens of ms (a session's first tick waits for its threads)."""
    return 0.0 if case["rig"] else samples[0]["time"]


def run_and_signal(case: str, signame: str, tmp_path: Path,
                   background: bool = False) -> SimpleNamespace:
    """Runs one case and sends the signal at a seeded random moment 1.0-3.0 s after the preroll.
    Returns srv (the Server), s (the summary's figures), delay (s after the preroll), rig (its
    summary and forces, or None) and `where` (what to print on a failure)."""
    c = CASES[case]
    rng = random.Random(f"{SEED}:{case}:{signame}:{background}")
    delay = rng.uniform(1.0, 3.0)
    port = free_port()
    args = list(c["args"]) + ["--record", tmp_path / "record.csv",
                              "--zenoh-listen", f"tcp/127.0.0.1:{free_port(socket.SOCK_STREAM)}"]
    if c["rig"]:
        args += ["--udp-bind", f"127.0.0.1:{port}"]
    rig = None
    launched = time.monotonic()
    with Server(*args, cwd=tmp_path, lcm_log=tmp_path / "session.lcm",
                inherit_ignored_signals=background) as srv:
        ready = srv.wait_ready()
        rig_run = Rig(port, write_trajectory(tmp_path / "press.csv", PRESS), RIG_SECONDS,
                      tmp_path / "rig_forces.csv") if c["rig"] else None
        try:
            time.sleep(max(0.0, ready + delay - time.monotonic()))
            t_signal = time.monotonic()
            srv.signal(SIGNALS[signame])
            rc = srv.finish(seconds=30)
            t_exit = time.monotonic()
            took = t_exit - t_signal
            if rig_run:
                rig = SimpleNamespace(summary=rig_run.finish(), forces=rig_run.forces())
        finally:
            if rig_run:
                rig_run.kill()
    where = (f"{case} {signame} at {delay:.3f} s (seed {SEED}): exit {rc}\n{srv.stdout}\n"
             f"{srv.stderr[-3000:]}")
    assert rc == 0, where
    # A safety limit, not a figure: the stop must not hang (the wind-down is at most 200 ticks).
    assert took < 5.0, f"{took:.2f} s from the signal to the exit; " + where
    # The session started after the launch, and at most the threads' start-up (tens of ms;
    # 0.25 s allowed) after its stage lines were seen; it was signalled at t_signal and ended
    # before the exit: the session times the signal can have come at.
    return SimpleNamespace(srv=srv, s=parse_summary(srv.stdout, srv.json), delay=delay, rig=rig,
                           where=where, signal_after=(t_signal - ready - 0.25, t_exit - launched))


@pytest.mark.parametrize("signame", SIGNALS)
@pytest.mark.parametrize("case", CASES)
def test_a_signal_stops_the_session_cleanly(case, signame, tmp_path):
    c = CASES[case]
    run = run_and_signal(case, signame, tmp_path)
    s, where = run.s, run.where

    # The summary names the signal and the moment.
    assert s["signal"] == signame, where
    assert s["of"] == float(option(c["args"], "--duration")), where
    assert 0.0 < s["after"] < s["of"], where
    # X is the session time in ms: at least the ticks run, at most those and the skipped ones.
    assert s["ticks"] / HAPTIC_RATE - 0.0005 <= s["after"], where
    assert s["after"] <= (s["ticks"] + s["missed"]) / HAPTIC_RATE + 0.0015, where
    if c["realtime"]:  # the session stopped at the signal, on the session's own clock
        earliest, latest = run.signal_after
        assert earliest <= s["stop"] <= latest, (run.signal_after, where)

    # The LCM log: every event readable, every haptic tick in it, the stop events.
    samples = check_lcm_log(tmp_path / "session.lcm", s)

    # The device record: complete to within 10 ms, every row well-formed, nothing dropped.
    assert Path(s["record_path"]) == tmp_path / "record.csv", where
    assert s["record_dropped"] == 0, where
    rows = check_record(tmp_path / "record.csv", s["stop"] - record_clock_offset(c, samples),
                        s["record_rows"])
    if not c["rig"]:
        # The mock records every command: the last is zero force on every finger.
        assert all(float(v) == 0.0 for r in rows[-FINGERS:] for v in r[9:12]), rows[-FINGERS:]

    if run.rig:
        # The rig pressed the cloth up to the signal, and the last force it got is exactly zero.
        summary, packets = run.rig.summary, run.rig.forces
        assert summary["forces_received"] > 0 and summary["forces_nonfinite"] == 0, summary
        assert max(math.hypot(*p["forces"][0]) for p in packets) > 1e-4, "the rig felt nothing"
        assert samples[-1]["in_contact"][0], f"finger 0 not on the cloth at the signal; {where}"
        last = packets[-1]["forces"]
        assert all(v == 0.0 for f in last for v in f), f"the rig's last force: {last}"


def test_sigint_stops_a_server_started_with_sigint_ignored(tmp_path):
    # A background job of a non-interactive shell (`server &`) starts with SIGINT and SIGTERM
    # ignored; the server installs its handler over that.
    run = run_and_signal("mock-realtime", "SIGINT", tmp_path, background=True)
    s = run.s
    assert s["signal"] == "SIGINT", run.where
    earliest, latest = run.signal_after
    assert earliest <= s["stop"] <= latest, (run.signal_after, run.where)
    samples = check_lcm_log(tmp_path / "session.lcm", s)
    offset = record_clock_offset(CASES["mock-realtime"], samples)
    check_record(tmp_path / "record.csv", s["stop"] - offset, s["record_rows"])


def second_signal_during_wind_down(first, second, tmp_path):
    """Starts a server, sends `first` once it runs and `second` as soon as a handler took the
    first. Returns (exit status, seconds from the second signal to the exit, stdout, stderr)."""
    with Server("--device", "mock", "--duration", "20", "--no-zenoh",
                "--record", tmp_path / "record.csv", cwd=tmp_path,
                lcm_log=tmp_path / "session.lcm") as srv:
        srv.wait_ready()
        time.sleep(1.0)
        srv.signal(first)
        assert srv.signal_delivered(first), "the first signal not taken, or the server exited"
        if srv.p.poll() is None:  # else it ended in order before the second could be sent
            srv.p.send_signal(second)
        t = time.monotonic()
        rc = srv.finish(seconds=30)
        took = time.monotonic() - t
    return rc, took, srv.stdout, srv.stderr


@pytest.mark.parametrize("first,second", [(signal.SIGINT, signal.SIGINT),
                                          (signal.SIGTERM, signal.SIGTERM),
                                          (signal.SIGINT, signal.SIGTERM)],
                         ids=["SIGINT-SIGINT", "SIGTERM-SIGTERM", "SIGINT-SIGTERM"])
def test_a_second_signal_exits_at_once(first, second, tmp_path):
    # The wind-down without contact takes a few ms (a tick, the files closed, the summary): a
    # test process held up that long sends the second signal after the server has already
    # ended in order, exit 0 with its whole summary. That is the right end for a signal that
    # came late, not the case under test, so the attempt is repeated (at most 4 times); a
    # handler that ignored the second signal would end every attempt that way.
    # Likewise a second signal that lands after the summary was printed (the server tearing down
    # its threads): it exits at once, 128 + signal, but the orderly end was all but done.
    for attempt in range(4):
        folder = tmp_path / f"attempt{attempt}"
        folder.mkdir()
        rc, took, out, err = second_signal_during_wind_down(first, second, folder)
        if rc != 0 and "stopped" not in out:
            break
        assert rc in (0, 128 + second), f"exit {rc}\n{out}\n{err[-2000:]}"
        assert f"stopped          by {signal.Signals(first).name}" in out, out
    assert rc == 128 + second, f"exit {rc} in each of 4 attempts\n{out}\n{err[-2000:]}"
    assert took < 2.0, took  # a safety limit; that it was _exit is the missing summary below
    # _exit: none of the orderly end (the summary is never printed).
    assert "haptic ticks" not in out and "stopped" not in out, out


def handler_installed(pid: int, sig: int) -> bool:
    """True once the process catches `sig` (/proc/PID/status SigCgt): its main has started."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    m = re.search(r"^SigCgt:\s*([0-9a-f]+)$", status, re.M)
    return m is not None and bool(int(m.group(1), 16) & (1 << (sig - 1)))


def signal_once_running(cmd, cwd, sig, after=0.0):
    """Starts `cmd`, sends `sig` `after` s once its main catches it (bounded waits); returns
    (exit status, stdout, stderr)."""
    p = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert wait_until(lambda: handler_installed(p.pid, sig) or p.poll() is not None, 10.0)
        time.sleep(after)
        p.send_signal(sig)
        stdout, stderr = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
            p.communicate()
    return p.returncode, stdout, stderr


def scene_of(tmp_path: Path, resolution: int, preroll: float) -> Path:
    """The hanging square at `resolution` x `resolution` quads with the given preroll, beside
    copies of the scenes' script and materials."""
    for folder in ("scenes", "materials"):
        shutil.copytree(REPO / "tools" / folder, tmp_path / folder, dirs_exist_ok=True)
    text = (REPO / "tools" / "scenes" / "hanging_square.toml").read_text()
    text = re.sub(r"(?m)^resolution = \[\d+, \d+\]", f"resolution = [{resolution}, {resolution}]", text)
    text = re.sub(r"(?m)^preroll = [0-9.]+", f"preroll = {preroll}", text)
    path = tmp_path / "scenes" / f"square_{resolution}.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM"])
def test_a_signal_during_set_up_stops_before_anything_runs(signame, tmp_path):
    """Issue 36 item 7: SIGINT was not honoured while a large mesh was built. A signal during
    set-up (here: building a 80000-triangle cloth, opening the transports) ends the server
    there: exit 0, one line on stderr, no stage line, no session, and neither the record nor the
    LCM log its claims created is left behind."""
    scene = scene_of(tmp_path, 200, preroll=600.0)
    out = tmp_path / "out"
    out.mkdir()
    cmd = [str(wait_for_program("hapticloth-server")), "--scene", str(scene), "--device", "mock",
           "--no-zenoh", "--record", str(out / "record.csv"), "--lcm-log", str(out / "session.lcm")]
    rc, stdout, stderr = signal_once_running(cmd, out, SIGNALS[signame])  # the 600 s preroll never starts
    said = f"exit {rc}\nstdout: {stdout}\nstderr: {stderr}"
    assert rc == 0, said
    assert f"hapticloth-server: stopped by {signame} during set-up (nothing ran)" in stderr, said
    assert "stage" not in stdout and "haptic ticks" not in stdout, said
    assert sorted(q.name for q in out.iterdir()) == [], said


@pytest.mark.parametrize("as_json", [False, True], ids=["text", "json"])
def test_sigterm_stops_a_headless_run_with_its_summary(as_json, tmp_path):
    """Issue 36 item 13: --headless ended with status 143 and no summary on SIGTERM. It stops at
    its next step and prints the summary of the steps it ran, saying so, and exits 0."""
    scene = scene_of(tmp_path, 40, preroll=0.0)
    cmd = [str(wait_for_program("hapticloth-server")), "--scene", str(scene), "--headless",
           "--duration", "100000"] + (["--json"] if as_json else [])
    rc, stdout, stderr = signal_once_running(cmd, tmp_path, signal.SIGTERM, after=1.0)  # steps run
    said = f"exit {rc}\nstdout: {stdout}\nstderr: {stderr}"
    assert rc == 0, said
    asked = round(100000 / 0.001)  # the scene's dt: 1 ms
    if as_json:
        j = json.loads(stdout)
        steps, stopped, finite = j["steps"], j["stopped"], j["finite"]
    else:
        steps = int(re.search(r"^steps +(\d+) ", stdout, re.M).group(1))
        stopped = re.search(r"^stopped +(.+)$", stdout, re.M).group(1)
        finite = "state finite     yes" in stdout
    assert 0 < steps < asked and finite, said
    assert stopped == f"by SIGTERM after {steps} of {asked} steps", said
