#!/usr/bin/env python3
"""Plots the JSON of `hapticloth-bench accuracy` or `hapticloth-bench stability` to a PNG.

Usage: plot_bench.py RESULT.json OUT.png
"""
import json
import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def finite(v):
    return isinstance(v, (int, float)) and math.isfinite(v) and v > 0


def plot_accuracy(j, out):
    scenes = list(j["scenes"].items())
    fig, axes = plt.subplots(1, len(scenes), figsize=(6 * len(scenes), 5))
    markers = {"dt-alpha": "o", "solver": "s", "resolution": "^", "local-patch": "D", "local-response": "P",
               "direct-long-step": "x"}
    for ax, (name, sc) in zip(axes, scenes):
        key = "force_err_rel" if name != "release" else "pos_err_mm"
        runs = [r for r in sc["runs"] if finite(r.get(key))]
        for sweep, mk in markers.items():
            rs = [r for r in runs if r["sweep"] == sweep]
            if not rs:
                continue
            c = [r["alpha"] for r in rs] if sweep == "dt-alpha" else None
            style = dict(c=c, cmap="viridis", vmin=0.5, vmax=1.0) if c else dict(color="0.4")
            if mk != "x":
                style.update(edgecolors="k", linewidths=0.3)
            ax.scatter([r["cpu_s_per_sim_s"] for r in rs], [r[key] for r in rs], marker=mk,
                       label=sweep, s=30, **style)
        front = sorted((r for r in runs if r.get("pareto")), key=lambda r: r["cpu_s_per_sim_s"])
        ax.plot([r["cpu_s_per_sim_s"] for r in front], [r[key] for r in front], "r-", lw=1,
                label="Pareto front")
        for r in front:
            ax.annotate(r["label"], (r["cpu_s_per_sim_s"], r[key]), fontsize=6,
                        xytext=(3, 3), textcoords="offset points")
        d = j["defaults"]
        for r in runs:
            if r["label"] == d["label"] and r["sweep"] in ("dt-alpha", "solver"):
                ax.scatter([r["cpu_s_per_sim_s"]], [r[key]], s=160, facecolors="none",
                           edgecolors="r", linewidths=1.5, label="default")
                break
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("CPU s per simulated s")
        ax.set_ylabel("relative RMS force error" if key == "force_err_rel" else "RMS position error (mm)")
        ax.set_title(name + " (colour: alpha)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=110)


def plot_stability(j, out):
    cells = j["cells"]
    alphas = sorted({c["alpha"] for c in cells})
    speeds = sorted({c["finger_speed"] for c in cells})
    dts = sorted({c["dt_ms"] for c in cells})
    scales = sorted({c["stiffness_scale"] for c in cells})
    fig, axes = plt.subplots(len(alphas), len(speeds), figsize=(4 * len(speeds), 3.2 * len(alphas)),
                             squeeze=False)
    for i, a in enumerate(alphas):
        for k, v in enumerate(speeds):
            ax = axes[i][k]
            for c in cells:
                if c["alpha"] != a or c["finger_speed"] != v:
                    continue
                x, y = dts.index(c["dt_ms"]), scales.index(c["stiffness_scale"])
                fail = c.get("failure", "")
                if c["pass"]:
                    col = "gold" if c["retries"] > 0 else "tab:green"
                elif fail.startswith("penetration"):
                    col = "tab:orange"  # stable; the global cloth inside the proxy > tolerance
                else:
                    col = "tab:red"  # non-finite, energy over the bound, or abandoned steps
                ax.add_patch(plt.Rectangle((x - 0.45, y - 0.45), 0.9, 0.9, color=col))
                ax.text(x, y, "%.1f" % c["max_penetration_mm"], ha="center", va="center", fontsize=7)
            ax.set_xlim(-0.5, len(dts) - 0.5)
            ax.set_ylim(-0.5, len(scales) - 0.5)
            ax.set_xticks(range(len(dts)), ["%g" % d for d in dts])
            ax.set_yticks(range(len(scales)), ["x%g" % s for s in scales])
            ax.set_xlabel("dt (ms)")
            ax.set_ylabel("stiffness")
            ax.set_title("alpha %g, finger %g m/s" % (a, v), fontsize=9)
    fig.suptitle("stability map (dt 1 ms: direct coupling; 5-40 ms: local patch). green pass, gold "
                 "pass after retried steps, orange: penetration over tolerance only,\nred: "
                 "abandoned steps, energy over bound or non-finite (numbers: max penetration, mm)",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(out, dpi=110)


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    with open(sys.argv[1]) as f:
        j = json.load(f)
    {"accuracy": plot_accuracy, "stability": plot_stability}[j["benchmark"]](j, sys.argv[2])


if __name__ == "__main__":
    main()
