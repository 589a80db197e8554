"""The finest level of the 3-D smoothed aggregation in compiled loops: pyamg's values and orders, bit for bit.

For a 3-D vector problem (A in 3 x 3 node blocks, six near-null vectors)
pyamg's set-up of the finest level makes, in BSR: A.tobsr, the strength of
connection (with theta = 0 the node graph of A), the aggregates, the
tentative prolongator T (3 x 6 blocks, one per node), D^-1 A and its
(omega / rho) multiple (two copies of A), their product with T, P = T - (that
product), R = P' and the Galerkin product A_1 = (R A) P.  On the 3-D block at
h = 1/32 (3.1e5 unknowns) the finest level took 1.9 of the set-up's 2.7 s of
CPU, most of it scipy's generic BSR products and the temporaries they fill
(R A alone holds a 6 x 3 block for every pair (aggregate, fine node) two
steps apart).

:func:`finest_level` makes the same level from the CSR matrix itself:

* the node graph, 1 / a_ii and the spectral radius estimate's products read
  the CSR arrays (no BSR copy of A, no scaled copies): the products are
  scipy's ``bsr_matvec`` sums in their order, with the scaled entries
  fl(a_ij / a_ii) made as they are read;
* P = T - (omega / rho) D^-1 A T in one pass over A, each block's sums in
  the order of scipy's ``bsr_matmat`` (a block row's blocks in order, the
  3 terms of each inner product one after the other) and P's blocks in the
  order of scipy's ``bsr_minus_bsr``;
* A_1 row by row: the row of R A in a work array (scipy's sums and its order
  of first appearance), at once multiplied by P, so R A is never stored.

The aggregation, T and R = P' stay pyamg's and scipy's (cheap); the levels
below are pyamg's own set-up of A_1.  Same bits as pyamg's hierarchy
(tests/admmkit/test_amg_finest3d.py compares every array), hence the same
iterates.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..kernels import _u, njit


@njit(cache=True)
def node_graph(indptr, indices, Cp, Cj):
    """Whether the CSR pattern is made of whole 3 x 3 node blocks, in ascending block columns, each block row's
    three rows alike; if so its node graph (the BSR pattern) into ``Cp`` (n_nodes + 1) and ``Cj`` (n_blocks, or
    empty to count only)."""
    n_nodes = (indptr.shape[0] - 1) // 3
    Cp[0] = 0
    for I in range(n_nodes):
        start = indptr[_u(3 * I)]
        length = indptr[_u(3 * I + 1)] - start
        if length % 3 != 0:
            return False
        for r in range(1, 3):
            if indptr[_u(3 * I + r + 1)] - indptr[_u(3 * I + r)] != length:
                return False
        m = length // 3
        last = -1
        for q in range(m):
            J = indices[_u(start + 3 * q)] // 3
            if J <= last:
                return False
            last = J
            for r in range(3):
                base = indptr[_u(3 * I + r)] + 3 * q
                for c in range(3):
                    if indices[_u(base + c)] != 3 * J + c:
                        return False
            if Cj.shape[0]:
                Cj[_u(Cp[_u(I)] + q)] = J
        Cp[_u(I + 1)] = Cp[_u(I)] + m
    return True


@njit(cache=True)
def inverse_diagonal(indptr, indices, data):
    """1 / a_ii of a CSR matrix (0 where a_ii is 0 or not stored), as pyamg's ``get_diagonal(A, inv=True)``."""
    n = indptr.shape[0] - 1
    out = np.zeros(n)
    for i in range(n):
        for k in range(indptr[_u(i)], indptr[_u(i + 1)]):
            if indices[_u(k)] == i:
                if data[_u(k)] != 0.0:
                    out[_u(i)] = 1.0 / data[_u(k)]
                break
    return out


@njit(cache=True)
def scaled_matvec(indptr, indices, data, dinv, x, y):
    """y = (D^-1 A) x with the entries fl(a_ij dinv_i), each row summed from 0 in CSR order (scipy's bsr_matvec
    for whole 3 x 3 blocks: the same sums in the same order)."""
    n = indptr.shape[0] - 1
    for i in range(n):
        s = 0.0
        d = dinv[_u(i)]
        for k in range(indptr[_u(i)], indptr[_u(i + 1)]):
            s += (data[_u(k)] * d) * x[_u(indices[_u(k)])]
        y[_u(i)] = s


@njit(cache=True)
def _first_aggregates(Cp, Cj, agg, I, order, seen):
    """The aggregates of node I's neighbours in order of first appearance (as scipy's bsr_matmat meets them) into
    ``order``; returns their count (``seen`` marks them and is cleared again by the caller)."""
    m = 0
    for q in range(Cp[_u(I)], Cp[_u(I + 1)]):
        K = agg[_u(Cj[_u(q)])]
        if K >= 0 and not seen[_u(K)]:
            seen[_u(K)] = True
            order[_u(m)] = K
            m += 1
    return m


@njit(cache=True)
def prolongator_pattern(Cp, Cj, agg, n_agg, Pp):
    """Rows of P = T - X (X = c D^-1 A T): their block counts into ``Pp`` (before all-zero blocks are dropped),
    and whether X is in canonical order (every row's blocks ascending), which decides scipy's order of P."""
    n_nodes = Cp.shape[0] - 1
    seen = np.zeros(n_agg, dtype=np.bool_)
    order = np.empty(n_agg, dtype=np.int64)
    canonical = True
    Pp[0] = 0
    for I in range(n_nodes):
        m = _first_aggregates(Cp, Cj, agg, I, order, seen)
        count = m
        for q in range(m):
            if q and order[_u(q)] <= order[_u(q - 1)]:
                canonical = False
            seen[_u(order[_u(q)])] = False
        own = agg[_u(I)]
        if own >= 0:
            count += 1
            for q in range(m):
                if order[_u(q)] == own:
                    count -= 1
        Pp[_u(I + 1)] = Pp[_u(I)] + count
    return canonical


@njit(cache=True)
def smoothed_prolongator(indptr, data, Cp, Cj, agg, n_agg, T, dinv, c, canonical, Pp, Pj, Px):
    """P = T - c (D^-1 A) T in 3 x 6 blocks, the values and order of pyamg's jacobi_prolongation_smoother.

    ``agg[J]``: node J's aggregate, the column of its one block of T, ``T[J]`` (-1: none); ``c`` = omega / rho.
    Each block X_IK is the sum, over the blocks A_IJ of row I with agg[J] = K in order, of
    fl(fl(a dinv) c) T_J, summed as scipy's gemm (each entry from its running value, the 3 products one after
    the other).  The row's blocks in the order of scipy's bsr_minus_bsr: ascending if ``canonical`` (T and X
    both in ascending order), else the reverse of their order of first appearance (T's block, then X's); its
    all-zero blocks dropped.  ``Pp`` is rewritten with the blocks kept; returns their number."""
    n_nodes = Cp.shape[0] - 1
    seen = np.zeros(n_agg, dtype=np.bool_)
    order = np.empty(n_agg, dtype=np.int64)
    slot = np.full(n_agg, -1, dtype=np.int64)
    listed = np.empty(n_agg + 1, dtype=np.int64)
    X = np.zeros((n_agg, 3, 6))
    cs = np.empty((3, 3))
    nnz = 0
    Pp[0] = 0
    for I in range(n_nodes):
        m = _first_aggregates(Cp, Cj, agg, I, order, seen)
        for q in range(m):
            K = order[_u(q)]
            slot[_u(K)] = q
            seen[_u(K)] = False
            for r in range(3):
                for t in range(6):
                    X[_u(q), r, t] = 0.0
        for q in range(Cp[_u(I)], Cp[_u(I + 1)]):
            J = Cj[_u(q)]
            K = agg[_u(J)]
            if K < 0:
                continue
            b = q - Cp[_u(I)]
            for r in range(3):
                base = indptr[_u(3 * I + r)] + 3 * b
                for e in range(3):
                    cs[r, e] = (data[_u(base + e)] * dinv[_u(3 * I + r)]) * c
            s = slot[_u(K)]
            for r in range(3):
                for t in range(6):
                    dot = X[_u(s), r, t]
                    for e in range(3):
                        dot += cs[r, e] * T[_u(J), e, t]
                    X[_u(s), r, t] = dot
        own = agg[_u(I)]
        w = 0
        if own >= 0:
            listed[0] = own
            w = 1
        for q in range(m):
            if order[_u(q)] != own:
                listed[_u(w)] = order[_u(q)]
                w += 1
        if canonical:
            listed[:w].sort()
        else:
            listed[:w] = listed[:w][::-1].copy()
        for q in range(w):
            K = listed[_u(q)]
            s = slot[_u(K)]
            nonzero = False
            for r in range(3):
                for t in range(6):
                    if canonical:                       # bsr_binop_bsr_canonical: op(a, b), op(a, 0), op(0, b)
                        a = T[_u(I), r, t] if K == own else 0.0
                        x = X[_u(s), r, t] if s >= 0 else 0.0
                    else:                               # the general one: rows summed into zeroed work arrays
                        a = 0.0 + T[_u(I), r, t] if K == own else 0.0
                        x = 0.0 + X[_u(s), r, t] if s >= 0 else 0.0
                    v = a - x
                    Px[_u(nnz), r, t] = v
                    if v != 0.0:
                        nonzero = True
            if nonzero:
                Pj[_u(nnz)] = K
                nnz += 1
        for q in range(m):
            slot[_u(order[_u(q)])] = -1
        Pp[_u(I + 1)] = nnz
    return nnz


@njit(cache=True)
def galerkin_pattern(Rp, Rj, Cp, Cj, Pp, Pj, n_agg, Ap):
    """Block counts of the rows of A_1 = (R A) P into ``Ap`` (scipy's bsr_matmat keeps every block it meets)."""
    n_nodes = Cp.shape[0] - 1
    mark_J = np.full(n_nodes, -1, dtype=np.int64)
    mark_M = np.full(n_agg, -1, dtype=np.int64)
    Ap[0] = 0
    for K in range(n_agg):
        count = 0
        for ii in range(Rp[_u(K)], Rp[_u(K + 1)]):
            I = Rj[_u(ii)]
            for q in range(Cp[_u(I)], Cp[_u(I + 1)]):
                J = Cj[_u(q)]
                if mark_J[_u(J)] == K:
                    continue
                mark_J[_u(J)] = K
                for pp in range(Pp[_u(J)], Pp[_u(J + 1)]):
                    M = Pj[_u(pp)]
                    if mark_M[_u(M)] != K:
                        mark_M[_u(M)] = K
                        count += 1
        Ap[_u(K + 1)] = Ap[_u(K)] + count


@njit(cache=True)
def galerkin_product(Rp, Rj, Rx, indptr, data, Cp, Cj, Pp, Pj, Px, Ap, Aj, Ax):
    """A_1 = (R A) P in 6 x 6 blocks, scipy's values and order: row K of R A (6 x 3 blocks) summed in a work array
    as bsr_matmat sums it (R's blocks of row K in order, each times A's block row in order; its blocks in order of
    first appearance), then multiplied by P the same way, so R A is never stored."""
    n_nodes = Cp.shape[0] - 1
    n_agg = Ap.shape[0] - 1
    RA = np.zeros((n_nodes, 6, 3))
    at_J = np.full(n_nodes, -1, dtype=np.int64)
    list_J = np.empty(n_nodes, dtype=np.int64)
    acc = np.zeros((n_agg, 6, 6))
    at_M = np.full(n_agg, -1, dtype=np.int64)
    list_M = np.empty(n_agg, dtype=np.int64)
    r, block, ra = np.empty((6, 3)), np.empty((3, 3)), np.empty((6, 3))
    for K in range(n_agg):
        n_J = 0
        for ii in range(Rp[_u(K)], Rp[_u(K + 1)]):
            I = Rj[_u(ii)]
            for a in range(6):
                for d in range(3):
                    r[a, d] = Rx[_u(ii), a, d]
            for q in range(Cp[_u(I)], Cp[_u(I + 1)]):
                J = Cj[_u(q)]
                if at_J[_u(J)] < 0:
                    at_J[_u(J)] = n_J
                    list_J[_u(n_J)] = J
                    n_J += 1
                b = q - Cp[_u(I)]
                for d in range(3):
                    base = indptr[_u(3 * I + d)] + 3 * b
                    for e in range(3):
                        block[d, e] = data[_u(base + e)]
                for a in range(6):
                    for e in range(3):
                        dot = RA[_u(J), a, e]
                        for d in range(3):
                            dot += r[a, d] * block[d, e]
                        RA[_u(J), a, e] = dot
        n_M = 0
        for jj in range(n_J):
            J = list_J[_u(jj)]
            for a in range(6):
                for d in range(3):
                    ra[a, d] = RA[_u(J), a, d]
            for pp in range(Pp[_u(J)], Pp[_u(J + 1)]):
                M = Pj[_u(pp)]
                if at_M[_u(M)] < 0:
                    at_M[_u(M)] = n_M
                    list_M[_u(n_M)] = M
                    n_M += 1
                for a in range(6):
                    for t in range(6):
                        dot = acc[_u(M), a, t]
                        for d in range(3):
                            dot += ra[a, d] * Px[_u(pp), d, t]
                        acc[_u(M), a, t] = dot
            at_J[_u(J)] = -1
            for a in range(6):
                for e in range(3):
                    RA[_u(J), a, e] = 0.0
        w = Ap[_u(K)]
        for mm in range(n_M):
            M = list_M[_u(mm)]
            Aj[_u(w + mm)] = M
            for a in range(6):
                for t in range(6):
                    Ax[_u(w + mm), a, t] = acc[_u(M), a, t]
                    acc[_u(M), a, t] = 0.0
            at_M[_u(M)] = -1


class ScaledRows:
    """D^-1 A as an operator for the spectral radius estimate: ``op @ v`` for an (n, 1) column is scipy's product
    with pyamg's scaled copy of A, made without the copy (:func:`scaled_matvec`)."""

    def __init__(self, A: sp.csr_matrix, dinv: np.ndarray):
        self.A, self.dinv = A, dinv
        self.shape, self.dtype = A.shape, A.dtype

    def __matmul__(self, v: np.ndarray) -> np.ndarray:
        """(D^-1 A) v for an (n, 1) column, as an (n, 1) column."""
        y = np.empty(self.shape[0])
        scaled_matvec(self.A.indptr, self.A.indices, self.A.data, self.dinv, np.ascontiguousarray(v.ravel()), y)
        return y.reshape(-1, 1)


#: pyamg's default damping of the Jacobi prolongation smoother
OMEGA = 4.0 / 3.0


def finest_level(A: sp.csr_matrix, B: np.ndarray, spectral_radius, max_coarse: int):
    """(level, A_1, B_1): the finest level of pyamg's smoothed aggregation of A (level.A = A, B, P, R; the
    defaults of :class:`admmkit.linalg.amg.AMGPreconditioner`: symmetric strength with theta 0, standard
    aggregation, Jacobi smoothing with omega 4/3), its Galerkin product A_1 (BSR 6 x 6) and near-null vectors
    B_1; the same arrays as pyamg's.  None where it does not apply: A not in whole 3 x 3 node blocks (sorted
    CSR), B without 6 columns, or A already coarse (at most ``max_coarse`` nodes).  ``spectral_radius``: the
    estimate pyamg's smoother would call (with the caller's random state)."""
    from pyamg.aggregation.aggregate import standard_aggregation
    from pyamg.aggregation.tentative import fit_candidates
    from pyamg.multilevel import MultilevelSolver
    n = A.shape[0]
    B = np.asarray(B, dtype=float)
    if (not sp.issparse(A) or A.format != "csr" or n % 3 or n // 3 <= max_coarse or B.ndim != 2
            or B.shape != (n, 6) or not A.has_sorted_indices):
        return None
    index = A.indices.dtype
    Cp = np.empty(n // 3 + 1, dtype=index)
    if not node_graph(A.indptr, A.indices, Cp, np.empty(0, dtype=index)):
        return None
    Cj = np.empty(Cp[-1], dtype=index)
    node_graph(A.indptr, A.indices, Cp, Cj)
    C = sp.csr_array((np.ones(Cj.size), Cj, Cp), shape=(n // 3, n // 3))
    AggOp, _ = standard_aggregation(C)
    T, B1 = fit_candidates(AggOp, B)
    n_agg = T.shape[1] // 6
    rows = np.diff(T.indptr)
    if T.blocksize != (3, 6) or rows.max(initial=0) > 1:
        return None
    agg = np.full(n // 3, -1, dtype=np.int64)
    agg[rows > 0] = T.indices
    Tnode = np.zeros((n // 3, 3, 6))
    Tnode[rows > 0] = T.data
    dinv = inverse_diagonal(A.indptr, A.indices, A.data)
    c = OMEGA / spectral_radius(ScaledRows(A, dinv))
    Pp = np.empty(n // 3 + 1, dtype=index)
    canonical = prolongator_pattern(Cp, Cj, agg, n_agg, Pp)
    Pj, Px = np.empty(Pp[-1], dtype=index), np.empty((Pp[-1], 3, 6))
    nnz = smoothed_prolongator(A.indptr, A.data, Cp, Cj, agg, n_agg, Tnode, dinv, c, canonical, Pp, Pj, Px)
    P = type(T)((Px[:nnz], Pj[:nnz], Pp), shape=(n, 6 * n_agg))
    R = P.T
    Ap = np.empty(n_agg + 1, dtype=index)
    galerkin_pattern(R.indptr, R.indices, Cp, Cj, P.indptr, P.indices, n_agg, Ap)
    Aj, Ax = np.empty(Ap[-1], dtype=index), np.empty((Ap[-1], 6, 6))
    galerkin_product(R.indptr, R.indices, R.data, A.indptr, A.data, Cp, Cj, P.indptr, P.indices, P.data, Ap, Aj, Ax)
    A1 = type(T)((Ax, Aj, Ap), shape=(6 * n_agg, 6 * n_agg))
    level = MultilevelSolver.Level()
    level.A, level.B, level.P, level.R = A, B, P, R
    return level, A1, B1
