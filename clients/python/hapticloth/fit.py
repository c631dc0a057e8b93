"""Fit the spline material laws of HAPTEX appendix A.2 to measured fabric curves.

    hapticloth-fit MEASURED.csv -o MATERIAL.toml [--segments K] [--plot OUT.png] [--json]

The law of each curve (weft, warp, shear) is the C1 truncated power spline

    sigma(eps) = sum_{i<K} sum_{j<=3} B_ij (eps - E_i)_+^j,   E_0 = 0 < E_1 < E_2,
    B_i0 = B_i1 = 0 for i >= 1,  B_00 = 0,

with K = 1..3 segments. The shear law is odd, sigma(-e) = -sigma(e), and is fitted to
sigma(|e|) * sign(e) over both branches of the data; weft and warp are fitted on their loading
branch and pass through the origin.

Fitting (variable projection, as in the appendix): for given knots the coefficients B are the
solution of a linear least-squares problem, so only the inner knots E_1, E_2 are nonlinear
unknowns. The objective is evaluated on a grid of knot positions and scipy.optimize.least_squares
is started from the best few grid points, through a smooth map from the unit box onto ordered
knots inside the data range that are separated by a minimum gap. The fit is done in scaled units (strain / max strain, stress / max |stress|).

Monotonicity: the server rejects a law whose tangent d sigma / d eps is negative anywhere on
[0, max_strain] (max_strain: the largest |strain| of the data). If the unconstrained coefficients
for given knots give a negative tangent (checked exactly: the tangent is a quadratic on each knot
interval), the coefficients are recomputed as an inequality-constrained least-squares problem,
solved with the LSI -> LDP -> NNLS reduction of Lawson and Hanson (Solving Least Squares
Problems, ch. 23). The constraints are cutting planes: tangent >= 0 where the previous solution's
tangent was smallest, added until the exact minimum is >= 0 (with a fallback to 801 evenly
spaced strains, a superset of the 401 the server checks).

Number of segments, per curve: starting from one segment, the best law with more segments (up
to K) replaces the current choice only if it lowers the RMS error by at least 10% and lowers the
Bayesian information criterion n ln(RSS / n) + p ln(n) (n points, p coefficients and knots), so
that knots are not spent on fitting measurement noise. The last knot keeps at least four data
points after it.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import re
import sys
from dataclasses import dataclass, field

import numpy as np

from .errors import EXIT_FAILED, UserError, check_writable, run_cli

CURVES = ("weft", "warp", "shear")
COLUMNS = ("test", "strain", "stress")
MAX_SEGMENTS = 3
DENSITY_KEY = "areal_density_kg_per_m2"

# More segments must lower the RMS error by at least this fraction to be chosen.
SEGMENT_GAIN = 0.10
# Minimum separation of the knots (E_1 from E_0 = 0 too), as a fraction of the largest strain
# and in data spacings (the median distance between successive distinct |strain| values).
MIN_GAP_FRACTION = 0.05
MIN_GAP_SPACINGS = 2.5
# Minimum distance of the last knot from the largest strain: the last segment's two coefficients
# must rest on enough points (4.5 spacings: at least four), or it bends to fit the noise of the
# last few points and extrapolates badly.
END_GAP_FRACTION = 0.1
END_GAP_SPACINGS = 4.5
# Tangent samples of the monotonicity constraint on [0, max_strain]; a multiple of the server's
# 400 intervals so that its sample strains are among them.
TANGENT_SAMPLES = 800
# Required tangent at the constrained strains, in scaled units (max |stress| / max strain).
TANGENT_MARGIN = 1e-9
# Cutting-plane rounds of the monotone fit before it falls back to all tangent samples.
MAX_CUTS = 40
# Largest |stress| (N/m) and |strain| of a data point: far beyond any fabric (the KES-F tester's
# full scale is 490 N/m; a shear angle beyond 90 degrees means nothing), near enough that the
# fit's scaled arithmetic cannot overflow. Also catches strains in percent or degrees.
MAX_ABS_STRESS = 1e6
MAX_ABS_STRAIN = {"weft": 10.0, "warp": 10.0, "shear": math.pi / 2}
# Knot search: the objective is evaluated on a grid of this many values per unit-box knot
# coordinate, and least_squares is started from the best LOCAL_STARTS grid points.
SEARCH_GRID = 12
LOCAL_STARTS = 4


class InputError(UserError):
    """A problem with the input file, reported as FILE:LINE: message."""

    def __init__(self, path: str, line: int, message: str):
        super().__init__(f"{path}:{line}: {message}")
        self.path = path
        self.line = line
        self.message = message


# --------------------------------------------------------------------------------------------
# Measured data
# --------------------------------------------------------------------------------------------


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


def _parse_number(path: str, lineno: int, what: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise InputError(path, lineno, f"{what} {text!r} is not a number") from None
    if not math.isfinite(value):
        raise InputError(path, lineno, f"{what} {text!r} is not a finite number")
    return value


def fit_parameter_count(segments: int) -> int:
    """Coefficients plus inner knots of a law with `segments` segments (B_00 fixed at 0)."""
    coefficients = 3 + 2 * (segments - 1)
    return coefficients + (segments - 1)


def read_measured(path: str) -> Measured:
    """Read a measured-curves CSV; raises InputError (FILE:LINE: message) on bad input."""
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


# --------------------------------------------------------------------------------------------
# The spline law
# --------------------------------------------------------------------------------------------


@dataclass
class Spline:
    """sigma(eps) = sum_i sum_j B[i][j] (eps - knots[i])_+^j, as evaluated by the server."""

    knots: np.ndarray
    B: np.ndarray
    odd: bool

    @property
    def segments(self) -> int:
        return len(self.knots)

    def _positive(self, e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        b0 = self.B[0]
        s = b0[0] + e * (b0[1] + e * (b0[2] + e * b0[3]))
        ds = b0[1] + e * (2.0 * b0[2] + 3.0 * e * b0[3])
        for i in range(1, self.segments):
            d = np.maximum(e - self.knots[i], 0.0)
            s = s + d * d * (self.B[i][2] + d * self.B[i][3])
            ds = ds + d * (2.0 * self.B[i][2] + 3.0 * d * self.B[i][3])
        return s, ds

    def evaluate(self, eps) -> tuple[np.ndarray, np.ndarray]:
        e = np.asarray(eps, dtype=float)
        s, ds = self._positive(np.abs(e))
        if self.odd:
            return np.where(e < 0.0, -s, s), ds
        k = self.B[0][1]
        return np.where(e < 0.0, self.B[0][0] + k * e, s), np.where(e < 0.0, k, ds)

    def stress(self, eps) -> np.ndarray:
        return self.evaluate(eps)[0]

    def tangent(self, eps) -> np.ndarray:
        return self.evaluate(eps)[1]

    def min_tangent(self, max_strain: float) -> tuple[float, float]:
        """Exact minimum of d sigma / d eps on [0, max_strain] and where it is reached."""
        return _min_tangent(self.knots, self.B, max_strain)

    def server_check(self, max_strain: float) -> float:
        """Smallest tangent at the 401 strains at which the server validates the law."""
        e = max_strain * np.arange(401) / 400.0
        return float(np.min(self.tangent(e)))


def _min_tangent(knots, B, max_strain: float) -> tuple[float, float]:
    # On each knot interval the tangent is the quadratic c0 + c1 x + c2 x^2: its minimum is at an
    # end of the interval or at the vertex.
    n = len(knots)
    c0, c1, c2 = float(B[0][1]), 2.0 * float(B[0][2]), 3.0 * float(B[0][3])
    best_t, best_x = math.inf, 0.0
    lo = 0.0
    for i in range(n):
        if i > 0:
            if knots[i] >= max_strain:
                break
            e, b2, b3 = float(knots[i]), float(B[i][2]), float(B[i][3])
            # 2 b2 (x - e) + 3 b3 (x - e)^2
            c0 += -2.0 * b2 * e + 3.0 * b3 * e * e
            c1 += 2.0 * b2 - 6.0 * b3 * e
            c2 += 3.0 * b3
            lo = e
        hi = float(knots[i + 1]) if i + 1 < n and knots[i + 1] < max_strain else max_strain
        xs = [lo, hi]
        if c2 > 0.0:
            v = -c1 / (2.0 * c2)
            if lo < v < hi:
                xs.append(v)
        for x in xs:
            t = c0 + x * (c1 + x * c2)
            if t < best_t:
                best_t, best_x = t, x
    return best_t, best_x


# --------------------------------------------------------------------------------------------
# Fitting
# --------------------------------------------------------------------------------------------


def _basis(t: np.ndarray, inner: np.ndarray) -> np.ndarray:
    cols = [t, t * t, t * t * t]
    for k in inner:
        d = np.maximum(t - k, 0.0)
        cols += [d * d, d * d * d]
    return np.column_stack(cols)


def _tangent_basis(t: np.ndarray, inner: np.ndarray) -> np.ndarray:
    cols = [np.ones_like(t), 2.0 * t, 3.0 * t * t]
    for k in inner:
        d = np.maximum(t - k, 0.0)
        cols += [2.0 * d, 3.0 * d * d]
    return np.column_stack(cols)


def _coefficients_to_B(c: np.ndarray, nseg: int) -> np.ndarray:
    B = np.zeros((nseg, 4))
    B[0, 1:4] = c[0:3]
    for i in range(1, nseg):
        B[i, 2:4] = c[3 + 2 * (i - 1): 5 + 2 * (i - 1)]
    return B


class LSI:
    """min ||E x - f|| subject to G x >= h, E of full column rank (Lawson and Hanson, ch. 23).

    With E = Q R, z = R x - Q^T f turns it into the least-distance problem
    min ||z|| s.t. (G R^-1) z >= h - G R^-1 Q^T f, which is solved by one NNLS problem. The
    factorization of E is done once for any number of constraint sets.
    """

    def __init__(self, E: np.ndarray, f: np.ndarray):
        Q, R = np.linalg.qr(E)
        self.f1 = Q.T @ f
        self.Rinv = np.linalg.solve(R, np.eye(R.shape[0]))

    def solve(self, G: np.ndarray, h: np.ndarray) -> np.ndarray:
        from scipy.optimize import nnls

        Gt = G @ self.Rinv
        ht = h - Gt @ self.f1
        n = Gt.shape[1]
        M = np.vstack([Gt.T, ht[None, :]])
        rhs = np.zeros(n + 1)
        rhs[n] = 1.0
        u, _ = nnls(M, rhs, maxiter=50 * M.shape[1])
        r = M @ u - rhs
        if not abs(r[n]) > 1e-12:
            raise ValueError("inequality constraints are infeasible")
        z = -r[:n] / r[n]
        return self.Rinv @ (z + self.f1)


def lsi(E: np.ndarray, f: np.ndarray, G: np.ndarray, h: np.ndarray) -> np.ndarray:
    """min ||E x - f|| subject to G x >= h (see LSI)."""
    return LSI(E, f).solve(G, h)


@dataclass
class _Inner:
    coefficients: np.ndarray
    residual: np.ndarray
    constrained: bool


class _ScaledProblem:
    """Scaled data t = |strain| / max, v = signed stress / max |stress| of one curve."""

    def __init__(self, x: np.ndarray, y: np.ndarray):
        self.xs = float(np.max(x))
        self.ys = float(np.max(np.abs(y))) or 1.0
        self.t = x / self.xs
        self.v = y / self.ys
        self.tangent_t = np.arange(TANGENT_SAMPLES + 1) / TANGENT_SAMPLES
        u = np.unique(self.t)
        spacing = float(np.median(np.diff(u))) if u.size > 1 else 1.0
        self.gap = max(MIN_GAP_FRACTION, MIN_GAP_SPACINGS * spacing)
        self.end_gap = max(END_GAP_FRACTION, END_GAP_SPACINGS * spacing)
        self.distinct = int(np.unique(self.t[self.t > 0.0]).size)

    def solve(self, inner: np.ndarray) -> _Inner:
        A = _basis(self.t, inner)
        c, *_ = np.linalg.lstsq(A, self.v, rcond=None)
        nseg = len(inner) + 1
        knots = np.concatenate([[0.0], inner])
        tmin, x = _min_tangent(knots, _coefficients_to_B(c, nseg), 1.0)
        constrained = False
        if tmin < 0.0:
            c = self._monotone(A, inner, x)
            constrained = True
        return _Inner(c, A @ c - self.v, constrained)

    def _monotone(self, A: np.ndarray, inner: np.ndarray, x: float) -> np.ndarray:
        """Least-squares coefficients with a tangent >= 0 on [0, 1].

        Cutting planes: require tangent >= TANGENT_MARGIN where the previous solution's tangent
        was smallest, until the exact minimum is >= 0. Should that not settle, the constraint is
        imposed at all TANGENT_SAMPLES + 1 sample strains at once.
        """
        nseg = len(inner) + 1
        knots = np.concatenate([[0.0], inner])
        problem = LSI(A, self.v)
        points = [x]
        for _ in range(MAX_CUTS):
            G = _tangent_basis(np.array(points), inner)
            c = problem.solve(G, np.full(len(points), TANGENT_MARGIN))
            tmin, x = _min_tangent(knots, _coefficients_to_B(c, nseg), 1.0)
            if tmin >= 0.0:
                return c
            points.append(x)
        G = _tangent_basis(self.tangent_t, inner)
        return problem.solve(G, np.full(G.shape[0], TANGENT_MARGIN))

    def knots_from_box(self, u: np.ndarray) -> np.ndarray:
        """Smooth map of the unit box onto ordered knots in [gap, 1 - end_gap], gap apart."""
        m = len(u)
        g = self.gap
        knots = np.empty(m)
        lower = g
        for i in range(m):
            upper = 1.0 - self.end_gap - (m - 1 - i) * g
            knots[i] = lower + u[i] * (upper - lower)
            lower = knots[i] + g
        return knots

    def feasible(self, nseg: int) -> bool:
        m = nseg - 1
        return (m * self.gap + self.end_gap <= 1.0 + 1e-12
                and self.distinct >= fit_parameter_count(nseg))


@dataclass
class CurveFit:
    name: str
    spline: Spline
    max_strain: float
    max_stress: float
    points: int
    rms: float
    max: float
    linear_k: float
    linear_rms: float
    linear_max: float
    constrained: bool
    rms_by_segments: dict[int, float] = field(default_factory=dict)

    def pct(self, value: float) -> float:
        return 100.0 * value / self.max_stress if self.max_stress > 0 else 0.0


def _fit_scaled(p: _ScaledProblem, nseg: int) -> tuple[np.ndarray, _Inner]:
    """Best knots (scaled) and inner solution for a law with nseg segments."""
    from scipy.optimize import least_squares

    m = nseg - 1
    if m == 0:
        return np.empty(0), p.solve(np.empty(0))

    def residual(u):
        return p.solve(p.knots_from_box(u)).residual

    def cost(u):
        r = residual(u)
        return float(np.dot(r, r))

    grid = (np.arange(SEARCH_GRID) + 0.5) / SEARCH_GRID
    starts = [np.array(u) for u in itertools.product(grid, repeat=m)]
    costs = np.array([cost(u) for u in starts])
    best_u, best_cost = None, math.inf
    for i in np.argsort(costs, kind="stable")[:LOCAL_STARTS]:
        u0 = starts[i]
        r = least_squares(residual, u0, bounds=(0.0, 1.0), method="trf",
                          xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=200 * m)
        value = float(np.dot(r.fun, r.fun))
        if value < best_cost - 1e-15:
            best_u, best_cost = r.x, value
    inner = p.knots_from_box(best_u)
    return inner, p.solve(inner)


def fit_curve(name: str, strain: np.ndarray, stress: np.ndarray,
              max_segments: int = MAX_SEGMENTS) -> CurveFit:
    """Fit one measured curve (shear: odd law) with at most max_segments segments."""
    odd = name == "shear"
    strain = np.asarray(strain, dtype=float)
    stress = np.asarray(stress, dtype=float)
    x = np.abs(strain)
    y = np.where(strain < 0.0, -stress, stress)
    p = _ScaledProblem(x, y)

    candidates: dict[int, tuple[Spline, float, bool]] = {}
    for nseg in range(1, max_segments + 1):
        if not p.feasible(nseg):
            break
        inner, sol = _fit_scaled(p, nseg)
        c = sol.coefficients
        B = _coefficients_to_B(c, nseg)
        for j in range(4):
            B[:, j] *= p.ys / p.xs ** j
        spline = Spline(np.concatenate([[0.0], inner * p.xs]), B, odd)
        res = spline.stress(strain) - stress
        candidates[nseg] = (spline, float(np.sqrt(np.mean(res * res))), sol.constrained)

    # More segments only if they lower the RMS error by SEGMENT_GAIN and lower the Bayesian
    # information criterion n ln(RSS / n) + (parameters) ln(n), so that extra knots are not
    # spent on fitting measurement noise.
    n = strain.size
    floor = (1e-12 * p.ys) ** 2

    def bic(nseg: int) -> float:
        rss = max(n * candidates[nseg][1] ** 2, n * floor)
        return n * math.log(rss / n) + fit_parameter_count(nseg) * math.log(n)

    chosen = 1
    for nseg in sorted(candidates)[1:]:
        best_rms = candidates[chosen][1]
        gain = best_rms - candidates[nseg][1]
        if gain > SEGMENT_GAIN * best_rms and gain > 1e-9 * p.ys and bic(nseg) < bic(chosen):
            chosen = nseg
    spline, rms, constrained = candidates[chosen]
    res = spline.stress(strain) - stress

    k = float(np.dot(strain, stress) / np.dot(strain, strain))
    lres = k * strain - stress
    return CurveFit(
        name=name, spline=spline, max_strain=float(np.max(x)),
        max_stress=float(np.max(np.abs(stress))), points=int(strain.size), rms=rms,
        max=float(np.max(np.abs(res))), linear_k=k,
        linear_rms=float(np.sqrt(np.mean(lres * lres))), linear_max=float(np.max(np.abs(lres))),
        constrained=constrained,
        rms_by_segments={n: v[1] for n, v in candidates.items()})


def fit_measured(measured: Measured, max_segments: int = MAX_SEGMENTS) -> dict[str, CurveFit]:
    return {name: fit_curve(name, c.strain, c.stress, max_segments)
            for name, c in measured.curves.items()}


# --------------------------------------------------------------------------------------------
# Output
# --------------------------------------------------------------------------------------------


def _toml_string(s: str) -> str:
    out = s.replace("\\", "\\\\").replace('"', '\\"')
    out = "".join(ch if ch >= " " or ch == "\t" else f"\\u{ord(ch):04x}" for ch in out)
    return f'"{out}"'


def _num(x: float) -> str:
    x = float(x)
    if x == 0.0:
        return "0.0"
    return repr(x)


def material_toml(measured: Measured, fits: dict[str, CurveFit], command: str) -> str:
    name = measured.fabric or os.path.splitext(os.path.basename(measured.path))[0]
    rms_text = ", ".join(f"{n} {fits[n].pct(fits[n].rms):.2f}%" for n in CURVES)
    lines = [f"# Fitted by hapticloth-fit from {measured.path}"]
    if measured.source:
        lines.append(f"# Data: {measured.source}")
    lines += [
        "# Spline law of HAPTEX appendix A.2; knots by nonlinear least squares, coefficients by",
        "# linear least squares for those knots, tangent kept >= 0 up to max_strain.",
        f"# Regenerate: {command}",
    ]
    for n in CURVES:
        f = fits[n]
        lines.append(
            f"#   {n + ':':<6} {f.spline.segments} segment{'s' if f.spline.segments > 1 else ' '}, "
            f"RMS {f.pct(f.rms):.2f}% and max {f.pct(f.max):.2f}% of max |stress| "
            f"{f.max_stress:.4g} N/m; linear law RMS {f.pct(f.linear_rms):.2f}%")
    wrapped = []
    for line in lines:
        wrapped += _wrap_comment(line)
    out = wrapped + [
        f"name = {_toml_string(name)}",
        f"areal_density = {_num(measured.areal_density)}  # kg/m^2",
        f"source = {_toml_string(f'hapticloth-fit {measured.path} (RMS of max stress: {rms_text})')}",
    ]
    for n in CURVES:
        f = fits[n]
        s = f.spline
        what = {"weft": "sigma_uu(eps_uu)", "warp": "sigma_vv(eps_vv)",
                "shear": "sigma_uv(eps_uv), odd"}[n]
        out += [
            "",
            f"[{n}]  # {what}, N/m",
            "knots = [" + ", ".join(_num(k) for k in s.knots) + "]",
            "B = [" + ",\n     ".join(
                "[" + ", ".join(_num(b) for b in row) + "]" for row in s.B) + "]",
            f"max_strain = {_num(f.max_strain)}",
        ]
    return "\n".join(out) + "\n"


def _wrap_comment(line: str, width: int = 100) -> list[str]:
    if len(line) <= width or line.startswith("# Regenerate:"):
        return [line]
    indent = "#   " if not line.startswith("#   ") else "#     "
    out, current = [], ""
    for word in line.split(" "):
        if current and len(current) + 1 + len(word) > width:
            out.append(current)
            current = indent + word
        else:
            current = f"{current} {word}" if current else word
    out.append(current)
    return out


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
    name = measured.fabric or os.path.splitext(os.path.basename(measured.path))[0]
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


# --------------------------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------------------------


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
    check_writable(args.output, "--output")
    if args.plot:
        check_writable(args.plot, "--plot")

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
        with open(args.output, "w", encoding="utf-8") as f:
            f.write(material_toml(measured, fits, command))
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
