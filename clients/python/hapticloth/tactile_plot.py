"""A spectrogram of what a finger's tactile display was sent, from a run's LCM log
(``hapticloth-server --lcm-log`` with a device that has a tactile display), with the weave's
frequency the finger's speed over the fabric predicts, v / period along the weft and the warp,
drawn over it (docs/tactile.md).

    hapticloth-tactile-plot out/hanging_square.lcm -o out/tactile.png [--finger 0] [--size 1200x700]

Exit code 2 (one line naming the file or option) when the log cannot be read or holds no
tactile_state_t, or the PNG cannot be written.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from .errors import UserError, check_writable, run_cli
from .lcmtypes import open_event_log, tactile_state_t
from .plot import FINGER_COLORS, log_plot_parser, parse_size

#: STFT: samples a window (Hann), and the hop between windows
WINDOW, HOP = 512, 64
#: s: the speed over the fabric is the slope of (u, v) over this long
SPEED_SPAN = 0.05


class TactileLog:
    """One finger's vibration samples and place on the fabric, tick by tick."""

    def __init__(self, path, finger):
        ticks, time, vib, u, v, touching = [], [], [], [], [], []
        meta = None
        log = open_event_log(path)
        try:
            for ev in log:
                if ev.channel != "HAPTICLOTH_TACTILE":
                    continue
                try:
                    m = tactile_state_t.decode(ev.data)
                except (ValueError, IndexError, UnicodeDecodeError):
                    continue
                if finger >= m.num_fingers:
                    raise UserError(f"{path}: --finger {finger}: the log's device has {m.num_fingers} fingers")
                meta = m
                for k in range(m.num_ticks):
                    ticks.append(m.tick[k])
                    time.append(m.time[k])
                    vib.append(m.vibration[k][finger])
                    u.append(m.u[k][finger])
                    v.append(m.v[k][finger])
                    touching.append(list(m.touching[k])[finger])  # lcm-gen decodes booleans as a map
        finally:
            log.close()
        if meta is None or meta.samples_per_tick < 1:
            raise UserError(f"{path}: no tactile_state_t with vibration samples (a device without a tactile display?)")
        self.rate = float(meta.sample_rate)
        self.weft, self.warp = float(meta.weft_period), float(meta.warp_period)
        self.time = np.asarray(time)
        self.signal = np.asarray(vib, dtype=float).ravel()
        self.u, self.v = np.asarray(u), np.asarray(v)
        self.touching = np.asarray(touching, dtype=bool)
        self.samples_per_tick = meta.samples_per_tick

    def spectrogram(self):
        """(times s, frequencies Hz, power dB) of the vibration, WINDOW-sample Hann windows."""
        x = self.signal
        if len(x) < WINDOW:
            raise UserError(f"the log holds {len(x)} vibration samples, fewer than a window of {WINDOW}")
        w = np.hanning(WINDOW)
        starts = np.arange(0, len(x) - WINDOW + 1, HOP)
        frames = np.stack([x[s:s + WINDOW] * w for s in starts])
        p = np.abs(np.fft.rfft(frames, axis=1)) ** 2
        t0 = self.time[0] - (self.samples_per_tick - 1) / self.rate
        times = t0 + (starts + WINDOW / 2) / self.rate
        return times, np.fft.rfftfreq(WINDOW, 1.0 / self.rate), 10.0 * np.log10(p.T + 1e-30)

    def weave_frequencies(self):
        """(times, weft Hz, warp Hz): |du/dt| / weft period and |dv/dt| / warp period while in
        contact, NaN elsewhere."""
        n = max(1, int(round(SPEED_SPAN / np.median(np.diff(self.time))))) if len(self.time) > 1 else 1
        t, fu, fv = [], [], []
        for i in range(0, len(self.time) - n, max(1, n // 5)):
            j = i + n
            dt = self.time[j] - self.time[i]
            ok = dt > 0 and self.touching[i:j + 1].all()
            t.append(0.5 * (self.time[i] + self.time[j]))
            su = abs(self.u[j] - self.u[i]) / dt if ok else np.nan
            sv = abs(self.v[j] - self.v[i]) / dt if ok else np.nan
            fu.append(su / self.weft if self.weft > 0 else np.nan)
            fv.append(sv / self.warp if self.warp > 0 else np.nan)
        return np.asarray(t), np.asarray(fu), np.asarray(fv)


def plot(log: TactileLog, out, finger, size=(1200, 700), max_hz=400.0):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    times, freqs, db = log.spectrogram()
    fig, ax = plt.subplots(figsize=(size[0] / 100, size[1] / 100), dpi=100)
    keep = freqs <= max_hz
    top = db[keep].max()
    mesh = ax.pcolormesh(times, freqs[keep], db[keep], shading="nearest", cmap="magma", vmin=top - 60, vmax=top)
    fig.colorbar(mesh, ax=ax, label="power, dB (re the loudest bin)")
    t, fu, fv = log.weave_frequencies()
    if log.weft > 0:
        ax.plot(t, fu, color="#7fdbff", lw=1.2, label=f"speed along the weft / {log.weft * 1e3:.3f} mm")
    if log.warp > 0:
        ax.plot(t, fv, color="#9fff7f", lw=1.2, ls="--", label=f"speed along the warp / {log.warp * 1e3:.3f} mm")
    ax.set_ylim(0, max_hz)
    ax.set_xlabel("session time, s")
    ax.set_ylabel("frequency, Hz")
    ax.set_title(f"Finger {finger}: the vibration its display was sent ({log.rate:.0f} Hz, "
                 f"{WINDOW}-sample windows)", color=FINGER_COLORS[finger % len(FINGER_COLORS)])
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(out)
    plt.close(fig)


def main(argv=None) -> int:
    return run_cli("hapticloth-tactile-plot", _main, argv)


def _main(argv) -> int:
    ap = log_plot_parser("hapticloth-tactile-plot", __doc__)
    ap.add_argument("--finger", type=int, default=0, help="finger (default 0)")
    ap.add_argument("--size", type=parse_size, default=(1200, 700), help="WxH in pixels (default 1200x700)")
    a = ap.parse_args(argv)
    if a.finger < 0:
        raise UserError(f"--finger {a.finger}: must be >= 0")
    check_writable(a.out, "--out")
    log = TactileLog(a.log, a.finger)
    plot(log, a.out, a.finger, a.size)
    print(f"hapticloth-tactile-plot: {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
