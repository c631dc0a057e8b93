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


def _read_lines(path: str) -> list[str]:
    check_input_file(path)
    try:
        with open(path, encoding="utf-8") as f:
            return f.read().splitlines()
    except UnicodeDecodeError as e:
        raise InputError(path, 1, f"not a UTF-8 text file ({e.reason})") from None


class _Header:
    """The '# key: value' comment lines (a line indented past '# ' continues the last key)."""

    def __init__(self):
        self.values: dict[str, str] = {}
        self.lines: dict[str, int] = {}
        self._last: str | None = None

    def read_comment(self, lineno: int, raw: str) -> None:
        content = raw.lstrip()[1:]
        if content.startswith(" "):
            content = content[1:]
        if content[:1].isspace() and self._last is not None:
            self.values[self._last] += " " + content.strip()
            return
        m = re.match(r"([A-Za-z_][A-Za-z0-9_]*)\s*:\s*(.*)$", content)
        self._last = m.group(1).lower() if m else None
        if m:
            self.values[self._last] = m.group(2).strip()
            self.lines[self._last] = lineno

    def end_comments(self) -> None:
        self._last = None


def _column_row(path: str, lineno: int, line: str, fields: list[str]) -> list[str]:
    """The columns the header row names, in its order."""
    expected = ",".join(COLUMNS)
    lowered = [x.lower() for x in fields]
    if not any(c in lowered for c in COLUMNS):
        raise InputError(path, lineno, f"missing header row: expected '{expected}', got {line!r}")
    for c in COLUMNS:
        if c not in lowered:
            raise InputError(path, lineno, f"header row lacks column '{c}' (expected '{expected}')")
    for c in lowered:
        if c not in COLUMNS:
            raise InputError(path, lineno, f"header row has unknown column {c!r} (expected '{expected}')")
    if len(set(lowered)) != len(lowered):
        raise InputError(path, lineno, "header row repeats a column")
    return lowered


def _check_point(path: str, lineno: int, row: dict[str, str], test: str, strain: float, stress: float,
                 previous: list[tuple[int, float, float]]) -> None:
    """A data point within range, after the test's previous one, and not negative in tension."""
    if abs(stress) > MAX_ABS_STRESS:
        raise InputError(
            path, lineno, f"stress {row['stress']} is outside -{MAX_ABS_STRESS:g}..{MAX_ABS_STRESS:g} N/m")
    if abs(strain) > MAX_ABS_STRAIN[test]:
        unit = "rad: a shear angle, not degrees" if test == "shear" else "a fraction, not percent"
        raise InputError(
            path, lineno,
            f"strain {row['strain']} of test '{test}' is beyond {MAX_ABS_STRAIN[test]:.4g} "
            f"in size (strain is {unit})")
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


def _data_row(path: str, lineno: int, columns: list[str], fields: list[str],
              rows: dict[str, list[tuple[int, float, float]]]) -> None:
    """Appends one data row's (line, strain, stress) to its test's rows."""
    if len(fields) != len(columns):
        raise InputError(
            path, lineno,
            f"expected {len(columns)} comma-separated values ({','.join(columns)}), got {len(fields)}")
    row = dict(zip(columns, fields))
    test = row["test"].lower()
    if test not in CURVES:
        raise InputError(path, lineno, f"unknown test {row['test']!r} (expected weft, warp or shear)")
    strain = _parse_number(path, lineno, "strain", row["strain"])
    stress = _parse_number(path, lineno, "stress", row["stress"])
    _check_point(path, lineno, row, test, strain, stress, rows[test])
    rows[test].append((lineno, strain, stress))


def _areal_density(path: str, header: _Header) -> float:
    if DENSITY_KEY not in header.values:
        raise InputError(path, 1, f"missing header line '# {DENSITY_KEY}: VALUE'")
    dline = header.lines[DENSITY_KEY]
    text = header.values[DENSITY_KEY].split()[0] if header.values[DENSITY_KEY] else "''"
    density = _parse_number(path, dline, DENSITY_KEY, text)
    if not density > 0.0:
        raise InputError(path, dline, f"{DENSITY_KEY} must be > 0, got {text}")
    return density


def _curve(path: str, test: str, r: list[tuple[int, float, float]], header_row_line: int) -> Curve:
    """One test's rows as a curve, with enough distinct points for the smallest model."""
    if not r:
        raise InputError(path, header_row_line, f"missing test '{test}': the file needs weft, warp and shear rows")
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
    return Curve(strain, stress, r[0][0])


def read_measured(path: str) -> Measured:
    """Read a measured-curves CSV; raises InputError (FILE:LINE: message) on bad input."""
    lines = _read_lines(path)
    header = _Header()
    columns: list[str] | None = None
    header_row_line = 0
    rows: dict[str, list[tuple[int, float, float]]] = {c: [] for c in CURVES}
    for lineno, raw in enumerate(lines, start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            header.read_comment(lineno, raw)
            continue
        header.end_comments()
        fields = [x.strip() for x in line.split(",")]
        if columns is None:
            columns, header_row_line = _column_row(path, lineno, line, fields), lineno
        else:
            _data_row(path, lineno, columns, fields, rows)
    if columns is None:
        raise InputError(path, max(len(lines), 1), f"missing header row '{','.join(COLUMNS)}' (no data rows)")
    density = _areal_density(path, header)
    curves = {test: _curve(path, test, rows[test], header_row_line) for test in CURVES}
    return Measured(path, density, header.values.get("fabric"), header.values.get("source"), curves)
