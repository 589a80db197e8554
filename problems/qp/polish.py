"""Solution polishing: OSQP's active-set refinement (Stellato et al. 2020, section 4; osqp ``src/polish.c``).

From the ADMM iterate (x, z, y) of the problem the loop iterates on (scaled
when the QP is), guess the active constraints

    lower active:  z_i - l_i < -y_i,        upper active:  u_i - z_i < y_i   (the others inactive, y_i = 0),

and solve the equality-constrained QP on them, regularised by delta,

    [P + delta I   A_act'  ] [x    ]   [ -q    ]
    [A_act        -delta I ] [y_act] = [ b_act ],                                   (P1)

b_act the active bounds, followed by ``refine`` steps of iterative
refinement against the unregularised matrix [[P, A_act'], [A_act, 0]].
The regularised matrix is quasi-definite, so it has an LDL' factorisation
in any symmetric order: qdldl's, with its AMD order, as OSQP's polish
(``_reduced_solver``; SuperLU with a symmetric minimum-degree order and no
pivoting where qdldl is not installed).  SuperLU's defaults (COLAMD,
partial pivoting) filled the factor 3-8x and took 3-8x longer on
QSCSD1 or CVXQP3_M: a polishing try during the run (admmkit's preset) cost
as much as 500 iterations.
Then z = clip(A x, l, u).  The polished (x, y) is taken only when the neutral
criteria (:func:`admmkit.problems.qp.residuals.neutral_residuals`: primal, dual, gap)
are better at it than at the unpolished point: polishing never replaces a
better answer.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .problem import QP
from .residuals import neutral_residuals


#: factorise (P1) by the QP's kernels where the process runs its compiled code (False: qdldl's wrapper always)
COMPILED_FACTOR = True


def _worst(res: dict) -> float:
    return max(res["primal"], res["dual"], res["gap"])


def _reduced_solver(upper: sp.csc_matrix, order: np.ndarray | None = None):
    """``solve(b)`` with K^-1, K the regularised (quasi-definite) matrix of (P1) given by its upper triangle
    ``upper`` (CSC): qdldl's LDL' when installed, else SuperLU in symmetric mode (minimum degree on K + K', no
    pivoting).  Where this process runs the QP's compiled
    code already, qdldl's factor is made by the QP's own kernels (:class:`admmkit.problems.qp.kkt_factor.KKTFactor`:
    AMD's compiled port and qdldl's phases, the same factor and solve bit for bit, 1.4-3.5x faster to order than
    qdldl's wheel, which builds AMD without optimisation), in ``order`` where one is given (else AMD's)."""
    try:
        import qdldl
    except ImportError:
        K = (upper + sp.triu(upper, k=1).T).tocsc()
        lu = spla.splu(K, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        return lu.solve
    from .segment import kernels_loaded
    if COMPILED_FACTOR and kernels_loaded():
        from .kkt_factor import KKTFactor
        factor = KKTFactor(lambda rho: upper, order)
        factor.prepare(1.0)
        return lambda b: factor.solve(1.0, b)
    return qdldl.Solver(upper, upper=True).solve


class _Compressed(NamedTuple):
    """A compressed sparse matrix's three arrays (CSC or CSR), what :func:`reduced_upper` reads of P and A."""
    indptr: np.ndarray
    indices: np.ndarray
    data: np.ndarray


def strict_upper(P) -> _Compressed:
    """The entries of the CSC matrix P strictly above its diagonal, column by column in P's order: the arrays of
    scipy's ``triu(P, k=1, format="csc")`` (for P with sorted indices), without its COO round trip (HS118: about
    20 against 380 us)."""
    n = P.shape[1]
    columns = np.repeat(np.arange(n), np.diff(P.indptr))
    keep = P.indices < columns
    indptr = np.zeros(n + 1, dtype=P.indptr.dtype)
    np.cumsum(np.bincount(columns[keep], minlength=n), out=indptr[1:])
    return _Compressed(indptr, P.indices[keep], P.data[keep])


def rows_of(A) -> _Compressed:
    """The CSC matrix A by rows (CSR arrays, each row's entries in column order), as scipy's ``csr_matrix(A)``
    with sorted indices stores it, by a stable sort of the row indices."""
    m = A.shape[0]
    order = np.argsort(A.indices, kind="stable")
    columns = np.repeat(np.arange(A.shape[1]), np.diff(A.indptr))
    indptr = np.zeros(m + 1, dtype=A.indptr.dtype)
    np.cumsum(np.bincount(A.indices, minlength=m), out=indptr[1:])
    return _Compressed(indptr, columns[order].astype(A.indices.dtype), A.data[order])


def _parts(qp: QP) -> tuple:
    """(P's strict upper triangle, P's diagonal, A's rows), the arrays of the scaled QP every try reads, made once
    per QP (scipy's ``triu`` and ``csr_matrix`` where P's or A's indices are not sorted)."""
    parts = qp.__dict__.get("_polish_parts")
    if parts is None or parts[0] is not qp.Ps:
        P, A = qp.Ps, qp.As
        if P.has_sorted_indices and A.has_sorted_indices and P.format == "csc" and A.format == "csc":
            upper, rows = strict_upper(P), rows_of(A)
        else:
            upper = sp.triu(P, k=1, format="csc")
            upper.sort_indices()
            rows = sp.csr_matrix(A)
            rows.sort_indices()
        parts = (P, upper, P.diagonal(), rows)
        qp.__dict__["_polish_parts"] = parts
    return parts[1:]


def reduced_upper(qp: QP, act: np.ndarray, delta: float) -> sp.csc_matrix:
    """The upper triangle (CSC, canonical) of (P1)'s regularised matrix [[P + delta I, A_act'], [A_act, -delta I]],
    built from arrays: column j < n holds P's entries above the diagonal, then P_jj + delta; column n + i holds row
    act[i] of A, then -delta (the entries and order of ``triu(bmat(...) + diags(...))``, without scipy's
    constructions, which cost a small QP's try about 2 ms)."""
    upper, diagonal, rows = _parts(qp)
    n, k = qp.n, act.size
    starts, stops = rows.indptr[act], rows.indptr[act + 1]
    lengths = stops - starts
    counts = np.r_[np.diff(upper.indptr), lengths] + 1
    indptr = np.zeros(n + k + 1, dtype=np.int64)
    np.cumsum(counts, out=indptr[1:])
    nnz = int(indptr[-1])
    indices, data = np.empty(nnz, dtype=np.int64), np.empty(nnz)
    at = np.arange(len(upper.data)) + np.repeat(np.arange(n), np.diff(upper.indptr))   # one diagonal before each column
    indices[at], data[at] = upper.indices, upper.data
    indices[indptr[1:n + 1] - 1], data[indptr[1:n + 1] - 1] = np.arange(n), diagonal + delta
    total = int(lengths.sum())
    take = np.repeat(starts - np.r_[0, np.cumsum(lengths)[:-1]], lengths) + np.arange(total)
    at = indptr[n] + np.arange(total) + np.repeat(np.arange(k), lengths)
    indices[at], data[at] = rows.indices[take], rows.data[take]
    indices[indptr[n + 1:] - 1], data[indptr[n + 1:] - 1] = n + np.arange(k), -delta
    return sp.csc_matrix((data, indices, indptr), shape=(n + k, n + k))


def induced_order(order: np.ndarray, n: int, act: np.ndarray, m: int) -> np.ndarray:
    """The order of (P1)'s unknowns (x, then the rows ``act`` of A) that a fill-reducing order of the whole KKT
    matrix [[P, A'], [A, .]] (``order``, of its n + m unknowns) induces: its entries kept where they are x or an
    active row, renumbered.  Eliminating a subset in the order induced by a larger matrix fills no more than that
    matrix's factor does on the subset, so a try factorises at most what a change of rho refactorises."""
    order = np.asarray(order, dtype=np.int64)
    new = np.full(n + m, -1, dtype=np.int64)
    new[:n] = np.arange(n)
    new[n + act] = n + np.arange(act.size)
    mapped = new[order]
    return mapped[mapped >= 0]


def polish(qp: QP, xb: np.ndarray, zb: np.ndarray, yb: np.ndarray, delta: float = 1e-6, refine: int = 3,
           order: np.ndarray | None = None):
    """Polish the loop's iterate (xb, zb, yb = M lam); return (x, y, info) in the user's problem or (None, None, info).

    ``order``: a fill-reducing order of the x-step's KKT matrix (n + m unknowns, x first) whose induced order
    (:func:`induced_order`) factorises (P1) where the QP's kernels do; None: AMD's order of (P1), as OSQP's polish.

    ``info``: ``status`` "succeeded" (the polished point is better under the neutral criteria) or "failed",
    the active-set sizes, and the neutral residuals before and after.
    """
    P, q, A, l, u = qp.Ps, qp.qs, qp.As, qp.ls, qp.us
    low = zb - l < -yb
    upp = ~low & (u - zb < yb)
    act = np.flatnonzero(low | upp)
    b_act = np.where(low[act], l[act], u[act])
    n, k = qp.n, act.size
    rhs = np.r_[-q, b_act]
    info = {"status": "failed", "lower_active": int(low.sum()), "upper_active": int(upp.sum())}

    def K0_times(v):                                              # [[P, A_act'], [A_act, 0]] v
        y = np.zeros(qp.m)
        y[act] = v[n:]
        return np.r_[P @ v[:n] + A.T @ y, (A @ v[:n])[act]]
    try:
        sub = None if order is None or len(order) != n + qp.m else induced_order(order, n, act, qp.m)
        solve = _reduced_solver(reduced_upper(qp, act, delta), sub)
        sol = solve(rhs)
        for _ in range(refine):                                   # iterative refinement against K0
            sol = sol + solve(rhs - K0_times(sol))
    except (RuntimeError, ValueError) as err:
        info["reason"] = f"the reduced KKT system could not be solved: {err}"
        return None, None, info
    if not np.all(np.isfinite(sol)):
        info["reason"] = "the reduced KKT solve gave non-finite values"
        return None, None, info
    y_full = np.zeros(qp.m)
    y_full[act] = sol[n:]
    x_pol = qp.finalize(sol[:n])
    y_pol = qp.scaling.unscale_y(y_full) if qp.scaled else y_full
    x0, _, y0 = qp.unscaled(xb, zb, yb if qp.w is None else yb / qp.w)
    before, after = neutral_residuals(qp, x0, y0), neutral_residuals(qp, x_pol, y_pol)
    info.update(before=before, after=after)
    if _worst(after) < _worst(before):
        info["status"] = "succeeded"
        return x_pol, y_pol, info
    info["reason"] = f"not better: worst neutral residual {_worst(after):.3g} polished vs {_worst(before):.3g}"
    return None, None, info
