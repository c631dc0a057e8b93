"""Plot of a simulated Kawabata test (the CSV written by ``hapticloth-kes --csv``).

Overlays the measured points (optional), the material law and the simulated test. Called by
``hapticloth-kes --plot``; usable on its own:

    python -m hapticloth.kes_plot SIM.csv OUT.png --test weft [--measured MEASURED.csv]
"""

from __future__ import annotations

import argparse
import csv
import sys

from .errors import UserError, check_input_file, check_writable, not_text_error, run_cli


def _read_sim(path):
    strain, stress, material = [], [], []
    for lineno, row in _csv_rows(path):
        strain.append(_number(path, lineno, row, "strain"))
        stress.append(_number(path, lineno, row, "stress_n_per_m"))
        material.append(_number(path, lineno, row, "material_n_per_m"))
    return strain, stress, material


def _read_measured(path, test):
    strain, stress = [], []
    for lineno, row in _csv_rows(path):
        if (row.get("test") or "").strip() == test:
            strain.append(_number(path, lineno, row, "strain"))
            stress.append(_number(path, lineno, row, "stress"))
    return strain, stress


def _csv_rows(path):
    """(line number, row as a dict) of a CSV with a header row; blank and '#' lines skipped.
    UserError naming the file for a missing or binary file."""
    check_input_file(path)
    try:
        with open(path, encoding="utf-8") as f:
            numbered = [(n, line) for n, line in enumerate(f.read().splitlines(), 1)
                        if line.strip() and not line.lstrip().startswith("#")]
    except UnicodeDecodeError as e:
        raise not_text_error(path, e) from None
    reader = csv.DictReader(line for _, line in numbered)
    try:
        for row in reader:
            yield numbered[reader.line_num - 1][0], row
    except csv.Error as e:
        raise UserError(f"{path}: {e}") from None


def _number(path, lineno, row, column):
    text = row.get(column)
    if text is None:
        raise UserError(f"{path}:{lineno}: no column '{column}'")
    try:
        return float(text)
    except ValueError:
        raise UserError(f"{path}:{lineno}: {column} {text!r} is not a number") from None


def main(argv=None) -> int:
    return run_cli("hapticloth-kes-plot", _main, argv)


def _main(argv) -> int:
    ap = argparse.ArgumentParser(prog="hapticloth-kes-plot", description=__doc__.splitlines()[0])
    ap.add_argument("sim_csv")
    ap.add_argument("out_png")
    ap.add_argument("--test", required=True, choices=["weft", "warp", "shear"])
    ap.add_argument("--measured")
    ap.add_argument("--title", default="")
    a = ap.parse_args(argv)
    # hapticloth-kes --plot OUT.png runs this after its test: name its option in the message.
    check_writable(a.out_png, "--plot")
    strain, stress, material = _read_sim(a.sim_csv)
    measured = _read_measured(a.measured, a.test) if a.measured else None

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.4), dpi=120)
    if measured:
        ax.plot(*measured, "o", ms=3, color="0.55", label="measured")
    ax.plot(strain, material, "-", color="C0", lw=2, label="material law")
    ax.plot(strain, stress, "x", color="C3", ms=5, label="simulated KES test")
    xlabel = "shear strain eps_uv (rad)" if a.test == "shear" else f"{a.test} strain"
    ax.set_xlabel(xlabel)
    ax.set_ylabel("force per unit width (N/m)")
    ax.set_title(f"{a.title} - {a.test}" if a.title else a.test)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    try:
        fig.savefig(a.out_png)
    except OSError as e:
        raise UserError(f"--plot {a.out_png}: cannot write ({e.strerror or e})") from None
    return 0


if __name__ == "__main__":
    sys.exit(main())
