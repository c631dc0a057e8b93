"""The command-line tools of clients/python/hapticloth/cli.py (hapticloth-record, -replay,
-inject) and hapticloth-bench-transport, run as subprocesses through the venv's console scripts:

- a user error (a bad option value, a missing, binary or empty input, an unwritable output, a
  server that is not there over zenoh or LCM) is one line on stderr naming the option, file or
  endpoint at fault, exit status 2, never a traceback;
- replay and inject wait for the server's answer to each command: exit 1 when one was rejected
  (a real hapticloth-server --device remote on loopback) or not answered (a fake zenoh server
  made here that answers the scene query and nothing else), 0 when all were accepted.

Network: tcp on 127.0.0.1 only; LCM through its in-process memq:// provider. Every wait is
bounded (subprocess timeouts, the tools' --timeout).
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from buildpaths import build_dir, program
from not_lcm_logs import NOT_LCM_LOGS, not_lcm_log
from test_client import Server, connect, free_port

lcm = pytest.importorskip("lcm")

from hapticloth.client import trajectory_message  # noqa: E402
from hapticloth.lcmtypes import scene_info_t  # noqa: E402

BIN = Path(sys.executable).parent  # the venv's console scripts


def tool(name, *args, timeout=60) -> subprocess.CompletedProcess:
    exe = BIN / name
    if not exe.is_file():
        pytest.skip(f"{name} is not installed in {BIN} (tools/setup)")
    return subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True,
                          timeout=timeout)


def assert_user_error(r, *named):
    """Exit 2, one line on stderr naming each of `named`, no traceback."""
    out = r.stdout + r.stderr
    assert "Traceback" not in out, out
    assert r.returncode == 2, out
    assert r.stderr.strip() and r.stderr.strip().count("\n") == 0, r.stderr
    for n in named:
        assert str(n) in r.stderr, (n, r.stderr)


def unreachable_endpoint() -> str:
    return f"tcp/127.0.0.1:{free_port()}"  # a port nothing listens on


def write_commands_log(path, commands):
    """An LCM log of trajectory commands: [(finger, [(time, (x, y, z))])], 0.1 s apart."""
    log = lcm.EventLog(str(path), "w", overwrite=True)
    for i, (finger, points) in enumerate(commands):
        m = trajectory_message(finger, [t for t, _ in points], [p for _, p in points])
        m.source, m.seq = "recorded", i + 1
        log.write_event(1_000_000 + 100_000 * i, "HAPTICLOTH_TRAJECTORY", m.encode())
    log.close()
    return path


# Device frame of the hanging square: the cloth in the y = 0 plane, the fingers' workspace
# +-0.1 m; finger 0 in front of the cloth, finger 1 behind it.
GOOD_COMMANDS = [(0, [(0.5, (-0.02, -0.03, 0.0)), (1.0, (-0.02, -0.02, 0.0))]),
                 (1, [(0.5, (0.06, 0.03, 0.0))])]
# Rejected by the remote device: a finger the scene does not have, a point outside the workspace.
BAD_COMMANDS = [(7, [(0.5, (0.0, -0.03, 0.0))]),
                (0, [(0.5, (0.5, 0.0, 0.0))])]


@pytest.fixture
def commands_log(tmp_path):
    return write_commands_log(tmp_path / "good.lcm", GOOD_COMMANDS)


@pytest.fixture
def trajectory_csv(tmp_path):
    p = tmp_path / "traj.csv"
    p.write_text("time,finger,x,y,z\n0.5,0,-0.02,-0.03,0.0\n1.0,0,-0.02,-0.02,0.0\n"
                 "0.5,1,0.06,0.03,0.0\n")
    return p


# --- bad option values: exit 2, the option named -------------------------------------------------

BAD_OPTIONS = [
    ("hapticloth-record", "--duration", "-1"),
    ("hapticloth-record", "--duration", "0"),
    ("hapticloth-record", "--duration", "nan"),
    ("hapticloth-record", "--duration", "inf"),
    ("hapticloth-record", "--timeout", "-1"),
    ("hapticloth-replay", "--speed", "0"),
    ("hapticloth-replay", "--speed", "-1"),
    ("hapticloth-replay", "--speed", "nan"),
    ("hapticloth-replay", "--speed", "1e9"),
    ("hapticloth-replay", "--lead", "-0.5"),
    ("hapticloth-replay", "--lead", "nan"),
    ("hapticloth-replay", "--timeout", "0"),
    ("hapticloth-inject", "--timeout", "nan"),
    ("hapticloth-inject", "--timeout", "1e9"),
    ("hapticloth-bench-transport", "--seconds", "0"),
    ("hapticloth-bench-transport", "--rate", "nan"),
    ("hapticloth-bench-transport", "--port", "0"),
]


@pytest.mark.parametrize("name, option, value", BAD_OPTIONS)
def test_bad_option_value_is_named_with_exit_2(name, option, value, tmp_path, commands_log,
                                               trajectory_csv):
    # Options are checked before any file is read or any server is looked for.
    first = {"hapticloth-record": [tmp_path / "out.lcm"], "hapticloth-replay": [commands_log],
             "hapticloth-inject": [trajectory_csv], "hapticloth-bench-transport": []}[name]
    where = [] if name == "hapticloth-bench-transport" else ["--endpoint", unreachable_endpoint()]
    r = tool(name, *first, option, value, *where)
    assert_user_error(r, f"{name}: {option}: must be", f"not {float(value):g}")


def test_bench_transport_names_what_replaced_haptic_seconds():
    r = tool("hapticloth-bench-transport", "--haptic-seconds", "10")
    assert_user_error(r, "hapticloth-bench-transport: --haptic-seconds: the haptic loop with "
                         "subscribers is measured by `hapticloth-bench haptic --subscribers N` now")


def test_duration_message_reads_as_documented(tmp_path):
    r = tool("hapticloth-record", tmp_path / "out.lcm", "--duration", "-1")
    assert r.stderr.strip() == "hapticloth-record: --duration: must be a positive number of seconds, not -1"


def test_argparse_usage_errors_still_exit_2(tmp_path):
    r = tool("hapticloth-record", tmp_path / "out.lcm", "--duration", "soon")
    assert r.returncode == 2 and "--duration" in r.stderr and "Traceback" not in r.stderr
    r = tool("hapticloth-record", tmp_path / "out.lcm", "--topics", "cloth,nonsense")
    assert r.returncode == 2 and "nonsense" in r.stderr


# --- no server there ----------------------------------------------------------------------------

def test_record_with_no_server_on_the_endpoint(tmp_path):
    ep = unreachable_endpoint()
    r = tool("hapticloth-record", tmp_path / "out.lcm", "--duration", "1", "--endpoint", ep)
    assert_user_error(r, f"--endpoint {ep}: cannot connect")
    assert not (tmp_path / "out.lcm").exists()


def test_inject_with_no_server_on_the_endpoint(trajectory_csv):
    ep = unreachable_endpoint()
    assert_user_error(tool("hapticloth-inject", trajectory_csv, "--endpoint", ep),
                      f"--endpoint {ep}: cannot connect")


def test_replay_with_no_server_on_the_endpoint(commands_log):
    ep = unreachable_endpoint()
    assert_user_error(tool("hapticloth-replay", commands_log, "--endpoint", ep),
                      f"--endpoint {ep}: cannot connect")


def test_bad_endpoint_and_missing_zenoh_config(tmp_path, trajectory_csv):
    assert_user_error(tool("hapticloth-inject", trajectory_csv, "--endpoint", "localhost"),
                      "--endpoint localhost: cannot connect")
    missing = tmp_path / "zenoh.json5"
    assert_user_error(tool("hapticloth-inject", trajectory_csv, "--zenoh-config", missing),
                      f"--zenoh-config {missing}: no such file")


# Over LCM nothing fails until a request goes unanswered: memq:// is LCM's in-process queue, a
# bus on which no server can be (and that sends nothing over the network).
@pytest.mark.parametrize("name", ["hapticloth-record", "hapticloth-replay", "hapticloth-inject"])
def test_no_server_on_the_lcm_bus(name, tmp_path, commands_log, trajectory_csv):
    first = {"hapticloth-record": tmp_path / "out.lcm", "hapticloth-replay": commands_log,
             "hapticloth-inject": trajectory_csv}[name]
    t0 = time.monotonic()
    r = tool(name, first, "--transport", "lcm", "--lcm-url", "memq://", "--timeout", "0.5")
    assert_user_error(r, "--lcm-url memq://: no answer from server 'default' within 0.5 s")
    assert time.monotonic() - t0 < 30  # a safety limit: a 0.5 s timeout must not hang


def test_bad_lcm_url(trajectory_csv):
    r = tool("hapticloth-inject", trajectory_csv, "--transport", "lcm", "--lcm-url", "bogus://x")
    assert_user_error(r, "--lcm-url bogus://x: cannot open the LCM provider", '"bogus" not found')


# --- files --------------------------------------------------------------------------------------

def test_record_to_a_missing_folder(tmp_path):
    out = tmp_path / "no" / "such" / "out.lcm"
    r = tool("hapticloth-record", out, "--endpoint", unreachable_endpoint())
    assert_user_error(r, f"{out}: cannot write: the folder {out.parent} does not exist")


def test_record_to_a_device_or_to_nothing(tmp_path):
    # Issue 36 item 9: /dev/full printed a traceback mid-run; "" was taken.
    assert_user_error(tool("hapticloth-record", "/dev/full", "--endpoint", unreachable_endpoint()),
                      "out /dev/full: not a regular file")
    assert_user_error(tool("hapticloth-record", "", "--endpoint", unreachable_endpoint()),
                      "out: needs a path")


def test_record_to_a_folder(tmp_path):
    assert_user_error(tool("hapticloth-record", tmp_path, "--endpoint", unreachable_endpoint()),
                      f"{tmp_path}: is a folder")


@NOT_LCM_LOGS
def test_replay_of_a_missing_or_non_lcm_log(tmp_path, content, words):
    log = not_lcm_log(tmp_path, content)
    assert_user_error(tool("hapticloth-replay", log, "--endpoint", unreachable_endpoint()),
                      f"{log}: {words}")


def test_replay_of_a_folder(tmp_path):
    assert_user_error(tool("hapticloth-replay", tmp_path, "--endpoint", unreachable_endpoint()),
                      f"{tmp_path}: cannot open as an LCM log (a folder)")


def test_replay_of_a_log_with_nothing_to_play(tmp_path):
    log = tmp_path / "scene_only.lcm"
    ev = lcm.EventLog(str(log), "w", overwrite=True)
    ev.write_event(1_000_000, "HAPTICLOTH_SCENE", scene_info_t().encode())
    ev.close()
    assert_user_error(tool("hapticloth-replay", log, "--endpoint", unreachable_endpoint()),
                      f"{log}: no trajectory commands", "to replay")
    assert_user_error(tool("hapticloth-replay", log, "--mode", "commands", "--endpoint",
                           unreachable_endpoint()), f"{log}: no trajectory commands")


def test_inject_of_an_empty_csv(tmp_path):
    for text in ("", "time,finger,x,y,z\n", "# nothing yet\n\n"):
        csv = tmp_path / "empty.csv"
        csv.write_text(text)
        assert_user_error(tool("hapticloth-inject", csv, "--endpoint", unreachable_endpoint()),
                          f"{csv}: no trajectory rows (time,finger,x,y,z)")


def test_inject_of_a_binary_file(tmp_path):
    data = tmp_path / "data.bin"
    data.write_bytes(bytes([0xBA, 0x00, 0xFF]) + os.urandom(1000))
    assert_user_error(tool("hapticloth-inject", data, "--endpoint", unreachable_endpoint()),
                      f"{data}: not a text file")


def test_inject_of_a_missing_csv_and_bad_rows(tmp_path):
    missing = tmp_path / "nope.csv"
    assert_user_error(tool("hapticloth-inject", missing), f"{missing}: no such file")
    bad = tmp_path / "bad.csv"
    bad.write_text("time,finger,x,y,z\n0.5,0,0,0,0\n0.7,0,0,0\n")
    assert_user_error(tool("hapticloth-inject", bad), f"{bad}:3: expected time,finger,x,y,z")
    bad.write_text("time,finger,x,y,z\n0.5,0,0,nan,0\n")
    assert_user_error(tool("hapticloth-inject", bad), f"{bad}:2: y nan is not a finite number")


# --- answers: a fake server that never answers commands ------------------------------------------

@pytest.fixture
def silent_server():
    """A zenoh peer on loopback that answers the scene query of server 'fake' and nothing else
    (what a server looks like when its answers are lost): yields its endpoint."""
    zenoh = pytest.importorskip("zenoh")
    ep = unreachable_endpoint()
    conf = ('{ mode: "peer", listen: { endpoints: ["%s"] }, '
            'scouting: { multicast: { enabled: false }, gossip: { enabled: false } } }' % ep)
    z = zenoh.open(zenoh.Config.from_json5(conf))
    scene = scene_info_t()
    scene.server_name = "fake"
    payload = scene.encode()
    q = z.declare_queryable("hapticloth/fake/scene", lambda query: query.reply(query.key_expr, payload))
    try:
        yield ep
    finally:
        q.undeclare()
        z.close()


def test_inject_unanswered_commands_exit_1(silent_server, trajectory_csv):
    t0 = time.monotonic()
    r = tool("hapticloth-inject", trajectory_csv, "--server", "fake", "--endpoint", silent_server,
             "--timeout", "0.5")
    assert r.returncode == 1, r.stdout + r.stderr
    assert "Traceback" not in r.stdout + r.stderr
    assert r.stdout.count("unanswered: ") == 2 and "no answer within 0.5 s" in r.stdout
    assert "accepted:" not in r.stdout
    assert time.monotonic() - t0 < 30  # a safety limit: a 0.5 s timeout must not hang


def test_replay_unanswered_commands_exit_1(silent_server, commands_log):
    r = tool("hapticloth-replay", commands_log, "--server", "fake", "--endpoint", silent_server,
             "--timeout", "0.5")
    assert r.returncode == 1, r.stdout + r.stderr
    assert r.stdout.count("unanswered: ") == 2
    assert "2 command(s): 0 accepted, 0 rejected, 2 unanswered" in r.stdout


# --- answers: a real server -----------------------------------------------------------------------

def wait_for_program(name, seconds=10.0):
    """The built program; the build directory may be relinked under the tests for a moment."""
    deadline = time.monotonic() + seconds
    while not (build_dir() / name).is_file() and time.monotonic() < deadline:
        time.sleep(0.5)
    return program(name)


@pytest.fixture(scope="module")
def server():
    """hapticloth-server --device remote (hanging square, 2 fingers, workspace +-0.1 m) named
    't' on a loopback port, up long enough for this module's tests; killed at the end."""
    wait_for_program("hapticloth-server")
    srv = Server(120.0, "--no-lcm-log")
    try:
        c, _ = connect(srv)
        c.close()
        yield srv
    finally:
        srv.kill()


def at(srv):
    return ["--server", "t", "--endpoint", srv.endpoint]


def test_inject_accepted_commands_exit_0(server, trajectory_csv):
    r = tool("hapticloth-inject", trajectory_csv, *at(server))
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.count("accepted: ") == 2
    assert "2 command(s): 2 accepted, 0 rejected, 0 unanswered" in r.stdout


def test_inject_rejected_command_exit_1(server, tmp_path):
    csv = tmp_path / "bad_finger.csv"
    csv.write_text("time,finger,x,y,z\n0.5,0,-0.02,-0.03,0.0\n0.5,7,0.0,-0.03,0.0\n")
    r = tool("hapticloth-inject", csv, *at(server))
    assert r.returncode == 1, r.stdout + r.stderr
    assert "Traceback" not in r.stdout + r.stderr
    lines = r.stdout.splitlines()
    assert lines[0].startswith("accepted: finger 0")
    assert lines[1].startswith("rejected: finger 7") and "out of range" in lines[1]


def test_replay_rejected_commands_exit_1(server, tmp_path):
    log = write_commands_log(tmp_path / "bad.lcm", BAD_COMMANDS)
    r = tool("hapticloth-replay", log, *at(server))
    assert r.returncode == 1, r.stdout + r.stderr
    assert "Traceback" not in r.stdout + r.stderr
    rejected = [line for line in r.stdout.splitlines() if line.startswith("rejected: ")]
    assert len(rejected) == 2, r.stdout
    assert "finger 7 out of range" in rejected[0] and "outside the workspace" in rejected[1]
    assert "accepted:" not in r.stdout


def test_replay_accepted_commands_exit_0(server, commands_log):
    r = tool("hapticloth-replay", commands_log, "--speed", "2", *at(server))
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.count("accepted: ") == 2 and "rejected: " not in r.stdout


def test_record_from_a_server_of_another_name(server, tmp_path):
    r = tool("hapticloth-record", tmp_path / "out.lcm", "--server", "nobody", "--endpoint",
             server.endpoint, "--timeout", "0.5", "--duration", "1")
    assert_user_error(r, f"--endpoint {server.endpoint}: no answer from server 'nobody'")
    assert not (tmp_path / "out.lcm").exists()


def test_record_writes_the_log(server, tmp_path):
    out = tmp_path / "out.lcm"
    r = tool("hapticloth-record", out, "--duration", "0.5", *at(server))
    assert r.returncode == 0, r.stderr
    counts = dict(kv.split("=") for kv in r.stdout.split())
    assert int(counts["scene"]) == 1 and int(counts["haptics"]) > 10
    assert out.read_bytes()[:4] == b"\xed\xa1\xda\x01"  # an LCM log
