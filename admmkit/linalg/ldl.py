"""A sparse LDL' factorisation in a given order, compiled (numba).

For a symmetric matrix A and an order (a permutation, ``P A P'`` the matrix
``A[order][:, order]``), :func:`ldl_factor` computes

    P A P' = (I + L) D (I + L)',   L strictly lower triangular, D diagonal,

by the *up-looking* algorithm of QDLDL (Stellato, Banjac, Goulart et al.,
the solver of OSQP; also Davis, *Direct Methods for Sparse Linear Systems*,
SIAM 2006, sections 4.1-4.4):

1. *Elimination tree and column counts* (:func:`ldl_analyse`): the parent of
   column i is the first row below i holding a nonzero of L in that column;
   row k of L is the set of nodes on the tree paths from the entries of the
   upper triangle's column k up to k.  One pass over the upper triangle gives
   the tree and the number of nonzeros of every column of L, so L is
   allocated once, exactly.
2. *Numeric factorisation* (:func:`ldl_factor`), row by row: row k of L solves
   the sparse triangular system (I + L_{<k}) D y = A_{<k,k}, visiting only
   the nonzeros of y (the tree paths of step 1, in topological order);
   then L_{k,j} = y_j / D_j and D_k = A_kk - sum_j y_j L_{k,j}.

No pivoting: the order is the caller's and is kept, which is the point of
this module (scipy's SuperLU and qdldl's wrapper choose their own or keep
none).  A symmetric positive definite A has positive pivots in every order;
a zero pivot (A singular, or its leading block in that order) is reported.
The factors are in qdldl's format, so :func:`admmkit.linalg.compiled.ldl_solve`
solves with them.

Why compiled code and why numba: the factorisation is a loop over scalars
that numpy cannot vectorise; numba compiles it at the first call (cached on
disk: a fresh process imports numba and loads the kernels in about 0.5 s,
measured on the 2-core machine of the benchmarks), is already a dependency and
needs no compiler on the user's machine, where a C extension (or a Cython
one) would.  ``fastmath`` stays off: the results are the same bits on every
run.  Without supernodes every update is a scalar loop, so the cost grows
with the factor's flops like SuperLU's but without dense-block (BLAS) speed:
it wins on small matrices, loses on large ones (the contact plug-in measures
the crossover, :mod:`admmkit.problems.contact.solvers.schur`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from admmkit.kernels import AVAILABLE, _u, kernel, njit

from admmkit.linalg.compiled import ldl_backward, ldl_forward, ldl_solve


@dataclass
class LDLFactor:
    """P A P' = (I + L) D (I + L)', L strictly lower triangular (CSC arrays Lp, Li, Lx), D = diag(d).

    ``order``: the permutation (``P A P' = A[order][:, order]``).
    """

    order: np.ndarray
    Lp: np.ndarray
    Li: np.ndarray
    Lx: np.ndarray
    d: np.ndarray

    @property
    def n(self) -> int:
        """The dimension of A."""
        return self.order.shape[0]

    @property
    def L(self) -> sp.csc_matrix:
        """L as a scipy matrix (strictly lower triangular, in the permuted order)."""
        return sp.csc_matrix((self.Lx, self.Li, self.Lp), shape=(self.n, self.n))

    def solve(self, b: np.ndarray) -> np.ndarray:
        """A^{-1} b (b and the result in A's own order, not the permuted one)."""
        b = np.ascontiguousarray(b, dtype=np.float64)
        out = np.empty_like(b)
        ldl_solve(self.Lp, self.Li, self.Lx, 1.0 / self.d, self.order, b, np.empty_like(b), out)
        return out

    def forward(self, b: np.ndarray, start: int = 0) -> np.ndarray:
        """(I + L)^{-1} b in the permuted order (a new array); ``start``: b is zero before it (skipped)."""
        y = np.array(b, dtype=np.float64)
        ldl_forward(self.Lp, self.Li, self.Lx, y, start)
        return y

    def backward(self, y: np.ndarray) -> np.ndarray:
        """(I + L)^{-T} y in the permuted order (a new array)."""
        x = np.array(y, dtype=np.float64)
        ldl_backward(self.Lp, self.Li, self.Lx, x)
        return x

    def solve_permuted(self, b: np.ndarray) -> np.ndarray:
        """(P A P')^{-1} b = (I + L)^{-T} D^{-1} (I + L)^{-1} b (b and the result in the permuted order)."""
        return self.backward(self.forward(b) / self.d)

    def trailing_block(self, m: int) -> np.ndarray:
        """(I + L) restricted to its last m rows and columns, dense (unit lower triangular, m x m)."""
        n = self.n
        out = np.eye(m)
        start = self.Lp[n - m]
        cols = np.repeat(np.arange(m), np.diff(self.Lp[n - m:]))
        out[self.Li[start:] - (n - m), cols] = self.Lx[start:]
        return out


@dataclass
class LDLAnalysis:
    """The upper triangle of P A P' (CSC arrays Up, Ui, Ux), its elimination tree and L's column counts.

    ``mean_column_length`` = sum_j c_j^2 / sum_j c_j (c_j: the nonzeros
    below the diagonal of column j of L) is the length of the column an
    average update touches; ``flops`` = sum_j c_j^2 is about the
    multiply-adds of the factorisation.  Both are known before it.
    """

    order: np.ndarray
    Up: np.ndarray
    Ui: np.ndarray
    Ux: np.ndarray
    parent: np.ndarray
    counts: np.ndarray

    @property
    def flops(self) -> float:
        """sum_j c_j^2: about the multiply-adds of the numeric factorisation."""
        return float(np.dot(self.counts.astype(np.float64), self.counts))

    @property
    def mean_column_length(self) -> float:
        """sum_j c_j^2 / sum_j c_j: the mean length of the columns the updates run over."""
        nnz = float(self.counts.sum())
        return self.flops / nnz if nnz else 0.0


def ldl_analyse(A: sp.spmatrix, order: np.ndarray | None = None) -> LDLAnalysis:
    """The symbolic phase: P A P' (upper triangle), its elimination tree and L's column counts.

    A: sparse, CSC or CSR, symmetric (both triangles stored; only the entries
    that land in the upper triangle of P A P' are read); ``order``: the
    permutation (None: A's own order).
    """
    if not AVAILABLE:   # pragma: no cover - numba is a dependency
        raise RuntimeError("admmkit.linalg.ldl needs numba")
    if A.shape[0] != A.shape[1]:
        raise ValueError(f"A must be square, got shape {A.shape}")
    n = A.shape[0]
    order = np.arange(n) if order is None else np.ascontiguousarray(order, dtype=np.int64)
    if order.shape != (n,) or (n and (order.min() < 0 or order.max() >= n or
                                      np.bincount(order, minlength=n).max() > 1)):
        raise ValueError(f"order must be a permutation of 0..{n - 1}")
    A = A if A.format in ("csc", "csr") else sp.csc_matrix(A)   # CSR of a symmetric A is the CSC of A' = A
    position = np.empty(n, np.int64)
    position[order] = np.arange(n)
    Up, Ui, Ux = _permuted_upper(A.indptr, A.indices, np.asarray(A.data, dtype=np.float64), order, position)
    parent, counts = _etree(Up, Ui)
    return LDLAnalysis(order, Up, Ui, Ux, parent, counts)


def ldl_factor(A: sp.spmatrix, order: np.ndarray | None = None, analysis: LDLAnalysis | None = None) -> LDLFactor:
    """The LDL' factorisation of the symmetric matrix A in the given order (None: A's own).

    ``analysis``: :func:`ldl_analyse`'s result for A and ``order``, if the
    caller has it (A and order are then not read).  Raises
    :class:`numpy.linalg.LinAlgError` when a pivot is zero or not finite
    (A singular, or not factorisable without pivoting in that order).
    """
    a = ldl_analyse(A, order) if analysis is None else analysis
    n = a.order.shape[0]
    Lp = np.zeros(n + 1, np.int64)
    np.cumsum(a.counts, out=Lp[1:])
    Li, Lx, d = np.empty(Lp[n], np.int64), np.empty(Lp[n], np.float64), np.empty(n, np.float64)
    bad = _factor(a.Up, a.Ui, a.Ux, a.parent, Lp, Li, Lx, d)
    if bad >= 0:
        raise np.linalg.LinAlgError(f"zero or non-finite pivot {d[bad]!r} at step {bad} of {n}: the matrix is "
                                    "singular, or not factorisable without pivoting in this order")
    return LDLFactor(a.order, Lp, Li, Lx, d)


@njit(cache=True)
def _permuted_upper(indptr, indices, data, order, position):
    """The CSC arrays of the upper triangle of A[order][:, order] (rows within a column unsorted)."""
    n = order.shape[0]
    Up = np.zeros(n + 1, np.int64)
    for j in range(n):
        count = 0
        for p in range(indptr[order[j]], indptr[order[j] + 1]):
            if position[indices[p]] <= j:
                count += 1
        Up[j + 1] = Up[j] + count
    Ui, Ux = np.empty(Up[n], np.int64), np.empty(Up[n], np.float64)
    for j in range(n):
        q = Up[j]
        for p in range(indptr[order[j]], indptr[order[j] + 1]):
            i = position[indices[p]]
            if i <= j:
                Ui[q], Ux[q] = i, data[p]
                q += 1
    return Up, Ui, Ux


@njit(cache=True)
def _etree(Up, Ui):
    """The elimination tree (parent[i], -1 at a root) and the nonzeros of each column of L, from the upper
    triangle (Up, Ui): row k of L holds the nodes met walking up from each entry of column k until k."""
    n = Up.shape[0] - 1
    parent = np.full(n, -1, np.int64)
    counts = np.zeros(n, np.int64)
    visited = np.full(n, -1, np.int64)          # visited[i] == k: node i is already in row k
    for k in range(n):
        visited[k] = k
        for p in range(Up[k], Up[k + 1]):
            i = Ui[p]
            while visited[i] != k:               # up the tree from i until a node of row k
                if parent[i] == -1:
                    parent[i] = k
                counts[i] += 1                   # L[k, i] is a nonzero
                visited[i] = k
                i = parent[i]
    return parent, counts


@njit(cache=True)
def _factor(Up, Ui, Ux, parent, Lp, Li, Lx, d):
    """Fill (Li, Lx) and d row by row (QDLDL's numeric phase); return -1, or the step of a zero pivot."""
    n = d.shape[0]
    y = np.zeros(n, np.float64)                  # row k of L D, scattered
    in_row = np.zeros(n, np.bool_)
    pattern = np.empty(n, np.int64)              # the nonzeros of row k, in topological order (from the end)
    path = np.empty(n, np.int64)
    filled = Lp[:n].copy()                       # the next free slot of each column of L
    for k in range(n):
        d[k] = 0.0
        top = n
        for p in range(Up[k], Up[k + 1]):
            i = Ui[p]
            if i == k:
                d[k] += Ux[p]
                continue
            y[i] += Ux[p]
            length = 0
            while i != -1 and i < k and not in_row[i]:   # the path from i up to the part of row k found so far
                in_row[i] = True
                path[length] = i
                length += 1
                i = parent[i]
            while length > 0:                    # prepended reversed: each node after its descendants
                length -= 1
                top -= 1
                pattern[top] = path[length]
        for t in range(top, n):                  # y_j final once its descendants are done: L[k, j] = y_j / d_j
            j = _u(pattern[t])
            yj = y[j]
            for p in range(_u(Lp[j]), _u(filled[j])):
                y[_u(Li[p])] -= Lx[p] * yj
            lkj = yj / d[j]
            Li[filled[j]] = k
            Lx[filled[j]] = lkj
            filled[j] += 1
            d[k] -= yj * lkj
            y[j] = 0.0
            in_row[j] = False
        if d[k] == 0.0 or not np.isfinite(d[k]):
            return k
    return -1


# -- qdldl's own factor, refactorised here ----------------------------------------------------------------------
# qdldl's wrapper hands its factor out only as a new scipy matrix (``Solver.factors()``: about 75 us, more than
# the factorisation of a small QP's KKT matrix, at every change of rho).  These two kernels redo its work on
# the matrix's upper triangle in qdldl's order (AMD's, read once from ``factors()``): the symbolic phase once,
# the numeric one at each new rho, with the operations of QDLDL_factor in its order (the permuted matrix
# built as qdldl's ``symperm`` builds it, L = y / D as y * (1 / D)), so the factor is qdldl's bit for bit
# (tests/problems/test_qp_kkt_factor.py compares them on generated and Maros-Meszaros KKT matrices).


@kernel(cache=True)
def qdldl_symbolic(Kp, Ki, perm):
    """The symbolic phase of qdldl on the upper triangle (Kp, Ki) of K in the order ``perm``: the upper triangle
    (Cp, Ci) of P K P' in qdldl's entry order, ``to_C`` (entry p of K is entry to_C[p] of it, -1 below the
    diagonal), the elimination tree ``parent`` and L's column pointers ``Lp``."""
    n = perm.shape[0]
    pinv = np.empty(n, np.int64)
    for j in range(n):
        pinv[perm[j]] = j
    w = np.zeros(n, np.int64)
    for j in range(n):                                  # csc_symperm: count the entries of each column of C
        for p in range(Kp[j], Kp[j + 1]):
            i = Ki[p]
            if i <= j:
                w[max(pinv[i], pinv[j])] += 1
    Cp = np.zeros(n + 1, np.int64)
    for j in range(n):
        Cp[j + 1] = Cp[j] + w[j]
        w[j] = Cp[j]
    Ci = np.empty(Cp[n], np.int64)
    to_C = np.full(Kp[n], -1, np.int64)
    for j in range(n):                                  # ... and place them, K's columns in order
        for p in range(Kp[j], Kp[j + 1]):
            i = Ki[p]
            if i <= j:
                i2, j2 = pinv[i], pinv[j]
                q = w[max(i2, j2)]
                w[max(i2, j2)] += 1
                Ci[q] = min(i2, j2)
                to_C[p] = q
    parent, counts = _etree(Cp, Ci)                   # QDLDL_etree
    Lp = np.zeros(n + 1, np.int64)
    for j in range(n):
        Lp[j + 1] = Lp[j] + counts[j]
    return Cp, Ci, to_C, parent, Lp


@kernel(cache=True)
def qdldl_numeric(Cp, Ci, Cx, parent, Lp, Li, Lx, D, Dinv, y, marked, pattern, path, next_slot):
    """QDLDL_factor on the permuted upper triangle (Cp, Ci, Cx): L (Li, Lx in Lp's columns), D and 1 / D, with
    qdldl's operations in its order; ``y``, ``marked``, ``pattern``, ``path``, ``next_slot`` are scratch of
    length n.  Returns -1, or the step whose pivot is zero (then the factor is not usable).  Indices are read
    as unsigned (``_u``: no negative-index test; the arithmetic is unchanged)."""
    n = D.shape[0]
    for i in range(n):
        marked[i] = False
        y[i] = 0.0
        D[i] = 0.0
        next_slot[i] = Lp[i]
    D[0] = Cx[0]
    if D[0] == 0.0:
        return 0
    Dinv[0] = 1.0 / D[0]
    for k in range(1, n):
        count = 0
        for p in range(_u(Cp[k]), _u(Cp[k + 1])):
            b = _u(Ci[p])
            if b == k:
                D[k] = Cx[p]
                continue
            y[b] = Cx[p]
            if not marked[b]:                           # the path from b up the tree to the part of row k found
                marked[b] = True
                path[0] = b
                length = 1
                node = parent[b]
                while node != -1 and node < k:
                    if marked[_u(node)]:
                        break
                    marked[_u(node)] = True
                    path[_u(length)] = node
                    length += 1
                    node = parent[_u(node)]
                while length > 0:
                    length -= 1
                    pattern[_u(count)] = path[_u(length)]
                    count += 1
        for t in range(count - 1, -1, -1):
            j = _u(pattern[_u(t)])
            end = _u(next_slot[j])
            yj = y[j]
            for p in range(_u(Lp[j]), end):
                y[_u(Li[p])] -= Lx[p] * yj
            Li[end] = k
            Lx[end] = yj * Dinv[j]
            D[k] -= yj * Lx[end]
            next_slot[j] = end + 1
            y[j] = 0.0
            marked[j] = False
        if D[k] == 0.0:
            return k
        Dinv[k] = 1.0 / D[k]
    return -1
