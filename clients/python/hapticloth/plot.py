"""Plots of a run from its LCM log (``hapticloth-server --lcm-log``): the contact force on each
finger against time, the haptic period histogram and the loop statistics, to one PNG.

    hapticloth-plot out/hanging_square.lcm -o out/plot.png [--size 1200x800]

Messages are recognised by their type fingerprint, whatever their channel. The period error is
the one the haptic loop measures (haptics/session.cpp), recomputed from each tick's loop-clock
time:
- on the loop's own clock, |wake-up - deadline|. The deadline of a tick is found as the loop
  finds it: the next one on the grid k / rate after the last tick's; after a wake-up more than a
  period late, the loop goes on from the last deadline passed (the ticks skipped are missed
  deadlines, not run);
- on the device's clock (the `started` event says "clock device"), |interval - period| between
  consecutive ticks;
- on a stepped clock every tick is on its deadline.
Quantiles of the period error and the compute time also come from the last loop_stats_t when the
run published one (real time): the log's own figures, beside the recomputed ones.
Exit code 2 (one line naming the file or option) when the log cannot be read or holds no
haptic samples, or the PNG cannot be written.
"""

from __future__ import annotations

import argparse
import struct
import sys
from dataclasses import dataclass, field

import numpy as np

from .errors import UserError, check_writable, run_cli
from .lcmtypes import event_t, haptic_state_t, loop_stats_t, open_event_log, scene_info_t

#: Finger colours, as hapticloth-render draws the fingertips.
FINGER_COLORS = ["#e87d1e", "#1e96af", "#9650be", "#5aa53c"]


@dataclass
class RunLog:
    """What the plots need from a log."""

    time: np.ndarray  # s, (n,) loop clock of each haptic tick
    tick: np.ndarray  # (n,)
    force: np.ndarray  # N, (n, fingers, 3), on the user's fingertip
    contact: np.ndarray  # (n, fingers) bool
    stats: list = field(default_factory=list)  # loop_stats_t, in log order
    scene: object = None  # scene_info_t or None
    device_clock: bool = False  # the session ticked on the device's samples (`started` event)

    @property
    def fingers(self) -> int:
        return self.force.shape[1]


class LogError(UserError):
    """The log cannot be used; the message names the file and the reason."""


def read_log(path) -> RunLog:
    """Reads the haptic samples, loop statistics and scene of an LCM log. Raises UserError
    (LogError) naming the file."""
    log = open_event_log(path)
    kinds = {cls._get_packed_fingerprint(): cls
             for cls in (haptic_state_t, loop_stats_t, scene_info_t, event_t)}
    batches, stats, scene, device_clock = [], [], None, False
    for ev in log:
        cls = kinds.get(ev.data[:8])
        if cls is None:
            continue
        try:
            m = cls.decode(ev.data)
        except (ValueError, struct.error):
            continue
        if cls is haptic_state_t:
            if m.num_samples > 0 and m.num_fingers > 0:
                batches.append(m)
        elif cls is loop_stats_t:
            stats.append(m)
        elif cls is event_t:
            device_clock = device_clock or (m.kind == "started" and "clock device" in m.text)
        elif scene is None:
            scene = m
    log.close()
    if not batches:
        raise LogError(f"{path}: no haptic_state_t message (was the log written by hapticloth-server?)")
    fingers = max(b.num_fingers for b in batches)
    batches = [b for b in batches if b.num_fingers == fingers]
    time = np.concatenate([np.asarray(b.time, dtype=float) for b in batches])
    tick = np.concatenate([np.asarray(b.tick, dtype=np.int64) for b in batches])
    force = np.concatenate([np.asarray(b.force, dtype=float).reshape(b.num_samples, fingers, 3) for b in batches])
    # lcm-gen's Python decodes boolean rows as map objects: materialise them.
    contact = np.concatenate([np.array([list(row) for row in b.in_contact], dtype=bool).reshape(b.num_samples, fingers)
                              for b in batches])
    order = np.argsort(tick, kind="stable")
    return RunLog(time[order], tick[order], force[order], contact[order], stats, scene, device_clock)


def deadlines(time: np.ndarray, tick: np.ndarray, rate: float) -> np.ndarray:
    """The deadline index k (deadline k / rate) each tick waited for, by the loop's rule: the
    one after the last tick's (as many after as ticks are missing from the log); a wake-up over
    a period late is late for that deadline, and the loop goes on from the last deadline it
    passed (the ticks between are skipped, missed deadlines)."""
    k = np.empty(len(time), dtype=np.int64)
    passed = np.floor(time * rate + 1e-9).astype(np.int64)
    last, last_tick = -1, tick[0] - 1 if len(tick) else 0
    for i in range(len(time)):
        k[i] = last + int(tick[i] - last_tick)
        last, last_tick = max(int(k[i]), int(passed[i])), tick[i]
    return k


def period_errors_us(run: RunLog, rate: float) -> np.ndarray:
    """us, the period error of every tick as the loop measures it (see the module's doc): on
    the device's clock one per interval between ticks, else one per tick."""
    if run.device_clock:
        return np.abs(np.diff(run.time) - 1.0 / rate) * 1e6
    return np.abs(run.time - deadlines(run.time, run.tick, rate) / rate) * 1e6


def contact_spans(t: np.ndarray, on: np.ndarray):
    """[(start, end)] of the runs where `on` holds."""
    if not on.any():
        return []
    d = np.diff(np.concatenate([[0], on.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1
    return [(t[a], t[b]) for a, b in zip(starts, ends)]


def stats_text(run: RunLog, errors: np.ndarray) -> str:
    q = np.percentile(errors, [50, 99, 99.9])
    lines = [f"haptic ticks in the log  {len(run.time)}"
             + ("  (on the device's clock)" if run.device_clock else ""),
             f"period error (ticks)  p50 {q[0]:.1f}  p99 {q[1]:.1f}  p99.9 {q[2]:.1f}  "
             f"max {errors.max():.1f} us"]
    if errors.max() < 1e-3:
        lines.append("stepped clock: every tick on its deadline")
    gaps = int(np.count_nonzero(np.diff(run.tick) != 1))
    if gaps:
        lines.append(f"gaps in the tick count (publisher behind)  {gaps}")
    if run.stats:
        s = run.stats[-1]
        lines += [
            "",
            f"loop statistics (last loop_stats_t, {s.ticks} ticks)",
            f"period error  p50 {s.period_error_p50_us:.1f}  p99 {s.period_error_p99_us:.1f}  "
            f"p99.9 {s.period_error_p999_us:.1f}  max {s.period_error_max_us:.1f} us",
            f"tick compute  p50 {s.compute_p50_us:.1f}  p99 {s.compute_p99_us:.1f}  "
            f"p99.9 {s.compute_p999_us:.1f}  max {s.compute_max_us:.1f} us",
            f"missed deadlines  {s.missed_deadlines}",
        ]
    else:
        lines += ["", "no loop_stats_t in the log (published in real-time runs)"]
    peak = np.linalg.norm(run.force, axis=2).max(axis=0)
    lines += [""] + [f"finger {f}: peak force {peak[f]:.3f} N, in contact {100 * run.contact[:, f].mean():.0f}% of ticks"
                     for f in range(run.fingers)]
    return "\n".join(lines)


def plot(run: RunLog, out, size=(1200, 800), title=None):
    """Writes the figure to `out` (PNG), size in pixels."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    dpi = 100
    fig = plt.figure(figsize=(size[0] / dpi, size[1] / dpi), dpi=dpi)
    grid = fig.add_gridspec(2, 2, height_ratios=[1.1, 1], hspace=0.35, wspace=0.25)
    rate = float(run.scene.haptic_rate) if run.scene is not None and run.scene.haptic_rate > 0 else 1000.0
    if title is None:
        title = run.scene.scene_name if run.scene is not None and run.scene.scene_name else "haptic session"
    fig.suptitle(title)

    # Force on each finger against time; contact spans shaded.
    ax = fig.add_subplot(grid[0, :])
    mag = np.linalg.norm(run.force, axis=2)
    for f in range(run.fingers):
        c = FINGER_COLORS[f % len(FINGER_COLORS)]
        ax.plot(run.time, mag[:, f], color=c, lw=1.2, label=f"finger {f}")
        for a, b in contact_spans(run.time, run.contact[:, f]):
            ax.axvspan(a, b, color=c, alpha=0.08, lw=0)
    if run.scene is not None and run.scene.max_force > 0 and mag.max() > 0.5 * run.scene.max_force:
        ax.axhline(run.scene.max_force, color="0.4", ls="--", lw=1, label="force limit")
    ax.set_xlabel("session time (s)")
    ax.set_ylabel("|force| on the fingertip (N)")
    ax.set_xlim(run.time[0], run.time[-1])
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=9)
    ax.set_title("contact force (shaded: in contact)", fontsize=10)

    # Period error histogram, log-spaced bins (most ticks within a microsecond, a long tail).
    ax = fig.add_subplot(grid[1, 0])
    e = period_errors_us(run, rate)
    floor = 0.1
    if e.max() > floor:
        bins = np.geomspace(floor, max(10.0, e.max() * 1.05), 60)
        ax.hist(np.clip(e, floor, None), bins=bins, color="#4a6fa5", log=True)
        ax.set_xscale("log")
        for q, ls in ((99, "--"), (99.9, ":")):
            ax.axvline(max(np.percentile(e, q), floor), color="0.2", ls=ls, lw=1, label=f"p{q:g}")
        ax.legend(fontsize=9)
        what = "|interval - period|" if run.device_clock else "|wake-up - deadline|"
        ax.set_xlabel(f"{what} (us; first bin: <= {floor:g})")
    else:
        ax.text(0.5, 0.5, "stepped clock:\nevery tick on its deadline", ha="center", va="center",
                transform=ax.transAxes)
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_xlabel("|wake-up - deadline| (us)")
    ax.set_ylabel("ticks")
    ax.set_title(f"haptic period error ({rate:g} Hz loop)", fontsize=10)
    ax.grid(alpha=0.3)

    # Loop statistics as text.
    ax = fig.add_subplot(grid[1, 1])
    ax.axis("off")
    ax.text(0.0, 1.0, stats_text(run, e), va="top", ha="left", family="monospace", fontsize=8,
            transform=ax.transAxes)
    fig.savefig(out, dpi=dpi)
    plt.close(fig)


def parse_size(s: str):
    try:
        w, h = (int(v) for v in s.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must be WxH in pixels, not {s!r}") from None
    if not (200 <= w <= 8000 and 200 <= h <= 8000):
        raise argparse.ArgumentTypeError(f"size {s} is outside 200..8000 pixels")
    return w, h


def log_plot_parser(prog: str, doc: str) -> argparse.ArgumentParser:
    """The arguments every plot of an LCM log takes: the log and the PNG to write."""
    ap = argparse.ArgumentParser(prog=prog, description=doc.splitlines()[0])
    ap.add_argument("log", help="LCM log written by hapticloth-server --lcm-log")
    ap.add_argument("-o", "--out", required=True, help="PNG to write")
    return ap


def main(argv=None) -> int:
    return run_cli("hapticloth-plot", _main, argv)


def _main(argv) -> int:
    ap = log_plot_parser("hapticloth-plot", __doc__)
    ap.add_argument("--size", type=parse_size, default=(1200, 800), help="WxH in pixels (default 1200x800)")
    ap.add_argument("--title", default=None, help="figure title (default: the scene name)")
    a = ap.parse_args(argv)
    check_writable(a.out, "--out", inputs=[a.log], suffixes=(".png",))  # before reading a long log
    run = read_log(a.log)
    try:
        plot(run, a.out, a.size, a.title)
    except OSError as e:
        raise UserError(f"--out {a.out}: cannot write ({e.strerror or e})") from None
    print(f"{a.out}: {len(run.time)} ticks, {run.fingers} fingers, {len(run.stats)} loop_stats_t")
    return 0


if __name__ == "__main__":
    sys.exit(main())
