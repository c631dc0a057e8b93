"""Inequality-constrained linear least squares, min ||E x - f|| subject to G x >= h.

Solved with the LSI -> LDP -> NNLS reduction of Lawson and Hanson (Solving Least Squares
Problems, ch. 23).
"""

from __future__ import annotations

import numpy as np


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
