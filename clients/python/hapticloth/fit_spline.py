"""The spline material law of HAPTEX appendix A.2, as the server evaluates it.

The law of each curve (weft, warp, shear) is the C1 truncated power spline

    sigma(eps) = sum_{i<K} sum_{j<=3} B_ij (eps - E_i)_+^j,   E_0 = 0 < E_1 < E_2,
    B_i0 = B_i1 = 0 for i >= 1,  B_00 = 0,

with K = 1..3 segments. The shear law is odd, sigma(-e) = -sigma(e).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def fit_parameter_count(segments: int) -> int:
    """Coefficients plus inner knots of a law with `segments` segments (B_00 fixed at 0)."""
    coefficients = 3 + 2 * (segments - 1)
    return coefficients + (segments - 1)


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
