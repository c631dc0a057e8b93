#!/usr/bin/env python3
"""Runs a test command again and again while other processes keep cores busy, as a loaded
machine or a shared CI runner would: the tests that must not depend on this machine's speed
(issue 39) are checked this way. Stops at the first failure. Prints one JSON object: the
command, the runs asked and passed, the busy cores, the CPU, and the failing run's output tail.

Usage: tools/bench/under_load.py [--runs 20] [--busy 1] [--timeout 1800] -- COMMAND...
Example: tools/bench/under_load.py --runs 20 -- build/tests/test_device_clock
"""
import argparse
import json
import multiprocessing
import subprocess
import sys
import time

from machine import cpu_model


def spin():
    """A busy loop: one core's worth of load until killed."""
    x = 0
    while True:
        x += 1


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20, help="runs asked (1-1000)")
    ap.add_argument("--busy", type=int, default=1, help="cores kept busy (0-64)")
    ap.add_argument("--timeout", type=float, default=1800.0, help="s allowed to each run")
    ap.add_argument("command", nargs=argparse.REMAINDER, help="-- COMMAND...")
    a = ap.parse_args()
    cmd = a.command[1:] if a.command[:1] == ["--"] else a.command
    if not cmd:
        ap.error("no command (give it after --)")
    if not 1 <= a.runs <= 1000:
        ap.error(f"--runs must be in [1, 1000], not {a.runs}")
    if not 0 <= a.busy <= 64:
        ap.error(f"--busy must be in [0, 64], not {a.busy}")
    load = [multiprocessing.Process(target=spin, daemon=True) for _ in range(a.busy)]
    for p in load:
        p.start()
    passed, failure, t0 = 0, None, time.monotonic()
    try:
        for run in range(a.runs):
            try:
                r = subprocess.run(cmd, capture_output=True, text=True, timeout=a.timeout)
            except subprocess.TimeoutExpired:
                failure = {"run": run + 1, "status": "timeout", "tail": ""}
                break
            if r.returncode != 0:
                failure = {"run": run + 1, "status": r.returncode, "tail": (r.stdout + r.stderr)[-3000:]}
                break
            passed += 1
    finally:
        for p in load:
            p.kill()
    print(json.dumps({"command": " ".join(cmd), "runs": a.runs, "passed": passed, "busy_cores": a.busy,
                      "cores": multiprocessing.cpu_count(), "cpu": cpu_model(),
                      "seconds": round(time.monotonic() - t0, 1), "failure": failure}))
    return 0 if failure is None else 1


if __name__ == "__main__":
    sys.exit(main())
