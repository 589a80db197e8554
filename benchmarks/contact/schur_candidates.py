"""Ways to build the contact-boundary Schur complement S = K_cc - K_ci K_ii^{-1} K_ic, timed.

The candidates of ``admmkit bench contact-schur`` (issue 25, part 3).  Each
function takes K (CSC), the inner and the contact dof indices and a block size,
and returns a dict with ``S`` (dense, None when not computed in full), the
seconds of each step (``steps``) and their sum (``setup``):

* :func:`ldl_contact_last`: :class:`admmkit.problems.contact.solvers.schur.BoundarySchur`
  with ``ldl`` given the dofs' coordinates (nested dissection of the inner
  dofs, :mod:`admmkit.linalg.ldl` in that order with the contact dofs last, S read
  off the last n_c columns of L);
* :func:`superlu_contact_last`: the same with SuperLU (LU without pivoting,
  S read off the trailing block of a copy of U);
* :func:`superlu_minimum_degree`: the same with SuperLU's minimum degree
  ordering of K_ii instead (the path before nested dissection);
* :func:`superlu_block_solves`: SuperLU LU of K_ii alone, then
  K_ii^{-1} K_ic by multi-right-hand-side solves of ``block`` columns;
* :func:`ngsolve_block_solves`: the same with NGSolve's sparse Cholesky and
  MultiVector solves;
* :func:`qdldl_factor`: qdldl's LDL' of K in its own AMD order (the wrapper
  takes no ordering, so the contact dofs cannot be put last): the factorisation
  alone, a lower bound;
* :func:`pardiso_schur` (when pypardiso is importable): MKL PARDISO's own
  Schur complement (iparm[35] = 1, the contact dofs marked in perm).

``REFERENCES`` are the pip-only factor + solve of K the study divides by:
SuperLU's (``admmkit bench contact``'s reference), qdldl's (its own AMD order)
and :mod:`admmkit.linalg.ldl`'s in nested dissection order of all dofs.

Block-solve candidates time the first ``max_blocks`` blocks and extrapolate to
all n_c columns (``extrapolated`` is then True); S is compared with the
current path's on the columns they computed.
"""
from __future__ import annotations

import ctypes
import importlib.util
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from admmkit.linalg.ldl import ldl_factor
from admmkit.linalg.linsolve import factorize

from admmkit.problems.contact.solvers.dissection import nested_dissection
from admmkit.problems.contact.solvers.schur import BoundarySchur


def _timed(steps: dict, name: str, fn):
    t0 = time.perf_counter()
    out = fn()
    steps[name] = time.perf_counter() - t0
    return out


def _result(S, steps, extrapolated=False, **extra) -> dict:
    return dict(S=S, steps=steps, setup=sum(steps.values()), extrapolated=extrapolated, **extra)


def superlu_contact_last(K, B, inner, contact, block=64, max_blocks=None, coordinates=None, backend="superlu"):
    """:class:`admmkit.problems.contact.solvers.schur.BoundarySchur` with SuperLU (or ``backend``), inner dofs in
    nested dissection order by ``coordinates`` (minimum degree when None); returns the dict described above."""
    t0 = time.perf_counter()
    schur = BoundarySchur(K, B, backend=backend, coordinates=coordinates)
    steps = dict(schur.timings)
    steps["rest"] = time.perf_counter() - t0 - sum(steps.values())
    return _result(schur.S, steps)


def ldl_contact_last(K, B, inner, contact, block=64, max_blocks=None, coordinates=None) -> dict:
    """:class:`admmkit.problems.contact.solvers.schur.BoundarySchur` with ``ldl``, inner dofs in nested
    dissection order, contact dofs last."""
    return superlu_contact_last(K, B, inner, contact, block, max_blocks, coordinates, backend="ldl")


def superlu_minimum_degree(K, B, inner, contact, block=64, max_blocks=None) -> dict:
    """The path before nested dissection: SuperLU's minimum degree order of K_ii, contact dofs last."""
    return superlu_contact_last(K, B, inner, contact, block, max_blocks, coordinates=None)


def _block_solves(solve, K, inner, contact, block, max_blocks, steps):
    """S = K_cc - K_ci X with X = K_ii^{-1} K_ic by blocks of columns; returns S or its first columns."""
    K_ic = sp.csc_matrix(K[inner][:, contact])
    K_cc = K[contact][:, contact].toarray()
    m = contact.size
    done = m if max_blocks is None else min(m, block * max_blocks)
    t0 = time.perf_counter()
    cols = []
    for j in range(0, done, block):
        X = solve(K_ic[:, j:j + block].toarray())
        cols.append(K_cc[:, j:j + block] - K_ic.T @ X)
    elapsed = time.perf_counter() - t0
    steps["block solves"] = elapsed * m / done
    return np.hstack(cols), done < m


def superlu_block_solves(K, B, inner, contact, block=64, max_blocks=2) -> dict:
    """SuperLU LU of K_ii (minimum degree, symmetric mode), then blocked multi-RHS solves."""
    steps: dict[str, float] = {}
    K_ii = _timed(steps, "slice", lambda: sp.csc_matrix(K[inner][:, inner]))
    lu = _timed(steps, "factorisation", lambda: spla.splu(K_ii, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                                         options=dict(SymmetricMode=True)))
    S, extrapolated = _block_solves(lu.solve, K, inner, contact, block, max_blocks, steps)
    return _result(S, steps, extrapolated)


def ngsolve_block_solves(K, B, inner, contact, block=64, max_blocks=1) -> dict:
    """NGSolve's sparse Cholesky of K_ii (freedofs = inner), then MultiVector solves."""
    import ngsolve as ng
    from ngsolve.la import MultiVector, SparseMatrixd
    steps: dict[str, float] = {}
    n = K.shape[0]

    def factor():
        L = sp.tril(K).tocoo()   # sparsecholesky reads the lower triangle
        mat = SparseMatrixd.CreateFromCOO(L.row, L.col, L.data, n, n)
        free = ng.BitArray(n)
        free.Clear()
        for i in inner:
            free.Set(int(i))
        return mat.Inverse(free, inverse="sparsecholesky")
    inverse = _timed(steps, "factorisation", factor)

    def solve(rhs_inner):
        k = rhs_inner.shape[1]
        rhs, out = MultiVector(n, k, False), MultiVector(n, k, False)
        full = np.zeros(n)
        for j in range(k):
            full[inner] = rhs_inner[:, j]
            rhs[j].FV().NumPy()[:] = full
        out[:] = inverse * rhs
        return np.column_stack([out[j].FV().NumPy()[inner] for j in range(k)])
    S, extrapolated = _block_solves(solve, K, inner, contact, block, max_blocks, steps)
    return _result(S, steps, extrapolated)


def qdldl_factor(K, B, inner, contact, block=64, max_blocks=None) -> dict:
    """qdldl's LDL' of the whole K in its own AMD order: no S (the contact dofs cannot be put last)."""
    import qdldl
    steps: dict[str, float] = {}
    _timed(steps, "factorisation", lambda: qdldl.Solver(sp.triu(K, format="csc")))
    return _result(None, steps)


def pardiso_schur(K, B, inner, contact, block=64, max_blocks=None) -> dict:
    """MKL PARDISO (real SPD, METIS ordering) computing S itself: iparm[35] = 1, perm marks the contact dofs."""
    import pypardiso
    steps: dict[str, float] = {}
    n, m = K.shape[0], contact.size
    U = _timed(steps, "upper triangle", lambda: sp.triu(K, format="csr"))
    U.sort_indices()
    solver = pypardiso.PyPardisoSolver(mtype=2)
    solver.iparm[:] = 0
    solver.iparm[0] = 1          # iparm given
    solver.iparm[1] = 2          # METIS
    solver.iparm[34] = 0         # one-based indices
    solver.iparm[35] = 1         # the Schur complement, dense, in x
    perm = np.zeros(n, dtype=np.int32)
    perm[contact] = 1
    ia, ja = U.indptr.astype(np.int32) + 1, U.indices.astype(np.int32) + 1
    x, b, err = np.zeros(max(m * m, n)), np.zeros(n), ctypes.c_int32(0)
    ip, dp = ctypes.POINTER(ctypes.c_int32), ctypes.POINTER(ctypes.c_double)
    one = ctypes.byref(ctypes.c_int32(1))

    def factor():
        solver._mkl_pardiso(solver.pt.ctypes.data_as(ctypes.POINTER(solver._pt_type[0])), one, one,
                            ctypes.byref(ctypes.c_int32(2)), ctypes.byref(ctypes.c_int32(12)),
                            ctypes.byref(ctypes.c_int32(n)), U.data.ctypes.data_as(dp), ia.ctypes.data_as(ip),
                            ja.ctypes.data_as(ip), perm.ctypes.data_as(ip), one, solver.iparm.ctypes.data_as(ip),
                            ctypes.byref(ctypes.c_int32(0)), b.ctypes.data_as(dp), x.ctypes.data_as(dp),
                            ctypes.byref(err))
    _timed(steps, "ordering + factorisation + S", factor)
    solver.free_memory(everything=True)
    if err.value != 0:
        raise RuntimeError(f"PARDISO error {err.value}")
    return _result(x[:m * m].reshape(m, m).copy(), steps)


def _ldl_nested_dissection(K, f, coordinates):
    """admmkit.linalg.ldl's factor + solve of K, all dofs in nested dissection order (no contact dofs last)."""
    order = nested_dissection(K, np.arange(K.shape[0]), coordinates)
    return ldl_factor(K, order).solve(f)


# the pip-only factor + solve of K: name -> (fn(K, f, coordinates), the module it needs)
REFERENCES = {
    "superlu": (lambda K, f, X: factorize(K, "superlu")(f), "scipy"),
    "qdldl (AMD)": (lambda K, f, X: factorize(K, "qdldl")(f), "qdldl"),
    "admmkit.linalg.ldl (nested dissection)": (_ldl_nested_dissection, "numba"),
}

CANDIDATES = {
    "ldl, contact last": (ldl_contact_last, "numba"),
    "superlu, contact last": (superlu_contact_last, "scipy"),
    "superlu, minimum degree (before)": (superlu_minimum_degree, "scipy"),
    "superlu K_ii + block solves": (superlu_block_solves, "scipy"),
    "ngsolve K_ii + block solves": (ngsolve_block_solves, "ngsolve"),
    "qdldl factor of K (no S)": (qdldl_factor, "qdldl"),
    "pardiso Schur (MKL)": (pardiso_schur, "pypardiso"),
}


def installed_candidates(table: dict | None = None) -> list[str]:
    """The candidates (or, with ``table=REFERENCES``, the references) whose library is importable here."""
    table = CANDIDATES if table is None else table
    return [name for name, (_, module) in table.items() if importlib.util.find_spec(module) is not None]
