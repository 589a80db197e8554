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

import functools
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from admmkit.kernels import compiled_now
from admmkit.loop.segments import AVAILABLE as NUMBA      # numba installed (asked once, without importing it)

from .csc import csc_of
from .ruiz_kernel import has_tiny_rows, ruiz_steps
from .sparse_kernels import inf_norms

#: OSQP_MIN_SCALING, OSQP_MAX_SCALING
MIN_SCALING, MAX_SCALING = 1e-4, 1e4
#: a row of A whose inf-norm is below TINY_ROW (and not 0) is divided by it, as a power of 2, before the Ruiz
#: steps: they leave rows below MIN_SCALING as they are, and the loop would never see such a row (issue #46)
TINY_ROW = 1e-6


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


class _ColMax:
    """Largest ``abs`` entry per column of a CSC matrix's ``data`` taken in the order ``take`` (all entries: None),
    columns delimited by ``indptr``; the segments are found once, each call is two vector operations."""

    def __init__(self, indptr: np.ndarray, take: np.ndarray | None = None):
        self.take, self.n = take, len(indptr) - 1
        self.full = np.flatnonzero(np.diff(indptr))          # the non-empty columns (empty ones stay 0)
        self.starts = indptr[self.full]

    def __call__(self, data: np.ndarray) -> np.ndarray:
        out = np.zeros(self.n)
        if self.full.size:
            out[self.full] = np.maximum.reduceat(np.abs(data if self.take is None else data[self.take]), self.starts)
        return out


class _Entries:
    """A CSC matrix's entries with the row and column of each, to scale them as diag(a) M diag(b) in place."""

    def __init__(self, M: sp.csc_matrix):
        M = _csc(M)
        if M.has_canonical_format and np.count_nonzero(M.data) == M.data.size:     # a validated QP's matrix: its data copied, its pattern shared
            M = csc_of(M.data.copy(), M.indices, M.indptr, M.shape)
        else:
            M = M.copy()
            M.sum_duplicates()
            M.eliminate_zeros()                   # the pattern scipy's products keep
        self.matrix, self.rows = M, M.indices

    @functools.cached_property
    def cols(self) -> np.ndarray:
        """The column of each entry (made at first use: the compiled steps walk the columns by ``indptr``)."""
        M = self.matrix
        return np.repeat(np.arange(M.shape[1]), M.indptr[1:] - M.indptr[:-1])      # (np.diff: 2 us more)

    def scale(self, left: np.ndarray, right: np.ndarray) -> None:
        """M <- diag(left) M diag(right), in the order scipy's ``diags(left) @ M @ diags(right)`` rounds."""
        data = self.matrix.data
        np.multiply(left[self.rows], data, out=data)
        np.multiply(data, right[self.cols], out=data)

    def col_max(self) -> _ColMax:
        """Largest ``abs`` entry per column, as a function of the data."""
        return _ColMax(self.matrix.indptr)

    def upper_col_max(self) -> _ColMax:
        """Largest ``abs`` entry per column of the upper triangle (what OSQP stores of P)."""
        keep = np.flatnonzero(self.rows <= self.cols)
        counts = np.bincount(self.cols[keep], minlength=self.matrix.shape[1])
        return _ColMax(np.r_[0, np.cumsum(counts)], keep)

    def row_max(self) -> _ColMax:
        """Largest ``abs`` entry per row (through the CSR order of the entries)."""
        order = np.argsort(self.rows, kind="stable")
        counts = np.bincount(self.rows, minlength=self.matrix.shape[0])
        return _ColMax(np.r_[0, np.cumsum(counts)], order)


def _csc(M):
    """``M`` as a float CSC matrix (``M`` itself when it is one: a new scipy object costs ~10 us)."""
    return M if sp.isspmatrix_csc(M) and M.dtype == np.float64 else sp.csc_matrix(M, dtype=float)


def _lift_tiny_rows(Ae: _Entries, E: np.ndarray) -> None:
    """Divide every row of A with inf-norm in (0, TINY_ROW) by that norm rounded to a power of 2 (exact), into E.

    OSQP's steps count a norm below MIN_SCALING as 1, so a row of norm 1e-8 stays 1e-8 in the scaled
    problem and rho A'A does not see it.  No Maros-Meszaros row is below TINY_ROW (the smallest is 1e-4),
    so their scalings, and the iterates, are OSQP's."""
    if NUMBA and compiled_now():                # one compiled pass (the same maxima), no argsort of the rows
        M = Ae.matrix
        if not has_tiny_rows(M.indices, M.data, M.shape[0], TINY_ROW):      # the common case: one call, no arrays
            return
        nu = inf_norms(M.indptr, M.indices, M.data, M.shape[0])[0]
    else:
        nu = Ae.row_max()(Ae.matrix.data)
    tiny = (nu > 0) & (nu < TINY_ROW)
    if tiny.any():
        E[tiny] = np.exp2(-np.round(np.log2(nu[tiny])))
        Ae.scale(E, np.ones(Ae.matrix.shape[1]))


def ruiz(P: sp.spmatrix, q: np.ndarray, A: sp.spmatrix, iterations: int = 10, compiled: bool = True):
    """Return (Scaling, Pb, qb, Ab): ``iterations`` Ruiz steps with cost scaling, as OSQP's ``scale_data``.

    ``iterations = 0`` gives the identity scaling and the data unchanged.  The
    steps scale the entries of P and A in place: in one compiled call
    (``admmkit.problems.qp.ruiz_kernel``, which sums the mean column norm in
    order, as OSQP does) when numba is installed and ``compiled``, else with
    vector operations on the CSC arrays (no new sparse matrix per step).
    """
    if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)) or iterations < 0:
        raise ValueError(f"scaling must be an integer >= 0 (Ruiz iterations; OSQP uses 10), got {iterations!r}")
    n, m = P.shape[0], A.shape[0]
    D, E, c = np.ones(n), np.ones(m), 1.0
    if not iterations:                           # the data as it is (a CSC matrix is returned itself, not copied)
        return Scaling(D, E, c), _csc(P), np.asarray(q, dtype=float).copy(), _csc(A)
    Pe, Ae, q = _Entries(P), _Entries(A), np.asarray(q, dtype=float).copy()
    _lift_tiny_rows(Ae, E)
    if compiled and NUMBA:
        c = ruiz_steps(int(iterations), MIN_SCALING, MAX_SCALING, Pe.matrix.data, Pe.rows, Pe.matrix.indptr,
                       Ae.matrix.data, Ae.rows, Ae.matrix.indptr, q, D, E)
        return Scaling(D, E, c), Pe.matrix, q, Ae.matrix
    P_cols, A_cols, A_rows = Pe.upper_col_max(), Ae.col_max(), Ae.row_max()
    for _ in range(int(iterations)):
        d = np.maximum(P_cols(Pe.matrix.data), A_cols(Ae.matrix.data))     # KKT columns 1..n (see below)
        e = A_rows(Ae.matrix.data)                                          # KKT columns n+1..n+m
        d, e = 1.0 / np.sqrt(_limit(d)), 1.0 / np.sqrt(_limit(e))
        Pe.scale(d, d)                                                      # P <- D P D
        Ae.scale(e, d)                                                      # A <- E A D
        q = d * q
        D, E = D * d, E * e
        mean_col = float(P_cols(Pe.matrix.data).sum()) / n
        c_step = 1.0 / _limit_scalar(max(mean_col, _limit_scalar(float(np.max(np.abs(q), initial=0.0)))))
        Pe.matrix.data *= c_step
        q = c_step * q
        c *= c_step
    return Scaling(D, E, c), Pe.matrix, q, Ae.matrix
