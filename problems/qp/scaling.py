"""Ruiz equilibration of a QP with OSQP's cost scaling (Stellato et al. 2020, section 5.1; osqp ``src/scaling.c``).

The scaled problem is

    minimise  1/2 xb' Pb xb + qb' xb   subject to  lb <= Ab xb <= ub,

    Pb = c D P D,   qb = c D q,   Ab = E A D,   lb = E l,   ub = E u,        (S1)

with x = D xb and the multipliers y = E yb / c.  D (n) and E (m) are positive
diagonal matrices and c > 0 a number.  Each of the ``iterations`` Ruiz steps
divides every column of the KKT matrix [[P, A'], [A, 0]] by the square root of
its infinity norm (norms below MIN_SCALING count as 1, above MAX_SCALING as
MAX_SCALING), then divides the cost by max(mean column norm of P, ||q||_inf)
(limited the same way).  These are the numbers of OSQP 1.x, step for step,
including one detail of its code: the column norms of P are those of the
upper triangle OSQP stores (``OSQPMatrix_col_norm_inf`` on triu(P)), so an
entry below the diagonal does not count in its column.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

#: OSQP_MIN_SCALING, OSQP_MAX_SCALING
MIN_SCALING, MAX_SCALING = 1e-4, 1e4


@dataclass
class Scaling:
    """The diagonal scalings D (length n), E (length m) and the cost scaling c of (S1)."""

    D: np.ndarray
    E: np.ndarray
    c: float

    @property
    def identity(self) -> bool:
        """True when D = 1, E = 1 and c = 1 (no scaling)."""
        return self.c == 1.0 and bool(np.all(self.D == 1.0)) and bool(np.all(self.E == 1.0))

    def unscale_x(self, xb: np.ndarray) -> np.ndarray:
        """x = D xb."""
        return self.D * xb

    def scale_x(self, x: np.ndarray) -> np.ndarray:
        """xb = D^-1 x."""
        return x / self.D

    def unscale_y(self, yb: np.ndarray) -> np.ndarray:
        """y = E yb / c."""
        return self.E * yb / self.c

    def scale_y(self, y: np.ndarray) -> np.ndarray:
        """yb = c E^-1 y."""
        return self.c * y / self.E

    def unscale_z(self, zb: np.ndarray) -> np.ndarray:
        """z = E^-1 zb (z lives where A x does)."""
        return zb / self.E


def _limit(v: np.ndarray) -> np.ndarray:
    """OSQP's limit_scaling: values < MIN_SCALING become 1, values > MAX_SCALING become MAX_SCALING."""
    v = np.where(v < MIN_SCALING, 1.0, v)
    return np.minimum(v, MAX_SCALING)


def _limit_scalar(v: float) -> float:
    return 1.0 if v < MIN_SCALING else min(v, MAX_SCALING)


def _col_norms(M: sp.csc_matrix) -> np.ndarray:
    return np.asarray(abs(M).max(axis=0).todense()).ravel() if M.shape[0] else np.zeros(M.shape[1])


def _row_norms(M: sp.csr_matrix) -> np.ndarray:
    return np.asarray(abs(M).max(axis=1).todense()).ravel() if M.shape[1] else np.zeros(M.shape[0])


def ruiz(P: sp.spmatrix, q: np.ndarray, A: sp.spmatrix, iterations: int = 10):
    """Return (Scaling, Pb, qb, Ab): ``iterations`` Ruiz steps with cost scaling, as OSQP's ``scale_data``.

    ``iterations = 0`` gives the identity scaling and the data unchanged.
    """
    if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)) or iterations < 0:
        raise ValueError(f"scaling must be an integer >= 0 (Ruiz iterations; OSQP uses 10), got {iterations!r}")
    n, m = P.shape[0], A.shape[0]
    D, E, c = np.ones(n), np.ones(m), 1.0
    P, A, q = sp.csc_matrix(P), sp.csc_matrix(A), np.asarray(q, dtype=float).copy()
    for _ in range(int(iterations)):
        d = np.maximum(_col_norms(sp.triu(P, format="csc")), _col_norms(A))   # KKT columns 1..n (see below)
        e = _row_norms(A.tocsr())                                          # KKT columns n+1..n+m
        d, e = 1.0 / np.sqrt(_limit(d)), 1.0 / np.sqrt(_limit(e))
        Dd, De = sp.diags(d), sp.diags(e)
        P = (Dd @ P @ Dd).tocsc()                                          # P <- D P D
        A = (De @ A @ Dd).tocsc()                                          # A <- E A D
        q = d * q
        D, E = D * d, E * e
        mean_col = float(_col_norms(sp.triu(P, format="csc")).sum()) / n
        c_step = 1.0 / _limit_scalar(max(mean_col, _limit_scalar(float(np.max(np.abs(q), initial=0.0)))))
        P = (c_step * P).tocsc()
        q = c_step * q
        c *= c_step
    return Scaling(D, E, c), P, q, A
