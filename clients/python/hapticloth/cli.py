"""Command-line tools: hapticloth-record, hapticloth-replay, hapticloth-inject."""

import argparse
import csv
import sys
import time

from .client import DEFAULT_ENDPOINT, DEFAULT_LCM_URL, Client
from . import lcmtypes


def _connection_args(p):
    p.add_argument("--transport", choices=("zenoh", "lcm"), default="zenoh")
    p.add_argument("--server", default="default", help="server name (its --name)")
    p.add_argument("--endpoint", default=DEFAULT_ENDPOINT, help="zenoh endpoint of the server")
    p.add_argument("--zenoh-config", default=None, help="zenoh JSON5 config file instead of --endpoint")
    p.add_argument("--lcm-url", default=DEFAULT_LCM_URL, help="LCM provider (transport lcm)")


def _client(a):
    return Client(a.transport, server=a.server, endpoint=a.endpoint, lcm_url=a.lcm_url,
                  zenoh_config=a.zenoh_config)


def record_main(argv=None):
    p = argparse.ArgumentParser(prog="hapticloth-record",
                                description="Record a server's messages into an LCM log.")
    p.add_argument("out", help="LCM log file to write")
    p.add_argument("--duration", type=float, default=10.0, help="seconds to record (default 10)")
    p.add_argument("--topics", default=",".join(lcmtypes.TOPICS),
                   help="comma-separated topics (default: all)")
    _connection_args(p)
    a = p.parse_args(argv)
    topics = [t for t in a.topics.split(",") if t]
    for t in topics:
        if t not in lcmtypes.TOPICS:
            p.error(f"unknown topic {t!r} (known: {', '.join(lcmtypes.TOPICS)})")
    with _client(a) as c:
        rec = c.record(a.out, topics)
        try:
            if "scene" in topics:  # the scene first, so the log stands on its own
                try:
                    scene = c.get_scene(timeout=2.0)
                    rec._writer("scene")(scene.encode())
                except TimeoutError:
                    print("hapticloth-record: no scene answer", file=sys.stderr)
            time.sleep(a.duration)
        except KeyboardInterrupt:
            pass
        counts = rec.stop()
    print(" ".join(f"{t}={n}" for t, n in counts.items()))
    return 0


def replay_main(argv=None):
    p = argparse.ArgumentParser(prog="hapticloth-replay",
                                description="Play an LCM log's trajectories (or recorded device "
                                            "positions) into a server's remote device.")
    p.add_argument("log", help="LCM log (hapticloth-record or the server's --lcm-log)")
    p.add_argument("--mode", choices=("auto", "commands", "positions"), default="auto")
    p.add_argument("--speed", type=float, default=1.0, help="time scale (2 = twice as fast)")
    p.add_argument("--lead", type=float, default=0.1,
                   help="positions mode: seconds to reach the first recorded position")
    _connection_args(p)
    a = p.parse_args(argv)
    with _client(a) as c:
        sent = c.replay(a.log, mode=a.mode, speed=a.speed, lead=a.lead)
        time.sleep(0.2)  # let the last puts leave before the session closes
    print(f"sent {len(sent)} trajectory command(s)")
    return 0


def read_csv(path):
    """CSV rows time,finger,x,y,z (a header line is allowed) -> {finger: (times, points)}."""
    per = {}
    with open(path, newline="") as f:
        for lineno, row in enumerate(csv.reader(f), 1):
            if not row or row[0].strip().startswith("#"):
                continue
            try:
                t, finger, x, y, z = (float(row[0]), int(row[1]), float(row[2]), float(row[3]),
                                      float(row[4]))
            except (ValueError, IndexError):
                if lineno == 1:
                    continue  # header
                raise ValueError(f"{path}:{lineno}: expected time,finger,x,y,z") from None
            per.setdefault(finger, ([], []))
            per[finger][0].append(t)
            per[finger][1].append([x, y, z])
    return per


def inject_main(argv=None):
    p = argparse.ArgumentParser(prog="hapticloth-inject",
                                description="Send fingertip trajectories from a CSV "
                                            "(time,finger,x,y,z; s and m) to a server's remote device.")
    p.add_argument("csv")
    p.add_argument("--frame", choices=("device", "scene"), default="device")
    p.add_argument("--timeout", type=float, default=5.0, help="seconds to wait for each answer")
    _connection_args(p)
    a = p.parse_args(argv)
    try:
        per = read_csv(a.csv)
    except (OSError, ValueError) as e:
        print(f"hapticloth-inject: {e}", file=sys.stderr)
        return 2
    status = 0
    with _client(a) as c:
        for finger, (times, points) in sorted(per.items()):
            try:
                seq, ok, text = c.inject_trajectory(finger, times, points, frame=a.frame, wait=a.timeout)
            except TimeoutError as e:
                print(f"hapticloth-inject: finger {finger}: {e}", file=sys.stderr)
                status = 1
                continue
            print(("accepted: " if ok else "rejected: ") + text)
            if not ok:
                status = 1
    return status
