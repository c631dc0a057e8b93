"""Text and JSON reports and plots of the fitted laws against the measured curves."""

from __future__ import annotations

import os

import numpy as np

from .fit_csv import CURVES, Measured
from .fit_curves import CurveFit


def report_json(measured: Measured, fits: dict[str, CurveFit], output: str) -> dict:
    curves = {}
    for n in CURVES:
        f = fits[n]
        curves[n] = {
            "segments": f.spline.segments,
            "knots": [float(k) for k in f.spline.knots],
            "B": [[float(b) for b in row] for row in f.spline.B],
            "points": f.points,
            "max_strain": f.max_strain,
            "max_stress": f.max_stress,
            "rms": f.rms,
            "rms_pct": f.pct(f.rms),
            "max": f.max,
            "max_pct": f.pct(f.max),
            "linear_k": f.linear_k,
            "linear_rms": f.linear_rms,
            "linear_rms_pct": f.pct(f.linear_rms),
            "linear_max": f.linear_max,
            "linear_max_pct": f.pct(f.linear_max),
            "monotone_constraint_active": f.constrained,
            "rms_pct_by_segments": {str(k): f.pct(v) for k, v in f.rms_by_segments.items()},
        }
    return {"file": measured.path, "output": output, "areal_density": measured.areal_density,
            "curves": curves}


def report_text(measured: Measured, fits: dict[str, CurveFit], output: str) -> str:
    name = measured.name
    out = [f"{measured.path}: {name}", f"areal density {measured.areal_density:g} kg/m^2; "
           "errors in N/m and in % of the curve's max |stress|", ""]
    out.append(f"{'':<29} {'max':>8}  {'spline law':^27}  {'linear law sigma = k eps':^36}"
               .rstrip())
    out.append(f"{'curve':<6}{'pts':>4}{'seg':>4}  {'inner knots':<13} {'|stress|':>8}  "
               f"{'RMS':>13} {'max':>13}  {'k':>8} {'RMS':>13} {'max':>13}")
    for n in CURVES:
        f = fits[n]
        knots = ",".join(f"{k:.3g}" for k in f.spline.knots[1:]) or "-"

        def err(v):
            return f"{v:.3g} {f.pct(v):.2f}%"

        out.append(
            f"{n:<6}{f.points:>4}{f.spline.segments:>4}  {knots:<13} {f.max_stress:>8.4g}  "
            f"{err(f.rms):>13} {err(f.max):>13}  {f.linear_k:>8.4g} "
            f"{err(f.linear_rms):>13} {err(f.linear_max):>13}")
    constrained = [n for n in CURVES if fits[n].constrained]
    if constrained:
        out.append("")
        out.append("tangent constraint active (the unconstrained fit would decrease): "
                   + ", ".join(constrained))
    out += ["", f"wrote {output}"]
    return "\n".join(out) + "\n"


def plot_fits(measured: Measured, fits: dict[str, CurveFit], path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.5))
    title = measured.fabric or os.path.basename(measured.path)
    fig.suptitle(title)
    for ax, n in zip(axes, CURVES):
        f = fits[n]
        c = measured.curves[n]
        lo = -f.max_strain if n == "shear" else 0.0
        e = np.linspace(lo, f.max_strain, 600)
        ax.plot(c.strain, c.stress, "o", ms=3, color="0.3", label="measured")
        ax.plot(e, f.spline.stress(e), "-", color="C0",
                label=f"spline, {f.spline.segments} seg., RMS {f.pct(f.rms):.2f}%")
        ax.plot(e, f.linear_k * e, "--", color="C3",
                label=f"linear, RMS {f.pct(f.linear_rms):.2f}%")
        knots = f.spline.knots[1:]
        for k in knots:
            for kk in ([k, -k] if n == "shear" else [k]):
                ax.axvline(kk, color="C2", lw=0.8, ls=":")
        if knots.size:
            ks = np.concatenate([knots, -knots]) if n == "shear" else knots
            ax.plot(ks, f.spline.stress(ks), "D", color="C2", ms=6, label="knots")
        ax.set_title(n)
        ax.set_xlabel("shear angle (rad)" if n == "shear" else "strain")
        ax.set_ylabel("stress (N/m)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
