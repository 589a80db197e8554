"""Sparse direct solves for ADMM x-steps, with one cached factorisation per rho.

An ADMM x-step solves ``A(rho) u = rhs`` with a sparse symmetric positive
definite ``A(rho) = K + rho * B^T M B``.  rho changes rarely and often comes
back to an earlier value, so :class:`CachedFactorization` keeps the
factorisations of the most recently used rho values.

Backends (all exact, direct solvers; the optional ones are imported lazily):

* ``"superlu"``: ``scipy.sparse.linalg.splu`` (always available),
* ``"ngsolve"``: NGSolve's ``sparsecholesky`` (an LDL^T of the lower triangle),
* ``"qdldl"``:   the LDL^T factorisation from OSQP (``pip install qdldl``),
* ``"cholmod"``: CHOLMOD via ``sksparse.cholmod`` (needs SuiteSparse headers),
* ``"pardiso"``: MKL PARDISO via ``pypardiso`` (large MKL wheel).
"""
import functools
import importlib.util
import math
import os
import time
import weakref
from collections import OrderedDict
from typing import Callable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

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
    solver = qdldl.Solver(sp.triu(A, format="csc"))

    def solve(b):
        return solver.solve(b)
    solve.ldl = solver.factors          # (L, D, p) with A = P (I + L) D (I + L)' P': for compiled solves
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


def factorize(matrix, backend: str = "auto") -> Callable[[np.ndarray], np.ndarray]:
    """Factorise a sparse SPD matrix once; return ``solve(rhs)``.

    ``rhs`` may be 1-D of length n or 2-D of shape (n, k); the result has the
    same shape.  Raises ValueError for an unknown backend or a non-square
    matrix and numpy.linalg.LinAlgError if the matrix is singular or cannot be
    factorised (the singularity may only show in the first solve).
    """
    name = _resolve(backend)
    A = sp.csc_matrix(matrix, dtype=np.float64)
    if A.ndim != 2 or A.shape[0] != A.shape[1]:
        raise ValueError(f"matrix must be square, got shape {A.shape}")
    n = A.shape[0]
    A.sum_duplicates()
    A.sort_indices()
    try:
        solve1 = globals()[f"_factor_{name}"](A)
    except Exception as err:  # backends raise RuntimeError, their own errors, ...
        raise np.linalg.LinAlgError(
            f"backend {name!r} could not factorise the {n}x{n} matrix "
            f"(singular or not positive definite?): {err}") from err

    def solve(rhs: np.ndarray) -> np.ndarray:
        """Solve matrix @ x = rhs for a 1-D (n,) or 2-D (n, k) rhs."""
        b = np.asarray(rhs, dtype=np.float64)
        if b.ndim not in (1, 2) or b.shape[0] != n:
            raise ValueError(f"rhs must have shape ({n},) or ({n}, k), got {b.shape}")
        if not np.isfinite(b).all():
            raise ValueError("rhs must be finite (it contains nan or inf)")
        try:
            x = solve1(b) if b.ndim == 1 else np.column_stack([solve1(c) for c in b.T])
        except Exception as err:
            raise np.linalg.LinAlgError(f"backend {name!r} failed to solve: {err}") from err
        x = np.asarray(x).reshape(b.shape)
        if not np.isfinite(x).all():
            raise np.linalg.LinAlgError(
                f"backend {name!r} returned a non-finite solution: the matrix is singular")
        return x
    solve.ldl = getattr(solve1, "ldl", None)
    return solve


class CachedFactorization:
    """Cache of sparse factorisations of matrix(rho), one per rho value.

    ``matrix(rho)`` returns the sparse SPD matrix for a penalty ``rho``; it is
    called and factorised the first time a rho value is seen.  Entries are
    keyed on ``float(rho)`` exactly; when more than ``max_cached`` values are
    held, the least recently used one is dropped.

    Attributes: ``factorizations`` and ``solves`` count the work done,
    ``factor_time`` and ``solve_time`` the seconds spent in it, ``backend`` is
    the resolved backend name.
    """

    def __init__(self, matrix: Callable[[float], "sp.spmatrix"], *, backend: str = "auto",
                 max_cached: int = 32):
        if not callable(matrix):
            raise TypeError("matrix must be a callable rho -> sparse matrix")
        if isinstance(max_cached, bool) or not isinstance(max_cached, int) or max_cached < 1:
            raise ValueError(f"max_cached must be an integer >= 1, got {max_cached!r}")
        self.matrix = matrix
        self.backend = _resolve(backend)
        self.max_cached = max_cached
        self.factorizations = 0
        self.solves = 0
        self.factor_time = 0.0
        self.solve_time = 0.0
        self._cache: OrderedDict[float, Callable] = OrderedDict()

    def __len__(self) -> int:
        """Number of factorisations currently held."""
        return len(self._cache)

    def __contains__(self, rho) -> bool:
        """Whether a factorisation for this rho is currently held."""
        return float(rho) in self._cache

    def _factor(self, rho: float):
        """The cached solve for ``rho``, factorising matrix(rho) first if it is not cached."""
        key = float(rho)
        if not (math.isfinite(key) and key > 0):
            raise ValueError(f"rho must be a finite number > 0, got {rho!r}")
        if key in self._cache:
            self._cache.move_to_end(key)
        else:
            start = time.perf_counter()
            self._cache[key] = factorize(self.matrix(key), self.backend)
            self.factor_time += time.perf_counter() - start
            self.factorizations += 1
            if len(self._cache) > self.max_cached:
                self._cache.popitem(last=False)
        return self._cache[key]

    def solve(self, rho: float, rhs: np.ndarray) -> np.ndarray:
        """Solve ``matrix(rho) @ x = rhs``, factorising matrix(rho) if not cached."""
        solve = self._factor(rho)
        start = time.perf_counter()
        x = solve(rhs)
        self.solve_time += time.perf_counter() - start
        self.solves += 1
        return x

    def ldl(self, rho: float):
        """The LDL' factors of matrix(rho) as arrays (Lp, Li, Lx, Dinv, perm), factorising if not cached;
        None unless the backend is qdldl.  ``admmkit.compiled.ldl_solve`` solves with them as qdldl does
        (the same operations, so the same bits); they are read from the factor once per rho."""
        solve = self._factor(rho)
        if solve.ldl is None:
            return None
        if not hasattr(solve, "ldl_arrays"):
            L, d, p = solve.ldl()
            L = sp.csc_matrix(L)
            solve.ldl_arrays = (L.indptr.astype(np.int64), L.indices.astype(np.int64), L.data.astype(np.float64),
                                1.0 / np.asarray(d, dtype=np.float64), np.asarray(p, dtype=np.int64))
        return solve.ldl_arrays
