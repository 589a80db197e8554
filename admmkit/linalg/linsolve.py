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
import math
import time
from collections import OrderedDict
from typing import Callable

import numpy as np
import scipy.sparse as sp

from .sparse_backends import AUTO_ORDER, available_backends, _resolve  # noqa: F401  (the public names here)
from . import sparse_backends


def factorize(matrix, backend: str = "auto") -> Callable[[np.ndarray], np.ndarray]:
    """Factorise a sparse SPD matrix once; return ``solve(rhs)``.

    ``rhs`` may be 1-D of length n or 2-D of shape (n, k); the result has the
    same shape.  Raises ValueError for an unknown backend or a non-square
    matrix and numpy.linalg.LinAlgError if the matrix is singular or cannot be
    factorised (the singularity may only show in the first solve).
    """
    name = _resolve(backend)
    A = _canonical(matrix)
    return _checked(_backend_factor(name, A, getattr(sparse_backends, f"_factor_{name}")), name, A)


def _canonical(matrix) -> sp.csc_matrix:
    """``matrix`` as a square float64 CSC matrix without duplicates, indices sorted (``matrix`` itself when it is
    one: a new scipy object costs ~10 us, a visible part of a small QP's whole solve)."""
    A = matrix if sp.isspmatrix_csc(matrix) and matrix.dtype == np.float64 else sp.csc_matrix(matrix, dtype=np.float64)
    if A.ndim != 2 or A.shape[0] != A.shape[1]:
        raise ValueError(f"matrix must be square, got shape {A.shape}")
    if not A.has_canonical_format:          # a copy: the caller's matrix is left as it was given
        A = A.copy()
        A.sum_duplicates()
        A.sort_indices()
    return A


def _backend_factor(name: str, A, factor):
    """``factor(A)``, any backend error as LinAlgError."""
    try:
        return factor(A)
    except Exception as err:  # backends raise RuntimeError, their own errors, ...
        raise np.linalg.LinAlgError(
            f"backend {name!r} could not factorise the {A.shape[0]}x{A.shape[0]} matrix "
            f"(singular or not positive definite?): {err}") from err


def _checked(solve1, name: str, A):
    """The backend's ``solve1`` with its input and output checked; ``solve.refactor(matrix)`` refactorises in
    place when the backend can and the pattern is ``A``'s (else None: factorise anew)."""
    n = A.shape[0]

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
    refactor = getattr(solve1, "refactor", None)

    def refactor_in_place(matrix):
        B = _canonical(matrix)
        same = B.indptr is A.indptr and B.indices is A.indices       # the same pattern arrays: nothing to compare
        if not (same or (B.shape == A.shape and np.array_equal(B.indptr, A.indptr)
                         and np.array_equal(B.indices, A.indices))):
            return None
        return _checked(_backend_factor(name, B, refactor), name, B)
    solve.refactor = None if refactor is None else refactor_in_place
    return solve


class CachedFactorization:
    """Cache of factorisations of matrix(rho), one per rho value: the one owner of a plug-in's factors.

    ``matrix(rho)`` returns the sparse SPD matrix for a penalty ``rho``; it is
    called and factorised the first time a rho value is seen.  Entries are
    keyed on ``float(rho)`` exactly; when more than ``max_cached`` values are
    held, the least recently used one is dropped.  ``in_place=True`` keeps one
    factorisation and refactorises it in place for a new rho when the backend
    can and the pattern is the same (qdldl: the numeric factorisation only, its
    ordering kept, as OSQP does on a change of rho; the same factor as a new
    one), else factorises anew.  ``factor`` replaces the backend's sparse
    factorisation by any callable matrix -> solve (a callable rhs -> x), e.g.
    a dense Cholesky factor of a small dense matrix; ``backend`` then names it.

    Attributes: ``factorizations`` and ``solves`` count the work done,
    ``factor_time`` and ``solve_time`` the seconds spent in it, ``backend`` is
    the resolved backend name.
    """

    def __init__(self, matrix: Callable[[float], "sp.spmatrix"], *, backend: str = "auto",
                 max_cached: int = 32, in_place: bool = False, factor: Callable | None = None):
        if not callable(matrix):
            raise TypeError("matrix must be a callable rho -> sparse matrix")
        if factor is not None and not callable(factor):
            raise TypeError(f"factor must be a callable matrix -> solve, got {factor!r}")
        if isinstance(max_cached, bool) or not isinstance(max_cached, int) or max_cached < 1:
            raise ValueError(f"max_cached must be an integer >= 1, got {max_cached!r}")
        self.matrix = matrix
        self.factor = factor
        self.backend = _resolve(backend) if factor is None else getattr(factor, "__name__", "custom")
        self.max_cached = 1 if in_place else max_cached
        self.in_place = bool(in_place)
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

    def held(self, rho: float):
        """The cached solve for ``rho`` (the factorisation object itself, called as ``solve(rhs)``),
        factorising matrix(rho) first if it is not cached; a plug-in that reads the factor (a compiled
        step) takes it from here."""
        key = float(rho)
        if not (math.isfinite(key) and key > 0):
            raise ValueError(f"rho must be a finite number > 0, got {rho!r}")
        if key in self._cache:
            self._cache.move_to_end(key)
        else:
            start = time.perf_counter()
            self._cache[key] = self._new_factor(key)
            self.factor_time += time.perf_counter() - start
            self.factorizations += 1
            if len(self._cache) > self.max_cached:
                self._cache.popitem(last=False)
        return self._cache[key]

    def _new_factor(self, key: float):
        """A factorisation of matrix(key): in place of the held one when ``in_place`` allows, else a new one."""
        matrix = self.matrix(key)
        if self.in_place and self._cache:
            old = self._cache[next(iter(self._cache))]
            if old.refactor is not None:
                solve = old.refactor(matrix)
                if solve is not None:
                    self._cache.clear()
                    return solve
        return factorize(matrix, self.backend) if self.factor is None else self.factor(matrix)

    def prepare(self, rho: float) -> None:
        """Factorise matrix(rho) now unless it is held (the event of a change of rho: :meth:`admmkit.Problem.update_rho`)."""
        self.held(rho)

    def refresh(self, rho: float) -> None:
        """matrix(rho) changed for the same rho (a new weighting of the rows): factorise it now (numerically in
        place of the held factorisation when ``in_place`` allows) and drop every other held one, now stale."""
        key = float(rho)
        start = time.perf_counter()
        solve = self._new_factor(key)
        self._cache.clear()
        self._cache[key] = solve
        self.factor_time += time.perf_counter() - start
        self.factorizations += 1

    def clear(self) -> None:
        """Drop every held factorisation (the counters stay): memory back, the next rho factorises anew."""
        self._cache.clear()

    def solve(self, rho: float, rhs: np.ndarray) -> np.ndarray:
        """Solve ``matrix(rho) @ x = rhs``, factorising matrix(rho) if not cached."""
        solve = self.held(rho)
        start = time.perf_counter()
        x = solve(rhs)
        self.solve_time += time.perf_counter() - start
        self.solves += 1
        return x

    def ldl(self, rho: float):
        """The LDL' factors of matrix(rho) as arrays (Lp, Li, Lx, Dinv, perm), factorising if not cached;
        None unless the backend is qdldl.  ``admmkit.linalg.compiled.ldl_solve`` solves with them as qdldl does
        (the same operations, so the same bits); they are read from the factor once per rho."""
        solve = self.held(rho)
        if solve.ldl is None:
            return None
        if not hasattr(solve, "ldl_arrays"):
            L, d, p = solve.ldl()
            solve.ldl_arrays = (L.indptr, L.indices, L.data, 1.0 / d, p)
        return solve.ldl_arrays
