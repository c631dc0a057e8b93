"""Running hapticloth-server as a user does, for the tests of stop signals and device presence
(test_stop_signal.py, test_udp_device.py): the server as a subprocess whose output is read
as it comes, so a test can act at a moment of the session (after the preroll, when the server
has printed its first `stage` line), the fake UDP rig (tools/fake_rig) as a second subprocess,
and readers of what they leave behind (the summary, the LCM log, the rig's force log).

Network: UDP and TCP on 127.0.0.1 only. Every wait is bounded in count and time.
"""

from __future__ import annotations

import csv
import json
import os
import re
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from buildpaths import build_dir, program

REPO = Path(__file__).resolve().parents[2]
SCENE = REPO / "tools" / "scenes" / "hanging_square.toml"
RIG = REPO / "tools" / "fake_rig" / "hapticloth-fake-rig"

#: CSV header of the device record (devices/log/device_log.hpp).
RECORD_HEADER = ["time", "finger", "x", "y", "z", "vx", "vy", "vz", "buttons", "fx", "fy", "fz"]


def free_port(kind=socket.SOCK_DGRAM) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for_program(name: str, seconds: float = 10.0) -> Path:
    """The built program; the build directory may be relinked under the tests for a moment."""
    deadline = time.monotonic() + seconds
    while not (build_dir() / name).is_file() and time.monotonic() < deadline:
        time.sleep(0.5)
    return program(name)


def wait_until(predicate, seconds: float, step: float = 0.01) -> bool:
    """Polls `predicate` every `step` s for at most `seconds` s (and at most that many polls)."""
    for _ in range(int(seconds / step) + 1):
        if predicate():
            return True
        time.sleep(step)
    return bool(predicate())


def has_haptic_sample(log: Path) -> bool:
    """Whether the LCM log (being written) holds an event on the haptics channel yet."""
    import lcm

    try:
        events = lcm.EventLog(str(log), "r")
    except (OSError, IOError):
        return False
    try:
        return any(ev.channel == "HAPTICLOTH_HAPTICS" for ev in events)
    except (OSError, IOError, ValueError):
        return False
    finally:
        events.close()


class Server:
    """hapticloth-server --scene hanging_square.toml ARGS, started at once in `cwd` (the default
    LCM log would land in cwd/out/). Its stdout and stderr are collected by reader threads."""

    def __init__(self, *args, cwd, lcm_log=None, inherit_ignored_signals=False, scene=SCENE):
        self.lcm_log = Path(lcm_log) if lcm_log else None
        self.json = "--json" in args
        cmd = [str(wait_for_program("hapticloth-server")), "--scene", str(scene), *map(str, args)]
        if self.lcm_log:
            cmd += ["--lcm-log", str(self.lcm_log)]

        def ignore_stop_signals():  # as a shell does for a background job (`server &`)
            signal.signal(signal.SIGINT, signal.SIG_IGN)
            signal.signal(signal.SIGTERM, signal.SIG_IGN)

        self.cmd = cmd
        self.p = subprocess.Popen(
            cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            preexec_fn=ignore_stop_signals if inherit_ignored_signals else None)
        self.out_lines: list[str] = []
        self.err_lines: list[str] = []
        self.stage_seen = threading.Event()
        self._readers = [threading.Thread(target=self._read, args=a, daemon=True)
                         for a in ((self.p.stdout, self.out_lines, True),
                                   (self.p.stderr, self.err_lines, False))]
        for t in self._readers:
            t.start()

    def _read(self, stream, lines, watch_stage):
        for line in stream:
            lines.append(line)
            if watch_stage and line.startswith("stage "):
                self.stage_seen.set()

    @property
    def stdout(self) -> str:
        return "".join(self.out_lines)

    @property
    def stderr(self) -> str:
        return "".join(self.err_lines)

    def wait_ready(self, seconds: float = 60.0) -> float:
        """Waits until the preroll is over and the session starts: the first `stage` line (text
        summary) or, with --json (which prints nothing before the end), the LCM log's first
        haptic sample (the log is open from before the preroll, with the scene in it; the
        haptic samples come once the session runs). Returns time.monotonic() at that moment."""
        def ready():
            if self.p.poll() is not None:
                raise AssertionError(f"the server exited ({self.p.returncode}) before its "
                                     f"session:\n{self.stdout}\n{self.stderr[-3000:]}")
            if self.json:
                log = self.lcm_log
                return log is not None and log.is_file() and has_haptic_sample(log)
            return self.stage_seen.is_set()
        assert wait_until(ready, seconds), \
            f"no session in {seconds} s: {self.stdout}{self.stderr}"
        return time.monotonic()

    def signal(self, sig):
        assert self.p.poll() is None, \
            f"the server already exited ({self.p.returncode}): {self.stderr[-2000:]}"
        self.p.send_signal(sig)

    def signal_delivered(self, sig, seconds: float = 0.5) -> bool:
        """True once `sig`, sent to the process, is no longer pending (a handler took it), by
        /proc/PID/status ShdPnd; False if the process ended or it is still pending after
        `seconds`."""
        bit = 1 << (sig - 1)

        def taken():
            try:
                status = Path(f"/proc/{self.p.pid}/status").read_text()
            except OSError:
                return True
            m = re.search(r"^ShdPnd:\s*([0-9a-f]+)$", status, re.M)
            return m is not None and not int(m.group(1), 16) & bit
        return wait_until(taken, seconds, step=0.0002) and self.p.poll() is None

    def finish(self, seconds: float = 60.0) -> int:
        """Waits (bounded) for the server to exit; kills it if it does not. Returns its status."""
        try:
            self.p.wait(timeout=seconds)
        except subprocess.TimeoutExpired:
            self.kill()
            raise AssertionError(f"the server did not exit within {seconds} s:\n{self.stdout}\n"
                                 f"{self.stderr[-3000:]}")
        for t in self._readers:
            t.join(timeout=10)
        return self.p.returncode

    def kill(self):
        if self.p.poll() is None:
            self.p.kill()
            self.p.wait(timeout=10)
        for t in self._readers:
            t.join(timeout=10)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.kill()


def write_trajectory(path: Path, knots: dict) -> Path:
    """A fingertip trajectory CSV (time,finger,x,y,z; m, device frame) for the fake rig or the
    mock device: knots = {finger: [(time, (x, y, z)), ...]}, piecewise-linear per finger."""
    rows = ["time,finger,x,y,z"]
    for finger, points in knots.items():
        rows += [f"{t!r},{finger},{x!r},{y!r},{z!r}" for t, (x, y, z) in points]
    path.write_text("\n".join(rows) + "\n")
    return path


class Rig:
    """tools/fake_rig/hapticloth-fake-rig streaming `trajectory` to the server at 1 kHz for
    `duration` s, logging every force packet it receives to `log`."""

    def __init__(self, port: int, trajectory: Path, duration: float, log: Path, *extra):
        self.log = Path(log)
        self.duration = duration
        self.p = subprocess.Popen(
            [sys.executable, str(RIG), "--server", f"127.0.0.1:{port}", "--duration", str(duration),
             "--trajectory", str(trajectory), "--log", str(self.log), *map(str, extra)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)

    def finish(self) -> dict:
        """Waits (bounded) for the rig to end; returns its JSON summary."""
        try:
            out, err = self.p.communicate(timeout=self.duration + 30)
        except subprocess.TimeoutExpired:
            self.kill()
            raise
        assert self.p.returncode == 0, err
        return json.loads(out.strip().splitlines()[-1])

    def forces(self) -> list[dict]:
        """The force packets the rig received, in order: {time, sequence, flags, forces} with
        forces[finger] = (fx, fy, fz) in N, device frame."""
        packets = []
        with self.log.open(newline="") as f:
            for row in csv.DictReader(f):
                n = (len(row) - 3) // 3
                forces = [tuple(float(row[f"f{i}{c}"]) for c in "xyz") for i in range(n)]
                packets.append({"time": float(row["time"]), "sequence": int(row["sequence"]),
                                "flags": int(row["flags"]), "forces": forces})
        return packets

    def kill(self):
        if self.p.poll() is None:
            self.p.kill()
            self.p.wait(timeout=10)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.kill()


def lcm_log_frames(path: Path) -> int:
    """How many events the file holds, by LCM's event log framing (sync word 0xEDA1DA01, event
    number, timestamp, channel length, data length, all big-endian, then channel and data); fails
    unless the events end exactly at the end of the file (a log cut mid-event)."""
    data = Path(path).read_bytes()
    pos = n = 0
    while pos < len(data):
        assert len(data) - pos >= 28, f"{path}: {len(data) - pos} bytes left after event {n}"
        sync, _, _, channel_len, data_len = struct.unpack_from(">IqqII", data, pos)
        assert sync == 0xEDA1DA01, f"{path}: no event at byte {pos}"
        pos += 28 + channel_len + data_len
        n += 1
    assert pos == len(data), f"{path}: the last event is cut ({pos - len(data)} bytes missing)"
    return n


def read_lcm_log(path: Path) -> list[tuple[str, object]]:
    """Every event of an LCM log, read by lcm.EventLog and decoded with its message type:
    [(topic, message)]. Fails unless the file ends with a whole event and lcm.EventLog reads
    every event (lcm.EventLog itself ends quietly at a cut event)."""
    lcm = pytest.importorskip("lcm")
    from hapticloth.lcmtypes import TOPICS, topic_of_channel

    frames = lcm_log_frames(path)
    log = lcm.EventLog(str(path), "r")
    events = []
    try:
        for ev in log:
            topic = topic_of_channel(ev.channel)
            assert topic in TOPICS, f"{path}: unexpected channel {ev.channel}"
            events.append((topic, TOPICS[topic].decode(ev.data)))
    finally:
        log.close()
    assert len(events) == frames, f"{path}: lcm.EventLog read {len(events)} of {frames} events"
    return events


def haptic_samples(events) -> list[dict]:
    """The haptic samples of a decoded LCM log, in order: {time, tick, in_contact, command,
    device_position} per sample, per finger lists."""
    out = []
    for topic, m in events:
        if topic != "haptics":
            continue
        for k in range(m.num_samples):
            out.append({"time": m.time[k], "tick": m.tick[k],
                        "in_contact": [bool(c) for c in m.in_contact[k]],
                        "command": [tuple(c) for c in m.command[k]],
                        "device_position": [tuple(p) for p in m.device_position[k]]})
    return out
