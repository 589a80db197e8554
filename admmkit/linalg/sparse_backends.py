"""The sparse direct solvers behind :mod:`admmkit.linalg.linsolve`, and which one ``backend="auto"`` takes.

Each ``_factor_<name>(A)`` takes a CSC float64 SPD (or, for qdldl and SuperLU,
quasi-definite) matrix and returns ``solve(b)`` for a 1-D right-hand side;
qdldl's also carries its factors and a numeric refactorisation
(``solve.ldl``, ``solve.refactor``).
"""
import functools
import importlib.util
import os
import weakref

import numpy as np
import scipy.sparse as sp

# Order used by backend="auto": the first one installed wins.  Measured by
# benchmarks/contact/linsolve_backends.py (docs/results/linsolve.md; 2-core Xeon) on
# plane-strain elasticity, 1 thread, seconds factor / solve:
#
#     n        cholmod      superlu      qdldl        ngsolve      pardiso
#     1e3   0.0013/3e-5  0.0020/7e-5  0.0015/4e-5  0.0045/1.4e-4 0.0026/1.7e-4
#     1e4   0.039/8e-4   0.030/1.1e-3 0.029/8.8e-4 0.048/1.8e-3  0.023/2.0e-3
#     1e5   0.55/0.011   0.68/0.021   1.3/0.028    0.74/0.037    0.35/0.026
#     1e6   10/0.24      21/0.29      50/0.38      14/0.74       5.5/0.49
#
# - cholmod is the fastest solver whenever it is installed (it rarely is: pip
#   needs Debian's libsuitesparse-dev, and scikit-sparse 0.5 needs SuiteSparse
#   7; 0.4.16 builds against Debian 12's SuiteSparse 5).
# - An ADMM run does many solves per factorisation, so solves weigh most.
#   superlu (MMD on A^T+A, symmetric mode) is always installed and has the
#   best solves of the rest from 1e5 on; qdldl solves a little faster below
#   1e4 (tens of microseconds) but factors 2x slower from 1e5 on.
# - ngsolve is slower than superlu at every size and its own thread pool adds
#   ~25 ms per factorisation when the other core is busy.
# - pardiso (MKL) factors fastest from 1e4 but solves slower than superlu,
#   and its OpenMP threads slow small solves badly on a loaded machine.
AUTO_ORDER = ["cholmod", "superlu", "qdldl", "ngsolve", "pardiso"]

_MODULES = {"superlu": "scipy", "ngsolve": "ngsolve", "qdldl": "qdldl",
            "cholmod": "sksparse.cholmod", "pardiso": "pypardiso"}


@functools.lru_cache(maxsize=None)
def _importable(module: str) -> bool:
    """Whether ``module`` can be imported (asked once per process: a search of sys.path costs ~20 us)."""
    try:
        return importlib.util.find_spec(module) is not None
    except ImportError:  # a parent package is missing
        return False


def available_backends() -> list[str]:
    """Names of the backends importable on this machine, fastest first."""
    return [name for name in AUTO_ORDER if _importable(_MODULES[name])]


def _resolve(backend: str) -> str:
    """Map ``"auto"`` to the fastest installed backend and check the name."""
    available = available_backends()
    if backend == "auto":
        return available[0]
    if backend not in _MODULES:
        raise ValueError(f"backend must be 'auto' or one of {sorted(_MODULES)}, got {backend!r}; "
                         f"available here: {available}")
    if backend not in available:
        raise ValueError(f"backend {backend!r} is not installed here; available: {available}")
    return backend


# Each _factor_<name>(A) takes a CSC float64 SPD matrix and returns solve(b)
# for a 1-D right-hand side b.

def _factor_superlu(A):
    import scipy.sparse.linalg as spla      # here, not at the import: it imports scipy.linalg (about 0.1-0.25 s)
    lu = spla.splu(A, permc_spec="MMD_AT_PLUS_A", options=dict(SymmetricMode=True))
    return lu.solve


def _factor_ngsolve(A):
    from ngsolve.la import SparseMatrixd
    L = sp.tril(A).tocoo()  # sparsecholesky reads the lower triangle only
    n = A.shape[0]
    mat = SparseMatrixd.CreateFromCOO(L.row, L.col, L.data, n, n)
    inverse = mat.Inverse(inverse="sparsecholesky")
    r, x = mat.CreateColVector(), mat.CreateColVector()

    def solve(b):
        r.FV().NumPy()[:] = b
        x.data = inverse * r
        return x.FV().NumPy().copy()
    return solve


def _factor_qdldl(A):
    import qdldl
    # qdldl reads the upper triangle; handing it only that (not the full matrix) made its solves 6x faster
    # on a QP's KKT matrix (PRIMAL4: 51 us against 302 us), same factor
    U = _upper(A)
    return _qdldl_solve(qdldl.Solver(U, upper=True), U.indices if U is A else None)


def _upper(A):
    """The upper triangle of CSC ``A`` (``A`` itself when it has no entry below the diagonal: no copy)."""
    below = A.indices > np.repeat(np.arange(A.shape[1], dtype=A.indices.dtype), np.diff(A.indptr))
    return sp.triu(A, format="csc") if below.any() else A


def _qdldl_solve(solver, pattern=None):
    """``solve(b)`` with qdldl's ``solver``, its factors (``solve.ldl``) and ``solve.refactor(A)``: new values on
    the same pattern, qdldl's numeric factorisation only (the ordering kept; the same factor as a new one).
    ``pattern``: the row indices of a matrix known to be upper triangular (no test for it again)."""
    def solve(b):
        return solver.solve(b)

    def refactor(A):
        solver.update(A if A.indices is pattern else _upper(A), upper=True)
        return _qdldl_solve(solver, pattern)
    solve.ldl = solver.factors          # (L, D, p) with A = P (I + L) D (I + L)' P': for compiled solves
    solve.refactor = refactor
    return solve


def _factor_cholmod(A):
    from sksparse import cholmod
    return cholmod.cholesky(A)


def _factor_pardiso(A):
    import pypardiso
    U = sp.triu(A, format="csr")  # mtype 2 (real SPD) reads the upper triangle
    U.sort_indices()
    solver = pypardiso.PyPardisoSolver(mtype=2)
    # Each new solver searches the file system for mkl_rt (~0.25 s); remember it.
    os.environ.setdefault("PYPARDISO_MKL_RT", solver.libmkl._name)
    solver.factorize(U)

    def solve(b):
        return solver.solve(U, b)
    weakref.finalize(solve, solver.free_memory, True)  # release MKL's memory
    return solve
