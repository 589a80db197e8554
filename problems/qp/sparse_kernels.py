"""Compiled (numba) passes over the QP's CSC arrays that scipy would do with several temporary matrices.

On a small QP each scipy operation costs tens of microseconds of Python
(building and checking a sparse matrix object), more than the arithmetic:
the symmetry test ``abs(P - P.T).max()`` took 80 us on HS21 (n = 2), the KKT
matrix's COO -> CSC assembly 150 us, while OSQP's whole solve takes 600 us.
These kernels read and write the arrays directly, in one pass each:

- :func:`symmetry_defect`: max |P_ij - P_ji| and max |P_ij| of a canonical CSC P;
- :func:`kkt_arrays`: the CSC arrays of the KKT matrix [[P + sigma I, A'], [A, 1]]
  (its upper triangle, or whole) and the positions of its last m diagonal entries.

Both need canonical CSC input (sorted row indices, no duplicates), which
:func:`admmkit.problems.qp.validate._validate` guarantees.  Callers fall back to
scipy when numba is not installed.
"""
from __future__ import annotations

import numpy as np

from admmkit.kernels import kernel
from admmkit.linalg.compiled import csc_matvec


@kernel(cache=True)
def _transpose(indptr, indices, data):
    """The CSC arrays of P' (P's CSR arrays) by a counting sort: row indices sorted, O(nnz)."""
    n = indptr.shape[0] - 1
    tp = np.zeros(n + 1, dtype=indptr.dtype)
    for p in range(indptr[n]):
        tp[indices[p] + 1] += 1
    for i in range(n):
        tp[i + 1] += tp[i]
    nxt = tp[:-1].copy()
    ti = np.empty(indptr[n], dtype=indices.dtype)
    tx = np.empty(indptr[n], dtype=data.dtype)
    for j in range(n):
        for p in range(indptr[j], indptr[j + 1]):
            q = nxt[indices[p]]
            ti[q] = j
            tx[q] = data[p]
            nxt[indices[p]] = q + 1
    return tp, ti, tx


@kernel(cache=True)
def symmetry_defect(indptr, indices, data):
    """(max |P_ij - P_ji|, max |P_ij|) over the stored entries of the canonical CSC matrix P (square).

    Column j of P and column j of P' (a counting-sort transpose) are merged
    as two sorted lists, an entry stored on one side only counting against
    0: every asymmetry is seen, in O(nnz).  A diagonal P (an LP's zero, a
    separable QP) returns after the first pass."""
    n = indptr.shape[0] - 1
    defect = 0.0
    scale = 0.0
    diagonal = True
    for j in range(n):
        for p in range(indptr[j], indptr[j + 1]):
            scale = max(scale, abs(data[p]))
            diagonal = diagonal and indices[p] == j
    if diagonal:
        return defect, scale
    tp, ti, tx = _transpose(indptr, indices, data)
    for j in range(n):
        p, end_p = indptr[j], indptr[j + 1]
        q, end_q = tp[j], tp[j + 1]
        while p < end_p or q < end_q:
            if q >= end_q or (p < end_p and indices[p] < ti[q]):
                defect = max(defect, abs(data[p]))
                p += 1
            elif p >= end_p or ti[q] < indices[p]:
                defect = max(defect, abs(tx[q]))
                q += 1
            else:
                defect = max(defect, abs(data[p] - tx[q]))
                p += 1
                q += 1
    return defect, scale


@kernel(cache=True)
def p_checks(indptr, indices, data):
    """(finite, max |P_ij - P_ji|, max |P_ij|, diagonal) of the canonical CSC matrix P: what the QP's construction
    asks of P (:func:`admmkit.problems.qp.validate._validate`), in one call; a P with a non-finite entry returns
    (False, 0, 0, False) at once."""
    n = indptr.shape[0] - 1
    for p in range(indptr[n]):
        if not np.isfinite(data[p]):
            return False, 0.0, 0.0, False
    defect, scale = symmetry_defect(indptr, indices, data)
    diagonal = True
    for j in range(n):
        for p in range(indptr[j], indptr[j + 1]):
            if indices[p] != j:
                diagonal = False
    return True, defect, scale, diagonal


@kernel(cache=True)
def shifted_cholesky_holds(indptr, indices, data, delta):
    """Whether P + delta I has a Cholesky factor (every pivot > 0), P given by the CSC arrays of a symmetric n x n
    matrix: the lower triangle copied into a dense array, as LAPACK's ``potrf`` reads it (``np.linalg.cholesky``),
    and factorised column by column (n^3 / 6 products: below n = 64 it costs less than LAPACK's call and the dense
    copy, the convexity test's ``COMPILED_CHOLESKY_MAX``)."""
    n = indptr.shape[0] - 1
    L = np.zeros((n, n))
    for j in range(n):
        for p in range(indptr[j], indptr[j + 1]):
            if indices[p] >= j:
                L[indices[p], j] = data[p]
        L[j, j] += delta
    for j in range(n):
        pivot = L[j, j]
        for k in range(j):
            pivot -= L[j, k] * L[j, k]
        if not pivot > 0.0:                       # <= 0 or NaN: P + delta I is not positive definite
            return False
        d = np.sqrt(pivot)
        L[j, j] = d
        for i in range(j + 1, n):
            s = L[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / d
    return True


@kernel(cache=True)
def kkt_arrays(n, m, Pp, Pi, Px, sigma, Ap, Ai, Ax, upper):
    """CSC arrays (indptr, indices, data) of K = [[P + sigma I, A'], [A, 1]] and the positions of K_{n+i, n+i}.

    P (n x n, canonical CSC) and A (m x n, canonical CSC).  ``upper``: the
    upper triangle only (qdldl's input), else the whole matrix.  Entries
    are those of scipy's sum of the blocks: P_jj + sigma is the one sum, and
    an exact zero is not stored (as ``eliminate_zeros`` drops it)."""
    rows_of_A = np.zeros(m + 1, dtype=np.int64)            # A's rows (A' by columns): a counting transpose
    for p in range(Ap[n]):
        rows_of_A[Ai[p] + 1] += 1
    for i in range(m):
        rows_of_A[i + 1] += rows_of_A[i]
    At_cols = np.empty(Ap[n], dtype=np.int64)
    At_vals = np.empty(Ap[n])
    fill = rows_of_A[:m].copy()
    for j in range(n):                                     # columns in order: each row's entries in ascending j
        for p in range(Ap[j], Ap[j + 1]):
            q = fill[Ai[p]]
            At_cols[q] = j
            At_vals[q] = Ax[p]
            fill[Ai[p]] += 1
    size = n + m
    cap = Pp[n] + n + (1 if upper else 2) * Ap[n] + m
    indptr = np.zeros(size + 1, dtype=np.int64)
    indices = np.empty(cap, dtype=np.int64)
    data = np.empty(cap)
    slots = np.empty(m, dtype=np.int64)
    nz = 0
    for j in range(n):                                     # column j: P's column (+ sigma on the diagonal), A's
        diagonal_done = False
        for p in range(Pp[j], Pp[j + 1]):
            i = Pi[p]
            if upper and i > j:
                break
            if i > j and not diagonal_done:                # the diagonal, absent from P
                diagonal_done = True
                if sigma != 0.0:
                    indices[nz] = j
                    data[nz] = sigma
                    nz += 1
            v = Px[p] + sigma if i == j else Px[p]
            if i == j:
                diagonal_done = True
            if v != 0.0:
                indices[nz] = i
                data[nz] = v
                nz += 1
        if not diagonal_done and sigma != 0.0:
            indices[nz] = j
            data[nz] = sigma
            nz += 1
        if not upper:
            for p in range(Ap[j], Ap[j + 1]):
                if Ax[p] != 0.0:
                    indices[nz] = n + Ai[p]
                    data[nz] = Ax[p]
                    nz += 1
        indptr[j + 1] = nz
    for i in range(m):                                     # column n + i: row i of A, then the -R^-1 slot
        for q in range(rows_of_A[i], rows_of_A[i + 1]):
            if At_vals[q] != 0.0:
                indices[nz] = At_cols[q]
                data[nz] = At_vals[q]
                nz += 1
        indices[nz] = n + i
        data[nz] = 1.0
        slots[i] = nz
        nz += 1
        indptr[n + i + 1] = nz
    return indptr, indices[:nz].copy(), data[:nz].copy(), slots


@kernel(cache=True, inline="always")
def _worse(m, v):
    """max(m, abs(v)) as ``np.max(np.abs(...))`` takes it: a NaN, once met, stays."""
    a = abs(v)
    return a if (a > m or a != a) else m


@kernel(cache=True)
def kkt_inf_norms(Pp, Pi, Px, q, Ap, Ai, Ax, l, u, x, z, y):
    """(primal, infeasibility, dual, complementarity, sign) of :func:`admmkit.problems.qp.kkt.kkt_residuals`.

    The user's P (n x n) and A (m x n) in CSC, the user's x, z and y.  The
    products are summed as scipy sums them (A x and P x column by column
    from 0, A'y row by row of A' = column by column of A), so every value is
    the numpy steps' bit for bit."""
    n, m = x.shape[0], z.shape[0]
    Axv = np.zeros(m)
    for j in range(n):
        for p in range(Ap[j], Ap[j + 1]):
            Axv[Ai[p]] += Ax[p] * x[j]
    primal = infeas = comp = sign = 0.0
    for i in range(m):
        a = Axv[i]
        primal = _worse(primal, a - z[i])
        infeas = _worse(infeas, a - min(max(a, l[i]), u[i]))
        y_pos, y_neg = max(y[i], 0.0), max(-y[i], 0.0)
        if np.isfinite(u[i]):
            comp = _worse(comp, y_pos * abs(u[i] - a))
        else:
            sign = _worse(sign, y_pos)
        if np.isfinite(l[i]):
            comp = _worse(comp, y_neg * abs(a - l[i]))
        else:
            sign = _worse(sign, y_neg)
    Pxv = np.zeros(n)
    for j in range(n):
        for p in range(Pp[j], Pp[j + 1]):
            Pxv[Pi[p]] += Px[p] * x[j]
    dual = 0.0
    for j in range(n):
        s = 0.0
        for p in range(Ap[j], Ap[j + 1]):
            s += Ax[p] * y[Ai[p]]
        dual = _worse(dual, (Pxv[j] + q[j]) + s)
    return primal, infeas, dual, comp, sign


@kernel(cache=True)
def osqp_norms(Pp, Pi, Px, q, Ap, Ai, Ax, l, u, x, z, y, deadzone):
    """The norms of :func:`admmkit.problems.qp.kkt.osqp_residuals` in one pass, and the vectors its three dot
    products read: (primal, primal_scale, dual, dual_scale, P x, up, y_pos, lo, y_neg), up = u where y_pos != 0
    (else 0), lo likewise, y_pos and y_neg projected as (R3) projects them.

    The user's P (n x n) and A (m x n) in CSC, the user's x, z and y.  Products are summed as scipy sums them,
    maxima taken as ``np.max(np.abs(...))`` and Python's ``max`` take them (NaN included), so every value is the
    numpy steps' bit for bit; the dot products (x'Px, q'x, S(y)) are left to numpy's, which may sum in another
    order than a loop."""
    n, m = x.shape[0], z.shape[0]
    Axv = np.empty(m)
    csc_matvec(Ap, Ai, Ax, x, Axv)
    up, lo, y_pos, y_neg = np.empty(m), np.empty(m), np.empty(m), np.empty(m)
    primal = ax_top = z_top = 0.0
    for i in range(m):
        primal = _worse(primal, Axv[i] - z[i])
        ax_top = _worse(ax_top, Axv[i])
        z_top = _worse(z_top, z[i])
        vp, vn = max(y[i], 0.0), min(y[i], 0.0)
        vp = vp if (np.isfinite(u[i]) and abs(vp) >= deadzone) else 0.0
        vn = vn if (np.isfinite(l[i]) and abs(vn) >= deadzone) else 0.0
        y_pos[i], y_neg[i] = vp, vn
        up[i] = u[i] if vp != 0 else 0.0
        lo[i] = l[i] if vn != 0 else 0.0
    Pxv = np.empty(n)
    csc_matvec(Pp, Pi, Px, x, Pxv)
    dual = px_top = aty_top = q_top = 0.0
    for j in range(n):
        s = 0.0
        for p in range(Ap[j], Ap[j + 1]):
            s += Ax[p] * y[Ai[p]]
        dual = _worse(dual, (Pxv[j] + q[j]) + s)
        px_top = _worse(px_top, Pxv[j])
        aty_top = _worse(aty_top, s)
        q_top = _worse(q_top, q[j])
    return (primal, _pymax(ax_top, z_top), dual, _pymax(_pymax(px_top, aty_top), q_top), Pxv, up, y_pos, lo,
            y_neg)


@kernel(cache=True)
def _pymax(a, b):
    """Python's max(a, b): b only where b > a (a NaN first stays, a NaN second does not)."""
    return b if b > a else a


@kernel(cache=True)
def neutral_norms(Pp, Pi, Px, q, Ap, Ai, Ax, l, u, x, y):
    """(primal, dual, gap) of :func:`admmkit.problems.qp.residuals.neutral_residuals` in one pass.

    primal and dual are the numpy steps' bit for bit (products summed as
    scipy sums them); the gap's dot products are summed in order, where
    numpy's BLAS may sum in another (the gap can differ in its last bits)."""
    n, m = x.shape[0], y.shape[0]
    Axv = np.zeros(m)
    for j in range(n):
        for p in range(Ap[j], Ap[j + 1]):
            Axv[Ai[p]] += Ax[p] * x[j]
    yp = np.empty(m)
    primal = support = 0.0
    for i in range(m):
        a = Axv[i]
        primal = _worse(primal, a - min(max(a, l[i]), u[i]))
        v = min(y[i], 0.0) if np.isinf(u[i]) else y[i]          # a harness sees no multiplier of an infinite bound
        v = max(v, 0.0) if np.isinf(l[i]) else v
        yp[i] = v
        if v > 0.0:
            support += u[i] * v
        elif v < 0.0:
            support += l[i] * v
    Pxv = np.zeros(n)
    for j in range(n):
        for p in range(Pp[j], Pp[j + 1]):
            Pxv[Pi[p]] += Px[p] * x[j]
    dual = quad = lin = 0.0
    for j in range(n):
        s = 0.0
        for p in range(Ap[j], Ap[j + 1]):
            s += Ax[p] * yp[Ai[p]]
        dual = _worse(dual, (Pxv[j] + q[j]) + s)
        quad += x[j] * Pxv[j]
        lin += q[j] * x[j]
    return primal, dual, abs(quad + lin + support)


@kernel(cache=True)
def inf_norms(indptr, indices, data, rows):
    """(row inf-norms, column inf-norms) of the CSC matrix (indptr, indices, data) with ``rows`` rows, in one pass
    (the values ``np.maximum.reduceat`` of ``abs`` gives over the rows and the columns: a max is exact)."""
    n = indptr.shape[0] - 1
    row = np.zeros(rows)
    col = np.zeros(n)
    for j in range(n):
        c = 0.0
        for p in range(indptr[j], indptr[j + 1]):
            a = abs(data[p])
            if a > c:
                c = a
            if a > row[indices[p]]:
                row[indices[p]] = a
        col[j] = c
    return row, col
