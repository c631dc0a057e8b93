"""Fitting of the spline law (fit_spline) to one measured curve, or to all three of a fabric.

The shear law is fitted to sigma(|e|) * sign(e) over both branches of the data; weft and warp
are fitted on their loading branch and pass through the origin.

Fitting (variable projection, as in the appendix): for given knots the coefficients B are the
solution of a linear least-squares problem, so only the inner knots E_1, E_2 are nonlinear
unknowns. The objective is evaluated on a grid of knot positions and scipy.optimize.least_squares
is started from the best few grid points, through a smooth map from the unit box onto ordered
knots inside the data range that are separated by a minimum gap. The fit is done in scaled units
(strain / max strain, stress / max |stress|).

Monotonicity: the server rejects a law whose tangent d sigma / d eps is negative anywhere on
[0, max_strain] (max_strain: the largest |strain| of the data). If the unconstrained coefficients
for given knots give a negative tangent (checked exactly: the tangent is a quadratic on each knot
interval), the coefficients are recomputed as an inequality-constrained least-squares problem
(lsq). The constraints are cutting planes: tangent >= 0 where the previous solution's tangent
was smallest, added until the exact minimum is >= 0 (with a fallback to 801 evenly spaced
strains, a superset of the 401 the server checks).

Number of segments, per curve: starting from one segment, the best law with more segments (up
to K) replaces the current choice only if it lowers the RMS error by at least 10% and lowers the
Bayesian information criterion n ln(RSS / n) + p ln(n) (n points, p coefficients and knots), so
that knots are not spent on fitting measurement noise. The last knot keeps at least four data
points after it.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np

from .fit_csv import Measured
from .fit_spline import Spline, _min_tangent, fit_parameter_count
from .lsq import LSI

MAX_SEGMENTS = 3

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
# Knot search: the objective is evaluated on a grid of this many values per unit-box knot
# coordinate, and least_squares is started from the best LOCAL_STARTS grid points.
SEARCH_GRID = 12
LOCAL_STARTS = 4


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
