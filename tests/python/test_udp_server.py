"""The server with the UDP device driver, end to end over loopback: the fake rig streams a
press into the hanging square at 1 kHz with loss, reordering, duplicates and garbage; the
server renders contact forces back, drops and counts the bad packets, and never sends a
non-finite force."""

from __future__ import annotations

import csv
import json
import math
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from buildpaths import program

REPO = Path(__file__).resolve().parents[2]
RIG = REPO / "tools" / "fake_rig" / "hapticloth-fake-rig"
SCENE = REPO / "tools" / "scenes" / "hanging_square.toml"


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_udp_rig_presses_the_cloth_through_the_server(tmp_path):
    port = free_port()
    # Finger 0 comes from 4 cm in front of the hanging cloth to 3 mm into it (device frame:
    # cloth in the y = 0 plane), holds; finger 1 stays behind, away from the cloth.
    traj = tmp_path / "press.csv"
    rows = ["time,finger,x,y,z",
            "0,0,-0.02,-0.04,0", "1.0,0,-0.02,-0.04,0", "2.0,0,-0.02,-0.005,0", "4.0,0,-0.02,-0.005,0",
            "0,1,0.06,0.05,0", "4.0,1,0.06,0.05,0"]
    traj.write_text("\n".join(rows) + "\n")
    log = tmp_path / "rig.csv"
    server = subprocess.Popen(
        [str(program("hapticloth-server")), "--scene", str(SCENE), "--device", "udp", "--udp-bind",
         f"127.0.0.1:{port}", "--duration", "6", "--no-realtime", "--json"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        time.sleep(0.5)  # the driver binds before the preroll
        rig = subprocess.run(
            [sys.executable, str(RIG), "--server", f"127.0.0.1:{port}", "--duration", "4.5",
             "--trajectory", str(traj), "--log", str(log), "--seed", "3", "--loss", "0.1",
             "--reorder", "0.05", "--duplicate", "0.05", "--garbage", "0.05"],
            capture_output=True, text=True, timeout=60)
        out, err = server.communicate(timeout=60)
    finally:
        if server.poll() is None:
            server.kill()
    assert rig.returncode == 0, rig.stderr
    assert server.returncode == 0, err
    summary = json.loads(rig.stdout.strip().splitlines()[-1])
    report = json.loads(out.strip().splitlines()[-1])
    assert report["device"].startswith("udp")
    # Garbage, duplicates and late packets were dropped and counted, nothing else broke.
    garbage = sum(summary["garbage"].values()) if isinstance(summary["garbage"], dict) else summary["garbage"]
    assert report["device_counters"]["dropped"] >= garbage > 0
    assert report["device_counters"]["samples"] > 2000
    # The press was felt: contact ticks and a force on the finger, all finite.
    assert report["contact_ticks"] > 500
    # Pushing a hanging membrane (tension about 1 N/m, 0.2 m below the pins) 3 mm sideways
    # takes about 2 pi T d / ln(R / a) ~ 0.006-0.01 N.
    assert 0.003 < report["max_force_n"] <= 8.0
    forces = []
    with log.open() as f:
        for row in csv.DictReader(f):
            fx, fy, fz = (float(row[k]) for k in ("f0x", "f0y", "f0z"))
            assert all(math.isfinite(v) for v in (fx, fy, fz))
            forces.append((fx, fy, fz))
    assert len(forces) > 2000
    # pressing from the front (-y) into the cloth: the cloth pushes the finger back (-y)
    assert min(f[1] for f in forces) < -0.003
