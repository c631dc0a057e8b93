"""Fit the spline material laws of HAPTEX appendix A.2 to measured fabric curves.

    hapticloth-fit MEASURED.csv -o MATERIAL.toml [--segments K] [--plot OUT.png] [--json]

The command line: reads the curves (fit_csv), fits them (fit_curves), writes the material file
(fit_toml) and prints a text or JSON report, optionally with a plot (fit_report).
"""

from __future__ import annotations

import argparse
import json
import re
import sys

import numpy as np

from .errors import EXIT_FAILED, UserError, check_writable, run_cli
from .fit_csv import read_measured
from .fit_curves import MAX_SEGMENTS, fit_measured
from .fit_report import plot_fits, report_json, report_text
from .fit_toml import kept_surface, material_toml

# Imported from hapticloth.fit by the tests.
from .fit_curves import _basis, _coefficients_to_B, fit_curve  # noqa: F401
from .fit_spline import Spline, _min_tangent  # noqa: F401
from .lsq import lsi  # noqa: F401


def _segments(text: str) -> int:
    try:
        k = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if not 1 <= k <= MAX_SEGMENTS:
        raise argparse.ArgumentTypeError(f"must be between 1 and {MAX_SEGMENTS}, got {k}")
    return k


def main(argv: list[str] | None = None) -> int:
    return run_cli("hapticloth-fit", _main, argv)


def _main(argv: list[str] | None) -> int:
    parser = argparse.ArgumentParser(
        prog="hapticloth-fit",
        description="Fit spline material laws (HAPTEX appendix A.2) to measured weft, warp and "
                    "shear curves and write a material TOML file for hapticloth-server.")
    parser.add_argument("csv", metavar="MEASURED.csv",
                        help="measured curves: '# areal_density_kg_per_m2: X' header line, "
                             "then rows test,strain,stress with test weft|warp|shear")
    parser.add_argument("-o", "--output", metavar="MATERIAL.toml", required=True,
                        help="material file to write")
    parser.add_argument("--segments", type=_segments, default=MAX_SEGMENTS, metavar="K",
                        help="maximum number of spline segments per curve, 1..3 (default 3)")
    parser.add_argument("--plot", metavar="OUT.png", help="plot data, fits and linear laws")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    args = parser.parse_args(argv)

    try:
        measured = read_measured(args.csv)
    except OSError as e:
        raise UserError(f"cannot read {args.csv}: {e.strerror or e}") from None
    # Both outputs are checked before the fit, so that neither is written when one cannot be.
    check_writable(args.output, "--output", inputs=[args.csv])
    if args.plot:
        check_writable(args.plot, "--plot", inputs=[args.csv, args.output], suffixes=(".png",))

    fits = fit_measured(measured, args.segments)
    for n, f in fits.items():
        if not np.all(np.isfinite(f.spline.B)) or not np.all(np.isfinite(f.spline.knots)):
            raise UserError(f"{args.csv}: the fitted {n} law is not finite (the data's strains "
                            "or stresses span too many orders of magnitude)")
        tmin = f.spline.server_check(f.max_strain)
        if tmin < 0.0:  # cannot happen with the constrained fit; never write a rejected law
            print(f"hapticloth-fit: internal error: {n} tangent {tmin:g} < 0", file=sys.stderr)
            return EXIT_FAILED

    argv_list = sys.argv[1:] if argv is None else argv
    command = "hapticloth-fit " + " ".join(_shell_quote(a) for a in argv_list)
    try:
        surface = kept_surface(args.output)
        with open(args.output, "w", encoding="utf-8") as f:
            f.write(material_toml(measured, fits, command) + surface)
        if args.plot:
            plot_fits(measured, fits, args.plot)
    except OSError as e:
        raise UserError(f"cannot write {e.filename}: {e.strerror}") from None

    if args.json:
        print(json.dumps(report_json(measured, fits, args.output), indent=2))
    else:
        sys.stdout.write(report_text(measured, fits, args.output))
    return 0


def _shell_quote(s: str) -> str:
    if re.fullmatch(r"[A-Za-z0-9_./=+:-]+", s):
        return s
    return "'" + s.replace("'", "'\"'\"'") + "'"


if __name__ == "__main__":
    sys.exit(main())
