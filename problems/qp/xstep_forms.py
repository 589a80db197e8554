"""The two forms of the QP's x-step and how "auto" picks one (the module docstring of
:mod:`admmkit.problems.qp.problem` derives them): the reduced SPD matrix P + sigma I + rho A'MA,
or OSQP's quasi-definite KKT matrix when A'A could be dense."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from admmkit.kernels import compiled_now
from admmkit.linalg.linsolve import CachedFactorization, available_backends
from admmkit.loop.segments import AVAILABLE as NUMBA      # numba installed (asked once, without importing it)

from .csc import csc_of
from .rows import FREE_ROW_PENALTY
from .segment import kkt_x_step
from .sparse_kernels import kkt_arrays

XSTEPS = ("auto", "reduced", "kkt")
#: "auto" uses the KKT form when A'A could have more entries than this (bound: nnz(P) + sum_i nnz(row_i of A)^2)
REDUCED_MAX_NNZ = 2e7
#: sparse solvers that factorise the indefinite KKT matrix (CHOLMOD's L L' and PARDISO's SPD mode cannot)
KKT_BACKENDS = ("qdldl", "superlu")


def reduced_nnz_bound(P: sp.spmatrix, A: sp.spmatrix) -> float:
    """An upper bound on the entries of P + rho A'A: nnz(P) + sum over rows of A of nnz(row)^2."""
    rows = np.diff(sp.csr_matrix(A).indptr).astype(float)
    return float(sp.csc_matrix(P).nnz + (rows ** 2).sum())


def _kkt_backend(backend: str) -> str:
    """The solver for the KKT form: qdldl if installed, else SuperLU, unless one of them is asked for."""
    if backend == "auto":
        return next(b for b in KKT_BACKENDS if b in available_backends())
    if backend not in KKT_BACKENDS:
        raise ValueError(f"backend for xstep 'kkt' must be 'auto' or one of {', '.join(KKT_BACKENDS)} "
                         f"(the KKT matrix is indefinite), got {backend!r}")
    return backend


def x_step_backend(backend: str, xstep: str) -> str:
    """The backend name checked for the form (a clear ValueError now, not at the first solve)."""
    if xstep == "kkt":
        return _kkt_backend(backend)
    if backend != "auto" and backend not in available_backends():
        raise ValueError(f"backend must be 'auto' or one of the installed sparse solvers "
                         f"{', '.join(available_backends())}, got {backend!r}")
    return backend


def x_step_solver(qp, backend: str):
    """The x-step matrix of ``qp`` (its scaled data, its ``xstep`` form) for any rho, factorised once per rho.

    reduced: P + sigma I + rho A'MA, with a free row's term at FREE_ROW_PENALTY instead (Q5);
    kkt: [[P + sigma I, A'], [A, -R^-1]] with R = ``qp.penalty(rho)``; with qdldl and compiled code, held as
    arrays that a kernel refactorises (:class:`admmkit.problems.qp.kkt_factor.KKTFactor`, ``kkt_factor.ENABLED``),
    else a ``CachedFactorization``.
    """
    if qp.xstep == "reduced":
        base = (qp.Ps + qp.sigma * sp.identity(qp.n, format="csc")).tocsc()
        qp._reduced_gram = weighted_gram(qp)
        if qp._free.size:
            Af = qp.As[qp._free]
            base = (base + FREE_ROW_PENALTY * (Af.T @ Af)).tocsc()
        # A'MA read at each factorisation: a new row weighting (QP.update_row_weights) makes it anew
        return CachedFactorization(lambda rho: (base + rho * qp._reduced_gram).tocsc(), backend=backend)
    kkt_backend = _kkt_backend(backend)
    # the KKT matrix is assembled once, with a placeholder on the -R^-1 diagonal; a new rho writes that
    # diagonal only (OSQP's update_kkt_rho_vec).  qdldl reads the upper triangle; given only that, its solves
    # are several times faster (its ordering then sees the symmetric pattern once): 51 us against 302 us on
    # PRIMAL4's KKT matrix
    K0, slots = _kkt_pattern(qp, upper=kkt_backend == "qdldl")

    def matrix(rho):            # K0 itself, its -R^-1 diagonal rewritten: every backend copies what it factorises
        K0.data[slots] = -qp.inverse_penalty(rho)        # -(1 / R) is -1 / R bit for bit; R^-1 held for the x-steps
        return K0
    if kkt_backend == "qdldl" and NUMBA and compiled_now():
        from . import kkt_factor
        if kkt_factor.ENABLED:          # qdldl's factor held as arrays, refactorised by a kernel (the same bits)
            return kkt_factor.KKTFactor(matrix)
    # in place: a new rho refactorises the one factorisation numerically (OSQP's update_rho), without a new ordering
    return CachedFactorization(matrix, backend=kkt_backend, in_place=True)


def weighted_gram(qp) -> sp.csc_matrix:
    """A'MA of the reduced x-step (the scaled A, M = diag(w) with the free rows' weights 0: their term is in the
    constant part, Q5)."""
    if qp.w is None:
        return (qp.Ats @ qp.As).tocsc()
    w = qp.w.copy()
    w[qp._free] = 0.0
    return (qp.Ats @ sp.diags(w) @ qp.As).tocsc()


def x_step_solution(qp, xp, z, lam, rho: float) -> tuple[np.ndarray, np.ndarray | None]:
    """(x~, z~) of (Q1) with the free rows' penalty (Q5), from x^k = ``xp`` (OSQP's relaxed x), z^k and lam^k, in the
    QP's form; z~ = A x~ read off the KKT solve (Q6), None in the reduced form.

    kkt: [P + sigma I, A'; A, -R^-1] [x; v] = b = [sigma x^k - q; z - R^-1 M lam] with R = ``qp.penalty(rho)``,
    solved in one compiled call on qdldl's factors where it can (the same bits as qdldl's solve); its second
    row gives A x~ = b_z + R^-1 v, OSQP's z~ (no product with A);
    reduced: (P + sigma I + rho A'MA) x = sigma x^k - q + A'M(rho z - lam).
    """
    if qp.xstep == "kkt":
        n = qp.n
        solved = kkt_x_step(qp, xp, z, lam, rho)
        if solved is not None:
            sol, rhs = solved
        else:
            rhs = np.empty(n + qp.m)
            np.subtract(qp.sigma * xp, qp.qs, out=rhs[:n])
            np.subtract(z, lam / rho, out=rhs[n:])
            if qp._free.size:
                f = qp._free
                rhs[n + f] = z[f] - qp._w_free_over_penalty * lam[f]
            sol = qp._solver.solve(rho, rhs)
        return sol[:n], rhs[n:] + qp.inverse_penalty(rho) * sol[n:]                 # (Q6)
    v = rho * z - lam
    v = v if qp.w is None else qp.w * v
    if qp._free.size:
        f = qp._free
        v[f] = FREE_ROW_PENALTY * z[f] - qp.w[f] * lam[f]
    return qp._solver.solve(rho, qp.sigma * xp - qp.qs + qp.Ats @ v), None


def _kkt_pattern(qp, upper: bool):
    """The KKT matrix [[P + sigma I, A'], [A, 1]] (its upper triangle if ``upper``) in CSC, and the positions of
    its last m diagonal entries (the -R^-1 slots).

    The same entries as scipy's ``bmat`` of the blocks plus ``diags``: P_ii + sigma is the one sum, and exact
    zeros are dropped as scipy's sums drop them.  One compiled pass over the arrays
    (``sparse_kernels.kkt_arrays``) where numba is installed, else one COO -> CSC pass.
    """
    n, m = qp.n, qp.m
    if NUMBA:
        P, A = qp.Ps, qp.As
        indptr, indices, data, slots = kkt_arrays(n, m, P.indptr, P.indices, P.data, qp.sigma,
                                                  A.indptr, A.indices, A.data, upper)
        return csc_of(data, indices, indptr, (n + m, n + m)), slots      # canonical: no constructor checks
    P, A = qp.Ps.tocoo(), qp.As.tocoo()
    keep = P.row <= P.col if upper else slice(None)
    diag = np.arange(n)
    rows = [P.row[keep], diag, A.col, n + np.arange(m)]
    cols = [P.col[keep], diag, n + A.row, n + np.arange(m)]
    data = [P.data[keep], np.full(n, qp.sigma), A.data, np.ones(m)]
    if not upper:                                   # the lower block A too
        rows.append(n + A.row)
        cols.append(A.col)
        data.append(A.data)
    size = n + m
    K0 = sp.csc_matrix((np.concatenate(data), (np.concatenate(rows), np.concatenate(cols))), shape=(size, size))
    K0.sum_duplicates()
    K0.eliminate_zeros()
    K0.sort_indices()
    col_of = np.repeat(np.arange(size), np.diff(K0.indptr))
    return K0, np.flatnonzero((K0.indices == col_of) & (col_of >= n))
