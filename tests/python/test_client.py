"""The server's state transports against the real hapticloth-server binary (--device remote):
Python clients over zenoh (loopback tcp) and LCM (udpm inside a network namespace made here)
inject fingertip trajectories, receive forces and cloth positions, record and replay, ask for
the scene late, stall or die without disturbing the server, and connect across a veth link
between two network namespaces.

Network: only 127.0.0.1, and addresses inside network namespaces these tests create (udpm with
ttl=0 inside an `unshare --net` namespace; 192.0.2.0/24, a documentation range, on a veth pair
between two `ip netns` namespaces). Every wait is bounded.

This file is also the script the namespace tests run inside their namespaces
(`python test_client.py <role> ...`).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

from buildpaths import build_dir

REPO = Path(__file__).resolve().parents[2]
SCENE = REPO / "tools" / "scenes" / "hanging_square.toml"
BUILD = build_dir()
SERVER = BUILD / "hapticloth-server"
LCM_URL = "udpm://239.255.76.67:7667?ttl=0"

# The scripted two-finger press-stroke-pinch (device frame: origin mid-cloth, the hanging cloth
# in the y = 0 plane; finger 0 in front, y < 0, finger 1 behind; fingertip radius 8 mm).
# Times in s after the device takes the command.
SCRIPT = {
    0: [(0.5, (-0.02, -0.04, 0.0)),     # (where the scene's script starts: out of the cloth)
        (1.5, (-0.02, -0.04, 0.0)),     # settle
        (2.5, (-0.02, -0.004, 0.0)),    # press: 4 mm into the cloth
        (3.0, (-0.02, -0.004, 0.0)),    # hold
        (4.5, (0.03, -0.004, 0.0)),     # stroke 5 cm sideways
        (5.0, (0.03, -0.04, 0.0)),      # leave
        (6.0, (0.0, -0.03, -0.05)),     # beside a point 5 cm lower
        (6.8, (0.0, -0.004, -0.05)),    # pinch: 4 mm into the cloth
        (7.8, (0.0, -0.004, -0.03)),    # lift 2 cm
        (8.5, (0.0, -0.004, -0.03)),    # hold
        (9.1, (0.0, -0.03, -0.03))],    # release
    1: [(0.5, (0.06, 0.04, 0.0)),       # behind the cloth
        (5.0, (0.06, 0.04, 0.0)),
        (6.0, (0.0, 0.03, -0.05)),
        (6.8, (0.0, 0.004, -0.05)),
        (7.8, (0.0, 0.004, -0.03)),
        (8.5, (0.0, 0.004, -0.03)),
        (9.1, (0.0, 0.03, -0.03))],
}
PRESS = (2.6, 3.0)     # windows (s after motion onset) to look at
STROKE = (3.3, 4.4)
PINCH = (7.0, 8.4)
SCRIPT_SECONDS = 9.5
ONSET = 1.5            # s: the fingers start where the scene's script does; finger 0 first moves here
FIRST_MOTION = {0: ONSET, 1: 5.0}


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Server:
    """hapticloth-server --device remote with the hanging square, run for `duration` s."""

    def __init__(self, duration, *extra, port=None, host="127.0.0.1", name="t", netns=None):
        self.port = port or free_port()
        self.endpoint = f"tcp/{host}:{self.port}"
        cmd = [str(SERVER), "--scene", str(SCENE), "--device", "remote", "--json",
               "--duration", str(duration), "--name", name]
        if "--no-zenoh" not in extra:
            cmd += ["--zenoh-listen", self.endpoint]
        cmd += list(extra)
        prefix = ["ip", "netns", "exec", netns] if netns else []
        self.duration = duration
        self.p = subprocess.Popen(prefix + cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                  text=True)

    def result(self):
        """The server's JSON summary (waits for it to finish, bounded)."""
        out, err = self.p.communicate(timeout=self.duration + 60)
        assert self.p.returncode == 0, f"server exit {self.p.returncode}: {err[-2000:]}"
        return json.loads(out.strip().splitlines()[-1])

    def kill(self):
        if self.p.poll() is None:
            self.p.kill()
            self.p.wait(timeout=10)


def connect(server, name="t", timeout=40.0):
    """A zenoh client that has the scene (so the server is up); bounded retries."""
    from hapticloth.client import Client
    deadline = time.monotonic() + timeout
    while True:
        try:
            c = Client("zenoh", server=name, endpoint=server.endpoint)
            try:
                scene = c.get_scene(timeout=2.0)
                return c, scene
            except TimeoutError:
                c.close()
                raise
        except Exception:
            if server.p.poll() is not None:
                raise RuntimeError("server exited: " + server.p.stderr.read()[-2000:])
            if time.monotonic() > deadline:
                raise
            time.sleep(0.3)


class Samples:
    """Collects haptic samples and cloth states (thread-safe)."""

    def __init__(self):
        self.lock = threading.Lock()
        self.t, self.dev, self.force, self.contact = [], [], [], []
        self.cloth = []   # (time, positions)
        self.stats = []

    def on_haptics(self, m):
        with self.lock:
            for k in range(m.num_samples):
                self.t.append(m.time[k])
                self.dev.append([list(p) for p in m.device_position[k]])
                self.force.append([list(f) for f in m.force[k]])
                self.contact.append(list(m.in_contact[k]))

    def on_cloth(self, m):
        with self.lock:
            self.cloth.append((m.time, [list(p) for p in m.positions]))

    def onset(self, rest, finger=0, eps=1e-5):
        """Loop time at which `finger` left its rest position (the command was taken)."""
        with self.lock:
            for t, d in zip(self.t, self.dev):
                if math.dist(d[finger], rest) > eps:
                    return t
        return None

    def window(self, t0, a, b):
        with self.lock:
            return [(t - t0, d, f, c) for t, d, f, c in zip(self.t, self.dev, self.force, self.contact)
                    if t0 + a <= t <= t0 + b]


def rest_of(s, finger):
    with s.lock:
        return s.dev[0][finger]


def inject_script(c, script=SCRIPT):
    answers = c.inject_trajectories({f: ([t for t, _ in pts], [p for _, p in pts])
                                     for f, pts in script.items()}, wait=5.0)
    for seq, ok, text in answers.values():
        assert ok, text


def mean(xs):
    return sum(xs) / len(xs)


def run_scripted(tmp_path, record_to=None, replay_from=None):
    """One server run with the script injected (or a recording replayed); returns the samples,
    the scene, the rest positions and the server's summary. The server runs on its stepped
    clock (--fast: the same session, deterministic, as fast as the machine allows), so what the
    fingers do to the cloth does not depend on how loaded the machine is; the clients still
    talk to it over zenoh in real time."""
    # The session outlasts the script by 20 s of its own time: a --fast server runs several times
    # faster than real time, so the 1-2 s the client takes to connect and send (a replay waits for
    # its acknowledgements) are 6-7 s of session time; with 6 s to spare, the replayed run's
    # session once ended 1.3 s into the pinch window (169 of its 1401 ms in common).
    srv = Server(SCRIPT_SECONDS + 20.0, "--fast")
    c = None
    try:
        c, scene = connect(srv)
        s = Samples()
        rest0 = None
        first = threading.Event()

        def on_h(m):
            nonlocal rest0
            if rest0 is None and m.num_samples:
                rest0 = list(m.device_position[0][0])
                first.set()
            s.on_haptics(m)

        c.subscribe_haptics(on_h)
        c.subscribe_state(s.on_cloth)
        rec = c.record(str(record_to), ["haptics", "cloth", "events"]) if record_to else None
        assert first.wait(10.0), "no haptic samples"
        assert rec is None or rec.wait_started(10.0), "the recorder got no cloth message"
        if replay_from:
            c.listen_for_answers()
            sent = c.replay(str(replay_from), mode="positions")
            assert len(sent) == 2
            for seq in sent:  # each finger's trajectory reached the server and was taken
                ok, text = c.wait_ack(seq, 5.0)
                assert ok, text
        else:
            inject_script(c)
        summary = srv.result()
        time.sleep(0.5)  # the last messages in flight
        if rec:
            rec.stop()
        return s, scene, rest0, summary
    finally:
        if c:
            c.close()
        srv.kill()


# --- tests -------------------------------------------------------------------------------------

def test_press_stroke_pinch_forces_and_cloth(tmp_path):
    log = tmp_path / "run.lcmlog"
    s, scene, rest0, summary = run_scripted(tmp_path, record_to=log)
    assert scene.topology.num_triangles == 968 and scene.device_name == "remote"
    t0 = s.onset(rest0)
    assert t0 is not None, "finger 0 never moved"
    t0 -= ONSET  # when the device took the command
    # Device positions follow the script (to the sample: 1 ms at <= 0.1 m/s here is 0.1 mm).
    for tt, (x, y, z) in [(1.5, (-0.02, -0.04, 0.0)), (2.8, (-0.02, -0.004, 0.0)), (8.1, (0.0, -0.004, -0.03))]:
        w = s.window(t0, tt - 0.005, tt + 0.005)
        assert w, f"no samples at {tt} s"
        assert math.dist(w[0][1][0], (x, y, z)) < 5e-4

    # The hanging cloth gives way to a press (a few mN), a pinch holds it (over a newton).
    # (The cloth swings away from a press, so contact comes and goes: ask for some of it.)
    press = [r for r in s.window(t0, PRESS[0] - 0.3, PRESS[1]) if r[3][0]]
    assert len(press) > 0.2 * 1000 * (PRESS[1] - PRESS[0] + 0.3), "finger 0 not in contact while pressing"
    fy = mean([r[2][0][1] for r in press])
    assert fy < -0.0005, f"pressing +y into the cloth: the force on the finger pushes back (-y), got {fy}"
    stroke = [r for r in s.window(t0, *STROKE) if r[3][0]]
    assert len(stroke) > 0.5 * 1000 * (STROKE[1] - STROKE[0]), "finger 0 lost the cloth while stroking"
    fx = mean([r[2][0][0] for r in stroke])
    assert fx < 0.0, f"stroking +x: friction on the finger points -x, got {fx}"
    # Before the press the fingers are free.
    assert not any(r[3][0] or r[3][1] for r in s.window(t0, 0.6, 1.5))
    pinch = s.window(t0, *PINCH)
    both = [r for r in pinch if r[3][0] and r[3][1]]
    assert len(both) > 0.5 * len(pinch), "pinch: both fingers in contact"
    assert mean([r[2][0][1] for r in both]) < -0.5 and mean([r[2][1][1] for r in both]) > 0.5

    # Cloth positions: the press pushes the cloth at finger 0 back (+y in the scene), the
    # pinch-lift raises the cloth between the fingers.
    origin = scene.device_origin

    def near(tt, p_dev):
        p = [p_dev[k] + origin[k] for k in range(3)]
        best = min(s.cloth, key=lambda c: abs(c[0] - (t0 + tt)))
        return min(best[1], key=lambda v: math.dist(v, p))

    before = near(1.4, (-0.02, 0.0, 0.0))
    pressed = near(2.9, (-0.02, 0.0, 0.0))
    assert abs(before[1] - origin[1]) < 0.004, "the cloth hangs in the device's y = 0 plane"
    assert pressed[1] > before[1] + 0.001, f"the press moved the cloth back ({before} -> {pressed})"
    z_before = near(5.9, (0.0, 0.0, -0.05))[2]
    lifted = [c for c in s.cloth if t0 + 8.0 <= c[0] <= t0 + 8.4]
    z_lift = max(max(v[2] for v in c[1] if abs(v[0] - origin[0]) < 0.02 and v[2] < origin[2] - 0.02)
                 for c in lifted)
    assert z_lift > z_before + 0.003, f"pinch-lift: cloth between the fingers rises ({z_before} -> {z_lift})"
    assert summary["haptic_ticks"] > 0


def _record_and_replay(tmp_path):
    """One record-and-replay comparison; returns what disagreed (empty: all agree)."""
    failures = []
    log = tmp_path / "rec.lcmlog"
    log.unlink(missing_ok=True)
    a, _, rest_a, _ = run_scripted(tmp_path, record_to=log)
    b, _, rest_b, _ = run_scripted(tmp_path, replay_from=log)
    ta, tb = a.onset(rest_a), b.onset(rest_b)
    assert ta is not None and tb is not None
    ta, tb = ta - ONSET, tb - ONSET  # script time 0 of each run, aligned on the first motion

    def series(s, t0, finger):
        return {round(t * 1000): f[finger] for t, d, f, c in s.window(t0, 0.5, 9.0)}

    # How far apart the two fingers' commands were taken in each run, against the script's
    # 3.5 s: the commands travel separately, and a gap between their arrivals is stretched by
    # the stepped clock's speed. Printed so that a failure shows whether the pinch's fingers
    # were out of step.
    for name, run in (("recorded", a), ("replayed", b)):
        f0 = run.onset(rest_of(run, 0), 0)
        f1 = run.onset(rest_of(run, 1), 1)
        if f0 is not None and f1 is not None:
            print(f"{name}: finger 1 first moved {f1 - f0:.3f} s after finger 0 (script: "
                  f"{FIRST_MOTION[1] - FIRST_MOTION[0]:.3f} s)")
            # The fingers' commands are one batch (same source and utime): taken in step however
            # far apart they arrive (issue 36 item 15; before, 62 ms apart under load).
            if abs((f1 - f0) - (FIRST_MOTION[1] - FIRST_MOTION[0])) > 0.010:
                failures.append(f"{name}: the fingers out of step by "
                                f"{(f1 - f0) - (FIRST_MOTION[1] - FIRST_MOTION[0]):.3f} s")
    for finger in (0, 1):
        # The fingers moved the same way: device positions, each finger aligned on its own
        # first motion (each finger's command is taken on its own tick).
        fa0 = a.onset(rest_of(a, finger), finger) - FIRST_MOTION[finger]
        fb0 = b.onset(rest_of(b, finger), finger) - FIRST_MOTION[finger]
        da = {round(t * 1000): d[finger] for t, d, f, c in a.window(fa0, 0.5, 9.0)}
        db = {round(t * 1000): d[finger] for t, d, f, c in b.window(fb0, 0.5, 9.0)}
        keys = [k for k in da if k in db]
        worst = max(keys, key=lambda k: math.dist(da[k], db[k]))
        assert math.dist(da[worst], db[worst]) < 2e-3, (finger, worst, da[worst], db[worst])
        # Forces on the same clock as the positions: the cloth's own onset (ta, tb) can be
        # set off by a twitch of the cloth in one run and shift the window before the pinch.
        fa, fb = series(a, fa0, finger), series(b, fb0, finger)
        common = [k for k in fa if k in fb and PINCH[0] * 1e3 <= k <= PINCH[1] * 1e3]
        assert len(common) > 1000, len(common)
        ma = [mean([fa[k][i] for k in common]) for i in range(3)]
        mb = [mean([fb[k][i] for k in common]) for i in range(3)]
        pa = max(math.hypot(*fa[k]) for k in common)
        pb = max(math.hypot(*fb[k]) for k in common)
        rms = math.sqrt(mean([math.dist(fa[k], fb[k]) ** 2 for k in common]))
        print(f"finger {finger}: mean force {[round(x, 3) for x in ma]} / {[round(x, 3) for x in mb]} N, "
              f"peak {pa:.3f} / {pb:.3f} N, rms difference {rms:.3f} N")
        if math.dist(ma, mb) > 0.2 * math.hypot(*ma):
            failures.append(f"finger {finger}: mean force {ma} recorded, {mb} replayed")
        if abs(pa - pb) > 0.2 * max(pa, pb):
            failures.append(f"finger {finger}: peak force {pa} recorded, {pb} replayed")
    return failures


def test_recording_replays_to_the_same_forces(tmp_path):
    """Record a scripted run, replay its device positions into a fresh server, compare forces.
    Both servers run the session on the stepped clock; the fingers' commands are taken whenever
    they arrive, each finger's batch (both fingers sent together) starting together, so the two
    runs differ by where the cloth was at that moment. Tolerance, per finger over the
    pinch-lift-hold window: the mean force vectors agree within 20 % of the recorded one's
    magnitude, the peak forces within 20 %, the fingers' first motions within 10 ms of the
    script's. The replayed device positions match the recorded ones to 2 mm.

    The cause of its one failure in 22 runs (issue 36 item 15): the two fingers' commands were
    taken each at the tick it arrived, and on the stepped clock (several times real time) a
    wall-clock gap between their arrivals became tens of ms of session time: under load the
    replayed pinch ran 43-62 ms out of step, and the RMS force difference grew from 0.03 to
    0.34 N of 3.1 N, near the bound. With batches: 4 ms at most, RMS 0.009-0.014 N, under
    the same load (a second test process)."""
    failures = _record_and_replay(tmp_path)
    assert not failures, failures


def test_a_late_joiner_gets_the_scene():
    srv = Server(8.0)
    try:
        first, _ = connect(srv)
        first.close()
        time.sleep(1.0)  # the run is under way
        from hapticloth.client import Client
        c = Client("zenoh", server="t", endpoint=srv.endpoint)
        try:
            scene = c.get_scene(timeout=5.0)
        finally:
            c.close()
        topo = scene.topology
        assert (topo.num_triangles, topo.num_vertices) == (968, 529)
        assert len(topo.weave_uv) == 968 and len(topo.rest_positions) == 529
        assert scene.server_name == "t" and scene.scene_name == "hanging_square"
        assert "denim" in scene.material_name and scene.areal_density > 0
        assert scene.fingers == 2 and scene.max_command_speed == 1.0
        keys = dict(zip(scene.topics, scene.key_expressions))
        assert keys["cloth"] == "hapticloth/t/cloth" and keys["trajectory"] == "hapticloth/t/trajectory"
        srv.result()
    finally:
        srv.kill()


def test_command_line_record_and_inject(tmp_path):
    """hapticloth-record and hapticloth-inject (CSV time,finger,x,y,z) against a server."""
    bindir = Path(sys.executable).parent
    csv = tmp_path / "traj.csv"
    csv.write_text("time,finger,x,y,z\n0.5,0,-0.02,-0.03,0.0\n1.0,0,-0.02,-0.02,0.0\n"
                   "0.5,1,0.06,0.03,0.0\n")
    bad = tmp_path / "bad.csv"
    bad.write_text("0.0,0,0.5,0.0,0.0\n")
    log = tmp_path / "rec.lcmlog"
    srv = Server(10.0)
    rec = None
    try:
        c, _ = connect(srv)
        c.close()
        conn = ["--server", "t", "--endpoint", srv.endpoint]
        rec = subprocess.Popen([str(bindir / "hapticloth-record"), str(log), "--duration", "2"] + conn,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        # inject only once the recorder's subscriptions are in place, or its events are missed
        assert rec.stderr.readline().startswith(f"recording {log}"), rec.stderr.read()
        ok = subprocess.run([str(bindir / "hapticloth-inject"), str(csv)] + conn,
                            capture_output=True, text=True, timeout=60)
        assert ok.returncode == 0, ok.stderr
        assert ok.stdout.count("accepted:") == 2
        no = subprocess.run([str(bindir / "hapticloth-inject"), str(bad)] + conn,
                            capture_output=True, text=True, timeout=60)
        assert no.returncode == 1 and "outside the workspace" in no.stdout
        out, err = rec.communicate(timeout=60)
        assert rec.returncode == 0, err
        counts = dict(kv.split("=") for kv in out.split())
        assert int(counts["haptics"]) > 100 and int(counts["cloth"]) > 50 and int(counts["scene"]) >= 1
        srv.result()
    finally:
        if rec and rec.poll() is None:
            rec.kill()
        srv.kill()
    import lcm
    channels = {ev.channel for ev in lcm.EventLog(str(log), "r")}
    assert {"HAPTICLOTH_HAPTICS", "HAPTICLOTH_CLOTH", "HAPTICLOTH_SCENE", "HAPTICLOTH_EVENTS"} <= channels


STALL_SCRIPT = r"""
import sys, time, threading
sys.path.insert(0, %(pkg)r)
from hapticloth.client import Client
c = Client("zenoh", server="t", endpoint=%(ep)r)
block = threading.Event()
def stall(m):
    block.wait(60)  # never returns during the run: this client's receive path is stuck
c.subscribe_state(stall)
c.subscribe_haptics(stall)
c.subscribe("topology", stall)
print("ready", flush=True)
time.sleep(60)
"""

SUB_SCRIPT = r"""
import sys, time
sys.path.insert(0, %(pkg)r)
from hapticloth.client import Client
c = Client("zenoh", server="t", endpoint=%(ep)r)
c.subscribe_state(lambda m: None)
c.subscribe_haptics(lambda m: None)
print("ready", flush=True)
time.sleep(60)
"""


def test_killed_or_stalled_subscribers_never_stall_the_server():
    duration = 8.0
    srv = Server(duration, "--cloth-rate", "120")
    procs = []
    c = None
    try:
        c, _ = connect(srv)
        pkg = str(REPO / "clients" / "python")
        for script in (STALL_SCRIPT, SUB_SCRIPT, SUB_SCRIPT):
            p = subprocess.Popen([sys.executable, "-c", script % {"pkg": pkg, "ep": srv.endpoint}],
                                 stdout=subprocess.PIPE, text=True)
            procs.append(p)
        for p in procs:
            assert p.stdout.readline().strip() == "ready"
        s = Samples()
        stats = []
        c.subscribe_haptics(s.on_haptics)
        c.subscribe_stats(stats.append)
        time.sleep(1.0)
        procs[1].send_signal(signal.SIGKILL)   # a subscriber dies mid-stream
        time.sleep(0.5)
        seq, ok, text = c.inject_trajectory(0, [0.5], [[-0.02, -0.04, 0.0]], wait=5.0)
        assert ok, text  # commands still handled
        summary = srv.result()
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.wait(timeout=10)
        if c:
            c.close()
        srv.kill()
    # The haptic loop kept time: every tick ran or, after one of the platform's late wake-ups
    # (1-9 ms, about once per 10 s), was skipped and counted as missed, and no tick waited for a
    # publisher. A loop blocked by a dead or stalled subscriber would be late by the length of
    # the stall (seconds here); the VM's own timer hiccups make a tick late by at most tens of
    # milliseconds, and they, not the publishers, are what the missed-deadline count measures
    # on a loaded 2-core machine (so its size is not asserted: timing targets live in the
    # benchmarks).
    ticks = round(duration * 1000)
    assert summary["haptic_ticks"] <= ticks
    assert summary["haptic_ticks"] + summary["missed_deadlines"] >= ticks
    assert summary["period_error_us"]["max"] < 250e3
    # The healthy client kept receiving to the end: no stall (a gap of at most a few batches,
    # which zenoh may drop for a moment while a dead peer's session is torn down) and almost
    # every sample.
    with s.lock:
        assert s.t and s.t[-1] > duration - 1.0
        gaps = [b - a for a, b in zip(s.t, s.t[1:])]
        span = s.t[-1] - s.t[0]
        print(f"healthy client: {len(s.t)} samples over {span:.3f} s, largest gap {max(gaps) * 1e3:.1f} ms; "
              f"server: missed {summary['missed_deadlines']}, period error {summary['period_error_us']}")
    # A subscriber blocked by the dead peer would wait out its session's lease (seconds); a
    # loaded machine delays a batch by tens of milliseconds: 1 s is the safety limit between.
    assert max(gaps) < 1.0
    # Almost every sample the loop published over that span (one a tick it ran).
    assert len(s.t) > 0.95 * summary["haptic_ticks"] * span / duration
    assert stats and stats[-1].ticks > 0


# --- network namespaces ------------------------------------------------------------------------

def _need_netns():
    import pytest
    if os.geteuid() != 0:
        pytest.skip("network namespaces need root")
    for tool in ("unshare", "ip"):
        if not shutil.which(tool):
            pytest.skip(f"{tool} not installed")


def test_lcm_end_to_end_in_a_network_namespace(tmp_path):
    """Server and Python client on LCM udpm (ttl=0) inside a namespace made here; the server's
    file:// log is read back with lcm.EventLog."""
    _need_netns()
    import lcm
    from hapticloth import lcmtypes
    log = tmp_path / "server.lcmlog"
    inner = (f"ip link set lo up && ip link set lo multicast on && ip route add 239.0.0.0/8 dev lo && "
             f"exec {sys.executable} {__file__} lcm-inner {log}")
    p = subprocess.run(["unshare", "--net", "sh", "-c", inner], capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 0, p.stderr[-3000:]
    got = json.loads(p.stdout.strip().splitlines()[-1])
    assert got["scene_triangles"] == 968
    assert got["accepted"] and not got["rejected_ok"]
    assert got["haptic_samples"] > 1000 and got["cloth"] > 30
    # The log: every topic, the command the client sent, decodable.
    counts, cmds, haptic = {}, [], 0
    for ev in lcm.EventLog(str(log), "r"):
        counts[ev.channel] = counts.get(ev.channel, 0) + 1
        if ev.channel == "HAPTICLOTH_TRAJECTORY":
            cmds.append(lcmtypes.trajectory_cmd_t.decode(ev.data))
        elif ev.channel == "HAPTICLOTH_HAPTICS":
            haptic += lcmtypes.haptic_state_t.decode(ev.data).num_samples
    for ch in ("SCENE", "TOPOLOGY", "CLOTH", "HAPTICS", "STATS", "EVENTS", "TRAJECTORY"):
        assert counts.get("HAPTICLOTH_" + ch), ch
    # Both commands are logged, the accepted one and the rejected one.
    assert [c.num_points for c in cmds] == [2, 1]
    assert haptic >= got["haptic_samples"]


def lcm_inner(log):
    """Inside the namespace: server on udpm + log, a Python LCM client."""
    sys.path.insert(0, str(REPO / "clients" / "python"))
    from hapticloth.client import Client
    srv = Server(6.0, "--no-zenoh", "--lcm-url", LCM_URL, "--lcm-log", log)
    c = Client("lcm", server="t", lcm_url=LCM_URL)
    try:
        scene = c.get_scene(timeout=40.0)
        s = Samples()
        c.subscribe_haptics(s.on_haptics)
        c.subscribe_state(s.on_cloth)
        _, ok, _ = c.inject_trajectory(0, [0.5, 1.0], [[-0.02, -0.04, 0.0], [-0.02, -0.01, 0.0]], wait=5.0)
        _, bad, _ = c.inject_trajectory(0, [0.0], [[0.5, 0.0, 0.0]], wait=5.0)
        time.sleep(2.0)
        srv.result()
        print(json.dumps({"scene_triangles": scene.topology.num_triangles, "accepted": ok,
                          "rejected_ok": bad, "haptic_samples": len(s.t), "cloth": len(s.cloth)}))
    finally:
        c.close()
        srv.kill()


def test_two_hosts_over_a_veth_link():
    """The server in one namespace, a Python client in another, joined by a veth pair: zenoh
    tcp across a real network interface (how renderers on other machines attach)."""
    _need_netns()
    tag = str(os.getpid())
    ns_s, ns_c, va, vb = f"hcs{tag}", f"hcc{tag}", f"hca{tag}"[:15], f"hcb{tag}"[:15]
    srv = None

    def ip(*args):
        subprocess.run(["ip", *args], check=True, capture_output=True, timeout=20)

    try:
        ip("netns", "add", ns_s)
        ip("netns", "add", ns_c)
        ip("link", "add", va, "type", "veth", "peer", "name", vb)
        ip("link", "set", va, "netns", ns_s)
        ip("link", "set", vb, "netns", ns_c)
        ip("-n", ns_s, "addr", "add", "192.0.2.1/24", "dev", va)
        ip("-n", ns_c, "addr", "add", "192.0.2.2/24", "dev", vb)
        for ns, v in ((ns_s, va), (ns_c, vb)):
            ip("-n", ns, "link", "set", "lo", "up")
            ip("-n", ns, "link", "set", v, "up")
        srv = Server(8.0, host="192.0.2.1", port=7447, netns=ns_s)
        p = subprocess.run(["ip", "netns", "exec", ns_c, sys.executable, __file__, "veth-client",
                            "tcp/192.0.2.1:7447"], capture_output=True, text=True, timeout=90)
        assert p.returncode == 0, p.stderr[-3000:]
        got = json.loads(p.stdout.strip().splitlines()[-1])
        assert got["triangles"] == 968
        assert got["accepted"]
        assert got["haptic_samples"] > 500 and got["cloth"] > 20
        srv.result()
    finally:
        if srv:
            srv.kill()
        for ns in (ns_s, ns_c):
            subprocess.run(["ip", "netns", "del", ns], capture_output=True, timeout=20)


def veth_client(endpoint):
    sys.path.insert(0, str(REPO / "clients" / "python"))
    from hapticloth.client import Client
    deadline = time.monotonic() + 40
    while True:
        try:
            c = Client("zenoh", server="t", endpoint=endpoint)
            scene = c.get_scene(timeout=2.0)
            break
        except Exception:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.3)
    s = Samples()
    c.subscribe_haptics(s.on_haptics)
    c.subscribe_state(s.on_cloth)
    _, ok, _ = c.inject_trajectory(1, [0.5], [[0.06, 0.04, 0.0]], wait=5.0)
    # The server answers from before its preroll (its transports open first): count 1.5 s of
    # the session from its first haptic sample.
    deadline = time.monotonic() + 40
    while not s.t and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(1.5)
    c.close()
    print(json.dumps({"triangles": scene.topology.num_triangles, "accepted": ok,
                      "haptic_samples": len(s.t), "cloth": len(s.cloth)}))


if __name__ == "__main__":
    role = sys.argv[1]
    if role == "lcm-inner":
        lcm_inner(sys.argv[2])
    elif role == "veth-client":
        veth_client(sys.argv[2])
    else:
        sys.exit(f"unknown role {role}")


def test_replay_keeps_a_recorded_batch_together(tmp_path):
    """A recorded batch (two fingers' commands of one source and utime) is one batch again in
    the replay, however far apart the recorder logged them: the log's timestamp is when the
    recorder received each, and a recorder held up 0.3 s once put the replayed pinch's fingers
    1.2 s out of step on the stepped clock. Another batch keeps its own time."""
    import lcm
    from hapticloth.client import channel, read_replay, trajectory_message

    log = tmp_path / "batches.lcmlog"
    w = lcm.EventLog(str(log), "w", overwrite=True)
    sent = []
    for stamp, finger, source, utime in ((1_000_000, 0, "replayer", 111), (1_300_000, 1, "replayer", 111),
                                         (2_000_000, 0, "replayer", 222)):
        m = trajectory_message(finger, [0.1], [(0.0, 0.0, 0.0)])
        m.source, m.utime = source, utime
        w.write_event(stamp, channel("trajectory"), m.encode())
        sent.append((finger, utime))
    w.close()
    plan = read_replay(log, mode="commands")
    assert [(m.finger, m.utime) for _, m in plan] == sent
    assert [due for due, _ in plan] == [0.0, 0.0, 1.0]
    # At double speed the spacing halves; the batch stays together.
    assert [due for due, _ in read_replay(log, mode="commands", speed=2.0)] == [0.0, 0.0, 0.5]
