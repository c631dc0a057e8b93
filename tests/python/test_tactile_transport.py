"""The tactile output published (issue 37, point 4): the main job's scene, whose mock device has
a tactile display, run in real time; a zenoh client subscribed to hapticloth/<server>/tactile
and the LCM log both get tactile_state_t, and the stroke's vibration in the log has the
dominant frequency the server's own tactile line reports. Real zenoh and real LCM over loopback."""

from __future__ import annotations

import json
import math
import threading
import time

from buildpaths import build_dir
from server_session import free_port
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SCENE = REPO / "tools" / "scenes" / "hanging_square.toml"


def dominant_hz(x, rate):
    """The peak of |DFT|^2 of the mean-removed signal, Hz, and the bin."""
    import numpy as np
    y = np.asarray(x, dtype=float)
    p = np.abs(np.fft.rfft(y - y.mean())) ** 2
    return (int(np.argmax(p[1:])) + 1) * rate / len(y), rate / len(y)


def test_tactile_goes_out_on_zenoh_and_lcm(tmp_path):
    from hapticloth import lcmtypes
    from hapticloth.client import Client
    import lcm

    port = free_port()
    log = tmp_path / "run.lcm"
    cmd = [str(build_dir() / "hapticloth-server"), "--scene", str(SCENE), "--duration", "4", "--json",
           "--name", "tt", "--zenoh-listen", f"tcp/127.0.0.1:{port}", "--lcm-log", str(log)]
    srv = subprocess.Popen(cmd, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    got, lock = [], threading.Lock()
    c = None
    try:
        deadline = time.monotonic() + 40.0
        while c is None:  # bounded: the server takes its preroll (6 s) before it answers
            try:
                c = Client("zenoh", server="tt", endpoint=f"tcp/127.0.0.1:{port}")
            except Exception:
                assert srv.poll() is None and time.monotonic() < deadline, srv.stderr.read()[-2000:]
                time.sleep(0.3)

        def on_tactile(m):
            with lock:
                got.append(m)

        c.subscribe_tactile(on_tactile)
        out, err = srv.communicate(timeout=90)
        assert srv.returncode == 0, err[-2000:]
        time.sleep(0.5)  # the last messages in flight
    finally:
        if c:
            c.close()
        if srv.poll() is None:
            srv.kill()
    summary = json.loads(out.strip().splitlines()[-1])
    (stroke,) = [s for s in summary["tactile"]["strokes"] if not s["carried"]]
    assert stroke["finger"] == 0 and stroke["matches"], stroke

    # zenoh: the display's layout, and the stroke's ticks with texture on finger 0.
    with lock:
        msgs = list(got)
    assert msgs, "no tactile_state_t over zenoh"
    m0 = msgs[0]
    assert (m0.num_fingers, m0.samples_per_tick, m0.rows, m0.cols, m0.num_pins, m0.sample_rate) == (2, 4, 6, 4, 24, 4000)
    ticks = [(t, m.vibration[k][0]) for m in msgs for k, t in enumerate(m.time)]
    assert len(ticks) > 2000, len(ticks)  # of about 4000: zenoh drops under congestion, never blocks
    textured = [t for t, v in ticks if any(x != 0.0 for x in v)]
    assert any(stroke["start"] <= t <= stroke["end"] for t in textured)

    # The LCM log: every tick, in order, and the stroke's frequency recomputed from its samples
    # over the stretch the server analysed: the server's peak, to a bin (the server holds that
    # peak to v / lambda: `matches` above).
    rows = []
    for ev in lcm.EventLog(str(log), "r"):
        if ev.channel == "HAPTICLOTH_TACTILE":
            m = lcmtypes.tactile_state_t.decode(ev.data)
            rows += [(m.tick[k], m.time[k], m.vibration[k][0]) for k in range(m.num_ticks)]
    ticks_logged = [r[0] for r in rows]
    assert ticks_logged == list(range(ticks_logged[0], ticks_logged[0] + len(ticks_logged))), "a gap in the log"
    x = [v for _, t, block in rows if stroke["start"] - 1e-6 <= t <= stroke["end"] + 1e-6 for v in block]
    hz, bin_hz = dominant_hz(x, 4000.0)
    assert abs(hz - stroke["peak_hz"]) <= 1.01 * max(bin_hz, stroke["bin_hz"]), (hz, stroke)
