"""Command-line tools: hapticloth-record, hapticloth-replay, hapticloth-inject.

Exit status (hapticloth.errors): 0 done (replay, inject: every command accepted); 1 a command
was rejected or not answered; 2 a user error (a bad option, an unreadable or unwritable file, a
server that does not answer), reported in one line naming what is at fault.
"""

import argparse
import csv
import math
import os
import sys
import tempfile
import time

from .client import DEFAULT_ENDPOINT, DEFAULT_LCM_URL, Client, read_replay, trajectory_message
from . import lcmtypes
from .errors import (EXIT_FAILED, UserError, check_input_file, check_number, check_writable,
                     not_text_error, run_cli, transport_errors, transport_error_text)

#: Bounds of the options (anything beyond is a typo, and would overflow a sleep or a timer).
MAX_RECORD_SECONDS = 7 * 86400.0
MAX_TIMEOUT = 600.0
MIN_SPEED, MAX_SPEED = 0.01, 100.0
MAX_LEAD = 60.0


def _connection_args(p):
    p.add_argument("--transport", choices=("zenoh", "lcm"), default="zenoh")
    p.add_argument("--server", default="default", help="server name (its --name)")
    p.add_argument("--endpoint", default=DEFAULT_ENDPOINT, help="zenoh endpoint of the server")
    p.add_argument("--zenoh-config", default=None, help="zenoh JSON5 config file instead of --endpoint")
    p.add_argument("--lcm-url", default=DEFAULT_LCM_URL, help="LCM provider (transport lcm)")
    p.add_argument("--timeout", type=float, default=5.0,
                   help=f"seconds to wait for the server's answers (default 5, at most {MAX_TIMEOUT:g})")


def _check_timeout(a):
    return check_number("--timeout", a.timeout, "a positive number of seconds", 0.0, MAX_TIMEOUT,
                        low_open=True, unit=" s")


def _where(a):
    """The option that says where the server is, as the user gave it."""
    if a.transport == "lcm":
        return f"--lcm-url {a.lcm_url}"
    return f"--zenoh-config {a.zenoh_config}" if a.zenoh_config else f"--endpoint {a.endpoint}"


def _open_client(a):
    """A Client, or UserError naming the endpoint, config file or LCM URL that failed."""
    if a.transport == "zenoh" and a.zenoh_config:
        check_input_file(a.zenoh_config, "--zenoh-config")
    if a.transport == "lcm":
        return _open_lcm_client(a)
    try:
        return Client("zenoh", server=a.server, endpoint=a.endpoint, zenoh_config=a.zenoh_config)
    except transport_errors() as e:
        raise UserError(f"{_where(a)}: cannot connect (zenoh: {transport_error_text(e)})") from None


def _open_lcm_client(a):
    """The LCM library prints why a provider fails on stderr and raises only "Couldn't create
    LCM": its words are caught here (file descriptor 2 for the moment of the call; no other
    thread runs yet) to be put into the one line of the error."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as caught:
        os.dup2(caught.fileno(), 2)
        try:
            return Client("lcm", server=a.server, lcm_url=a.lcm_url)
        except RuntimeError:
            caught.seek(0)
            why = caught.read().decode(errors="replace").strip().removeprefix("Error: ")
            raise UserError(f"{_where(a)}: cannot open the LCM provider "
                            f"({why.splitlines()[0] if why else 'invalid URL'})") from None
        finally:
            os.dup2(saved, 2)
            os.close(saved)


def _connect(a):
    """(client, scene_info_t) of a server that answered, or UserError saying where it was
    looked for: over LCM nothing fails until a request goes unanswered, so the scene is asked
    for before anything is sent or recorded."""
    c = _open_client(a)
    try:
        return c, c.get_scene(timeout=a.timeout)
    except TimeoutError:
        c.close()
        raise UserError(f"{_where(a)}: no answer from server '{a.server}' within {a.timeout:g} s "
                        f"(is hapticloth-server running there with --name {a.server}?)") from None


def report_answers(c, sent, timeout):
    """Prints the server's answer to each command sent (in order): "accepted: ...",
    "rejected: ..." or "unanswered: ..." (none within `timeout` s after the last was sent),
    then a count. Returns the exit status: 0 if every command was accepted, else 1."""
    deadline = time.monotonic() + timeout
    counts = {"accepted": 0, "rejected": 0, "unanswered": 0}
    for m in sent:
        try:
            ok, text = c.wait_ack(m.seq, max(0.0, deadline - time.monotonic()))
        except TimeoutError:
            kind, text = "unanswered", (f"finger {m.finger}, {m.num_points} points seq {m.seq}: "
                                        f"no answer within {timeout:g} s")
        else:
            kind = "accepted" if ok else "rejected"
        counts[kind] += 1
        print(f"{kind}: {text}", flush=True)
    print(f"{len(sent)} command(s): " + ", ".join(f"{n} {k}" for k, n in counts.items()))
    return 0 if counts["accepted"] == len(sent) else EXIT_FAILED


# --- hapticloth-record ---------------------------------------------------------------------------

def record_main(argv=None):
    return run_cli("hapticloth-record", _record, argv)


def _record(argv):
    p = argparse.ArgumentParser(prog="hapticloth-record",
                                description="Record a server's messages into an LCM log.")
    p.add_argument("out", help="LCM log file to write")
    p.add_argument("--duration", type=float, default=10.0,
                   help=f"seconds to record (default 10, at most {MAX_RECORD_SECONDS:g})")
    p.add_argument("--topics", default=",".join(lcmtypes.TOPICS),
                   help="comma-separated topics (default: all)")
    _connection_args(p)
    a = p.parse_args(argv)
    topics = [t for t in a.topics.split(",") if t]
    for t in topics:
        if t not in lcmtypes.TOPICS:
            p.error(f"unknown topic {t!r} (known: {', '.join(lcmtypes.TOPICS)})")
    check_number("--duration", a.duration, "a positive number of seconds", 0.0, MAX_RECORD_SECONDS,
                 low_open=True, unit=" s")
    _check_timeout(a)
    check_writable(a.out, "out")
    c, scene = _connect(a)
    started = True
    with c:
        rec = c.record(a.out, topics)
        try:
            if "scene" in topics:  # the scene first, so the log stands on its own
                rec._writer("scene")(scene.encode())
            started = rec.wait_started(a.timeout)
            if started:
                print(f"recording {a.out} for {a.duration:g} s", file=sys.stderr, flush=True)
                time.sleep(a.duration)
        except KeyboardInterrupt:
            pass
        counts = rec.stop()
    if rec.write_error:
        print(f"hapticloth-record: {a.out}: {rec.write_error}", file=sys.stderr, flush=True)
        return EXIT_FAILED
    if not started:
        raise UserError(f"{_where(a)}: no {rec.started_by} message from server '{a.server}' "
                        f"within --timeout {a.timeout:g} s")
    print(" ".join(f"{t}={n}" for t, n in counts.items()))
    return 0


# --- hapticloth-replay ---------------------------------------------------------------------------

def replay_main(argv=None):
    return run_cli("hapticloth-replay", _replay, argv)


def _replay(argv):
    p = argparse.ArgumentParser(prog="hapticloth-replay",
                                description="Play an LCM log's trajectories (or recorded device "
                                            "positions) into a server's remote device; print the "
                                            "server's answer to each command.")
    p.add_argument("log", help="LCM log (hapticloth-record or the server's --lcm-log)")
    p.add_argument("--mode", choices=("auto", "commands", "positions"), default="auto")
    p.add_argument("--speed", type=float, default=1.0,
                   help=f"time scale (2 = twice as fast; {MIN_SPEED:g} to {MAX_SPEED:g})")
    p.add_argument("--lead", type=float, default=0.1,
                   help=f"positions mode: seconds to reach the first recorded position (0 to {MAX_LEAD:g})")
    _connection_args(p)
    a = p.parse_args(argv)
    check_number("--speed", a.speed, f"a time scale from {MIN_SPEED:g} to {MAX_SPEED:g} (1: as recorded)",
                 MIN_SPEED, MAX_SPEED)
    check_number("--lead", a.lead, "a number of seconds >= 0", 0.0, MAX_LEAD, unit=" s")
    _check_timeout(a)
    commands = read_replay(a.log, mode=a.mode, speed=a.speed, lead=a.lead)  # before connecting
    c, _ = _connect(a)
    with c:
        c.listen_for_answers()
        sent = c.play(commands)
        return report_answers(c, sent, a.timeout)


# --- hapticloth-inject ---------------------------------------------------------------------------

CSV_COLUMNS = "time,finger,x,y,z"


def read_csv(path):
    """CSV rows time,finger,x,y,z (a header line is allowed) -> {finger: (times, points)}.
    Raises UserError naming the file (and line) for anything but such rows."""
    check_input_file(path)
    per = {}
    lineno = 0
    try:
        with open(path, newline="", encoding="utf-8") as f:
            for lineno, row in enumerate(csv.reader(f), 1):
                if not row or not "".join(row).strip() or row[0].strip().startswith("#"):
                    continue
                parsed = _trajectory_row(path, lineno, row)
                if parsed is None:
                    continue  # the header
                t, finger, point = parsed
                per.setdefault(finger, ([], []))
                per[finger][0].append(t)
                per[finger][1].append(point)
    except UnicodeDecodeError as e:
        raise not_text_error(path, e) from None
    except csv.Error as e:
        raise UserError(f"{path}:{lineno + 1}: {e} (a binary file?)") from None
    if not per:
        raise UserError(f"{path}: no trajectory rows ({CSV_COLUMNS})")
    return per


def _trajectory_row(path, lineno, row):
    """(time, finger, [x, y, z]) of a row; None for a header on line 1."""
    try:
        t, finger, x, y, z = (float(row[0]), int(row[1]), float(row[2]), float(row[3]),
                              float(row[4]))
    except (ValueError, IndexError):
        if lineno == 1:
            return None
        raise UserError(f"{path}:{lineno}: expected {CSV_COLUMNS}, got {','.join(row)[:60]!r}") from None
    for name, v in (("time", t), ("x", x), ("y", y), ("z", z)):
        if not math.isfinite(v):
            raise UserError(f"{path}:{lineno}: {name} {v:g} is not a finite number")
    return t, finger, [x, y, z]


def inject_main(argv=None):
    return run_cli("hapticloth-inject", _inject, argv)


def _inject(argv):
    p = argparse.ArgumentParser(prog="hapticloth-inject",
                                description="Send fingertip trajectories from a CSV "
                                            f"({CSV_COLUMNS}; s and m) to a server's remote device; "
                                            "print the server's answer to each.")
    p.add_argument("csv")
    p.add_argument("--frame", choices=("device", "scene"), default="device")
    _connection_args(p)
    a = p.parse_args(argv)
    _check_timeout(a)
    per = read_csv(a.csv)
    c, _ = _connect(a)
    with c:
        c.listen_for_answers()
        # One command per finger, back to back: the server takes them within a tick or two.
        sent = c.play([(0.0, trajectory_message(f, times, points, a.frame))
                       for f, (times, points) in sorted(per.items())])
        return report_answers(c, sent, a.timeout)
