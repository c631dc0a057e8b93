"""Plot of a simulated Kawabata test (the CSV written by ``hapticloth-kes --csv``).

Overlays the measured points (optional), the material law and the simulated test. Called by
``hapticloth-kes --plot``; usable on its own:

    python -m hapticloth.kes_plot SIM.csv OUT.png --test weft [--measured MEASURED.csv]
"""

from __future__ import annotations

import argparse
import csv
import sys


def _read_sim(path):
    strain, stress, material = [], [], []
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            strain.append(float(row["strain"]))
            stress.append(float(row["stress_n_per_m"]))
            material.append(float(row["material_n_per_m"]))
    return strain, stress, material


def _read_measured(path, test):
    strain, stress = [], []
    with open(path, newline="") as f:
        rows = (line for line in f if line.strip() and not line.lstrip().startswith("#"))
        for row in csv.DictReader(rows):
            if row["test"].strip() == test:
                strain.append(float(row["strain"]))
                stress.append(float(row["stress"]))
    return strain, stress


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="hapticloth-kes-plot", description=__doc__.splitlines()[0])
    ap.add_argument("sim_csv")
    ap.add_argument("out_png")
    ap.add_argument("--test", required=True, choices=["weft", "warp", "shear"])
    ap.add_argument("--measured")
    ap.add_argument("--title", default="")
    a = ap.parse_args(argv)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    strain, stress, material = _read_sim(a.sim_csv)
    fig, ax = plt.subplots(figsize=(6.4, 4.4), dpi=120)
    if a.measured:
        me, ms = _read_measured(a.measured, a.test)
        ax.plot(me, ms, "o", ms=3, color="0.55", label="measured")
    ax.plot(strain, material, "-", color="C0", lw=2, label="material law")
    ax.plot(strain, stress, "x", color="C3", ms=5, label="simulated KES test")
    xlabel = "shear strain eps_uv (rad)" if a.test == "shear" else f"{a.test} strain"
    ax.set_xlabel(xlabel)
    ax.set_ylabel("force per unit width (N/m)")
    ax.set_title(f"{a.title} - {a.test}" if a.title else a.test)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(a.out_png)
    return 0


if __name__ == "__main__":
    sys.exit(main())
