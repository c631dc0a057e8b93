"""Reading of measured fabric curves (weft, warp, shear) from a CSV file.

Errors in the file raise InputError, reported as FILE:LINE: message.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass

import numpy as np

from .errors import UserError, check_input_file
from .fit_spline import fit_parameter_count

CURVES = ("weft", "warp", "shear")
COLUMNS = ("test", "strain", "stress")
DENSITY_KEY = "areal_density_kg_per_m2"
# Largest |stress| (N/m) and |strain| of a data point: far beyond any fabric (the KES-F tester's
# full scale is 490 N/m; a shear angle beyond 90 degrees means nothing), near enough that the
# fit's scaled arithmetic cannot overflow. Also catches strains in percent or degrees.
MAX_ABS_STRESS = 1e6
MAX_ABS_STRAIN = {"weft": 10.0, "warp": 10.0, "shear": math.pi / 2}


class InputError(UserError):
    """A problem with the input file, reported as FILE:LINE: message."""

    def __init__(self, path: str, line: int, message: str):
        super().__init__(f"{path}:{line}: {message}")
        self.path = path
        self.line = line
        self.message = message


@dataclass
class Curve:
    """One measured curve: strictly increasing strains and their stresses."""

    strain: np.ndarray
    stress: np.ndarray
    first_line: int


@dataclass
class Measured:
    path: str
    areal_density: float
    fabric: str | None
    source: str | None
    curves: dict[str, Curve]

    @property
    def name(self) -> str:
        """The 'fabric' header, else the file name without its extension."""
        return self.fabric or os.path.splitext(os.path.basename(self.path))[0]


def _parse_number(path: str, lineno: int, what: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise InputError(path, lineno, f"{what} {text!r} is not a number") from None
    if not math.isfinite(value):
        raise InputError(path, lineno, f"{what} {text!r} is not a finite number")
    return value


def read_measured(path: str) -> Measured:
    """Read a measured-curves CSV; raises InputError (FILE:LINE: message) on bad input."""
    check_input_file(path)
    try:
        with open(path, encoding="utf-8") as f:
            lines = f.read().splitlines()
    except UnicodeDecodeError as e:
        raise InputError(path, 1, f"not a UTF-8 text file ({e.reason})") from None

    header: dict[str, str] = {}
    header_lines: dict[str, int] = {}
    last_key: str | None = None
    columns: list[str] | None = None
    header_row_line = 0
    rows: dict[str, list[tuple[int, float, float]]] = {c: [] for c in CURVES}

    for lineno, raw in enumerate(lines, start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            content = raw.lstrip()[1:]
            if content.startswith(" "):
                content = content[1:]
            if content[:1].isspace() and last_key is not None:
                header[last_key] += " " + content.strip()
                continue
            m = re.match(r"([A-Za-z_][A-Za-z0-9_]*)\s*:\s*(.*)$", content)
            if m:
                last_key = m.group(1).lower()
                header[last_key] = m.group(2).strip()
                header_lines[last_key] = lineno
            else:
                last_key = None
            continue
        last_key = None
        fields = [x.strip() for x in line.split(",")]
        if columns is None:
            lowered = [x.lower() for x in fields]
            if not any(c in lowered for c in COLUMNS):
                raise InputError(
                    path, lineno,
                    f"missing header row: expected '{','.join(COLUMNS)}', got {line!r}")
            for c in COLUMNS:
                if c not in lowered:
                    raise InputError(
                        path, lineno,
                        f"header row lacks column '{c}' (expected '{','.join(COLUMNS)}')")
            for c in lowered:
                if c not in COLUMNS:
                    raise InputError(
                        path, lineno,
                        f"header row has unknown column {c!r} (expected '{','.join(COLUMNS)}')")
            if len(set(lowered)) != len(lowered):
                raise InputError(path, lineno, "header row repeats a column")
            columns = lowered
            header_row_line = lineno
            continue
        if len(fields) != len(columns):
            raise InputError(
                path, lineno,
                f"expected {len(columns)} comma-separated values ({','.join(columns)}), "
                f"got {len(fields)}")
        row = dict(zip(columns, fields))
        test = row["test"].lower()
        if test not in CURVES:
            raise InputError(
                path, lineno, f"unknown test {row['test']!r} (expected weft, warp or shear)")
        strain = _parse_number(path, lineno, "strain", row["strain"])
        stress = _parse_number(path, lineno, "stress", row["stress"])
        if abs(stress) > MAX_ABS_STRESS:
            raise InputError(
                path, lineno,
                f"stress {row['stress']} is outside -{MAX_ABS_STRESS:g}..{MAX_ABS_STRESS:g} N/m")
        if abs(strain) > MAX_ABS_STRAIN[test]:
            unit = "rad: a shear angle, not degrees" if test == "shear" else "a fraction, not percent"
            raise InputError(
                path, lineno,
                f"strain {row['strain']} of test '{test}' is beyond {MAX_ABS_STRAIN[test]:.4g} "
                f"in size (strain is {unit})")
        previous = rows[test]
        if previous and not strain > previous[-1][1]:
            raise InputError(
                path, lineno,
                f"strain {row['strain']} of test '{test}' is not greater than the previous "
                f"one ({previous[-1][1]:g} on line {previous[-1][0]}): strains must be strictly "
                "increasing within a test")
        if test != "shear" and strain < 0.0:
            raise InputError(
                path, lineno,
                f"negative strain {row['strain']} in tensile test '{test}' (the loading branch "
                "starts at strain 0)")
        previous.append((lineno, strain, stress))

    if columns is None:
        raise InputError(path, max(len(lines), 1),
                         f"missing header row '{','.join(COLUMNS)}' (no data rows)")
    if DENSITY_KEY not in header:
        raise InputError(path, 1, f"missing header line '# {DENSITY_KEY}: VALUE'")
    dline = header_lines[DENSITY_KEY]
    density_text = header[DENSITY_KEY].split()[0] if header[DENSITY_KEY] else "''"
    density = _parse_number(path, dline, DENSITY_KEY, density_text)
    if not density > 0.0:
        raise InputError(path, dline, f"{DENSITY_KEY} must be > 0, got {density_text}")

    curves: dict[str, Curve] = {}
    for test in CURVES:
        r = rows[test]
        if not r:
            raise InputError(
                path, header_row_line,
                f"missing test '{test}': the file needs weft, warp and shear rows")
        strain = np.array([x[1] for x in r])
        stress = np.array([x[2] for x in r])
        distinct = np.unique(np.abs(strain[strain != 0.0])).size
        need = fit_parameter_count(1)
        if distinct < need:
            raise InputError(
                path, r[0][0],
                f"too few points in test '{test}': {distinct} at distinct nonzero "
                f"{'|strain|' if test == 'shear' else 'strain'}, the smallest model "
                f"(1 segment) has {need} parameters")
        curves[test] = Curve(strain, stress, r[0][0])

    source = header.get("source")
    return Measured(path, density, header.get("fabric"), source, curves)
