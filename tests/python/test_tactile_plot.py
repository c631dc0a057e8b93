"""hapticloth-tactile-plot (clients/python/hapticloth/tactile_plot.py): the spectrogram of a
finger's tactile vibration from a run's LCM log, with speed / period over it. On the main job's
scene (stepped clock) the spectrogram's loudest frequency during the stroke is the weave's
frequency the finger's speed over the fabric predicts; a log without tactile messages is refused
naming the file."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from buildpaths import build_dir
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SCENE = REPO / "tools" / "scenes" / "hanging_square.toml"


@pytest.fixture(scope="module")
def run_log(tmp_path_factory):
    d = tmp_path_factory.mktemp("tactile_plot")
    log = d / "run.lcm"
    r = subprocess.run([str(build_dir() / "hapticloth-server"), "--scene", str(SCENE), "--duration", "4",
                        "--fast", "--json", "--no-zenoh", "--lcm-log", str(log)],
                       cwd=d, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    return log


def test_spectrogram_peaks_at_speed_over_period_during_the_stroke(run_log, tmp_path):
    from hapticloth.tactile_plot import TactileLog
    log = TactileLog(run_log, 0)
    assert log.rate == 4000.0 and log.weft > 0 and log.warp > 0
    times, freqs, db = log.spectrogram()
    t, fu, _ = log.weave_frequencies()
    stroke = (times > 2.3) & (times < 3.2)  # the script's stroke: 2.0-3.5 s along x, the weft
    assert stroke.sum() > 10
    peak = freqs[np.argmax(db[:, stroke].mean(axis=1)[1:]) + 1]
    expected = np.nanmedian(fu[(t > 2.3) & (t < 3.2)])
    bin_hz = freqs[1] - freqs[0]
    assert abs(peak - expected) <= max(0.05 * expected, bin_hz), (peak, expected, bin_hz)

    out = tmp_path / "s.png"
    r = subprocess.run([sys.executable, "-m", "hapticloth.tactile_plot", str(run_log), "-o", str(out)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_log_without_tactile_messages_is_refused(run_log, tmp_path):
    import lcm
    plain = tmp_path / "plain.lcm"
    src, dst = lcm.EventLog(str(run_log), "r"), lcm.EventLog(str(plain), "w", overwrite=True)
    for ev in src:
        if ev.channel != "HAPTICLOTH_TACTILE":
            dst.write_event(ev.timestamp, ev.channel, ev.data)
    dst.close()
    r = subprocess.run([sys.executable, "-m", "hapticloth.tactile_plot", str(plain), "-o", str(tmp_path / "x.png")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and str(plain) in r.stderr and "no tactile_state_t" in r.stderr, r.stderr
    r = subprocess.run([sys.executable, "-m", "hapticloth.tactile_plot", str(run_log), "-o", str(tmp_path / "y.png"),
                        "--finger", "7"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "--finger 7" in r.stderr, r.stderr
