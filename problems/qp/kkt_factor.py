"""The KKT x-step's factor held as arrays: qdldl's LDL' refactorised by a kernel at a change of rho.

OSQP factorises its KKT matrix once in its setup and, at a change of rho,
refactorises it numerically in the same order.  ``CachedFactorization`` with
qdldl does the same through qdldl's wrapper, but the compiled x-step reads
the factor as arrays, which the wrapper hands out only as a new scipy matrix
(``Solver.factors()``, about 75 us at every factorisation, more than
factorising a small QP's KKT matrix).  :class:`KKTFactor` takes qdldl's
fill-reducing order (AMD's, from the routine qdldl's library calls:
:func:`amd_order`) and keeps the factor itself: the symbolic phase once (:func:`admmkit.linalg.ldl.qdldl_symbolic`),
the numeric one at each rho (:func:`admmkit.linalg.ldl.qdldl_numeric`, qdldl's
operations in its order: the same factor bit for bit), in place, so the
arrays a segment reads stay the same objects.

Used where the x-step is the KKT form, its backend qdldl and compiled code
is chosen (``admmkit.problems.qp.xstep_forms.x_step_solver``); ``ENABLED``
False keeps ``CachedFactorization`` (qdldl's update and ``factors()``: the
same numbers).
"""
from __future__ import annotations

import ctypes
import functools
import time

import numpy as np

from admmkit.kernels import compiled_code
from admmkit.linalg.compiled import ldl_solve
from admmkit.linalg.ldl import qdldl_numeric, qdldl_symbolic

#: hold the factor as arrays, refactorised by a kernel (False: qdldl's wrapper, ``CachedFactorization``)
ENABLED = True
#: take qdldl's order from the AMD routine its library exports (False, or a library without it: from its factor)
AMD_DIRECT = True
#: from this many stored entries of K's upper triangle on, the order comes from AMD's compiled port
#: (:mod:`admmkit.linalg.amd`, the same permutation): qdldl's wheel builds its AMD without optimisation, and on the
#: KKT matrices of the Maros-Meszaros problems with n + m <= 3000 the port was 1.4-2.2x faster from about 800
#: entries on (PRIMAL3, 23,893 entries: 8.2 against 28.6 ms), even at 100 (HS118) and 0.7-0.8x below (one run,
#: best of 5); 0 or None: always qdldl's routine
AMD_COMPILED_MIN_NNZ = 200


@functools.lru_cache(maxsize=None)
def _amd_routine():
    """``amd_l_order`` of qdldl's library (the AMD qdldl orders with, SuiteSparse's 64-bit form), or None."""
    try:
        import qdldl
        routine = ctypes.CDLL(qdldl.__file__).amd_l_order
    except (ImportError, OSError, AttributeError):
        return None
    routine.restype = ctypes.c_int
    routine.argtypes = [ctypes.c_int64] + [ctypes.c_void_p] * 5
    return routine


def amd_order(K) -> np.ndarray:
    """qdldl's fill-reducing order of the upper triangle K: AMD with its default controls, as qdldl's ``Solver``
    calls it (``amd_l_order(n, Kp, Ki, P, NULL, NULL)``): from ``AMD_COMPILED_MIN_NNZ`` entries on by AMD's
    compiled port (:func:`admmkit.linalg.amd.amd_order`, the same permutation), below it qdldl's routine called
    directly (about 10 us on a small QP); else read off qdldl's factor (``Solver(K).factors()``, the same order:
    tests/problems/test_qp_kkt_factor.py)."""
    n = K.shape[0]
    if AMD_COMPILED_MIN_NNZ and K.nnz >= AMD_COMPILED_MIN_NNZ:
        from admmkit.linalg.amd import amd_order as compiled_amd
        return compiled_amd(K.indptr, K.indices, n)
    routine = _amd_routine() if AMD_DIRECT else None
    if routine is not None:
        Kp = np.ascontiguousarray(K.indptr, dtype=np.int64)
        Ki = np.ascontiguousarray(K.indices, dtype=np.int64)
        perm = np.empty(n, dtype=np.int64)
        if routine(n, Kp.ctypes.data, Ki.ctypes.data, perm.ctypes.data, None, None) >= 0:     # AMD_OK (or jumbled)
            return perm
    import qdldl
    try:
        return np.asarray(qdldl.Solver(K, upper=True).factors()[2], dtype=np.int64)
    except Exception as err:
        raise np.linalg.LinAlgError(f"backend 'qdldl' could not factorise the {n}x{n} matrix (singular or not "
                                    f"positive definite?): {err}") from err


class KKTFactor:
    """The factor of ``matrix(rho)`` (the KKT matrix's upper triangle, one pattern for every rho) for the last rho
    asked, with ``CachedFactorization``'s interface as the QP uses it: ``prepare``, ``refresh``, ``solve``, ``ldl``,
    ``clear``, ``rho in factor``, and the counters ``factorizations``, ``solves``, ``factor_time``,
    ``solve_time``.  ``order``: a fill-reducing permutation to factorise in (None: AMD's, :func:`amd_order`)."""

    backend = "qdldl"

    def __init__(self, matrix, order: np.ndarray | None = None) -> None:
        self.matrix = matrix
        self._given_order = order
        self.factorizations = self.solves = 0
        self.factor_time = self.solve_time = 0.0
        self._rho = None                # the rho the held factor is of (None: none held)
        self._symbolic = None           # (Cp, Ci, to_C, parent, Lp, perm), once per pattern
        self._arrays = None             # (Lp, Li, Lx, Dinv, perm): what the compiled solves read

    @property
    def order(self) -> np.ndarray | None:
        """The permutation the factor is made in (None before the first factorisation)."""
        return None if self._symbolic is None else self._symbolic[5]

    def __contains__(self, rho) -> bool:
        """Whether the held factor is of this rho."""
        return self._rho is not None and float(rho) == self._rho

    def prepare(self, rho: float) -> None:
        """Factorise matrix(rho) now unless the held factor is of this rho."""
        if float(rho) not in self:
            self.refresh(rho)

    def refresh(self, rho: float) -> None:
        """Factorise matrix(rho) now (its values changed for the same rho: new row weights)."""
        start = time.perf_counter()
        K = self.matrix(float(rho))
        with compiled_code(True):
            if self._symbolic is None:
                self._analyse(K)
            self._numeric(K)
        self._rho = float(rho)
        self.factor_time += time.perf_counter() - start
        self.factorizations += 1

    def _analyse(self, K) -> None:
        """qdldl's order of K (AMD's: :func:`amd_order`, unless one was given) and the symbolic phase in it."""
        perm = amd_order(K) if self._given_order is None else np.asarray(self._given_order, dtype=np.int64)
        Cp, Ci, to_C, parent, Lp = qdldl_symbolic(K.indptr, K.indices, perm)
        n = perm.shape[0]
        self._symbolic = (Cp, Ci, to_C, parent, Lp, perm, np.flatnonzero(to_C >= 0))
        self._Cx = np.zeros(Cp[n])
        self._work = (np.empty(n), np.empty(n, np.bool_), np.empty(n, np.int64), np.empty(n, np.int64),
                      np.empty(n, np.int64))
        self._arrays = (Lp, np.empty(Lp[n], np.int64), np.empty(Lp[n]), np.empty(n), perm)
        self._D = np.empty(n)

    def _numeric(self, K) -> None:
        """qdldl's numeric factorisation of K's values, in place of the held factor."""
        Cp, Ci, to_C, parent, Lp, perm, upper = self._symbolic
        self._Cx[to_C[upper]] = K.data[upper]
        _, Li, Lx, Dinv, _ = self._arrays
        bad = qdldl_numeric(Cp, Ci, self._Cx, parent, Lp, Li, Lx, self._D, Dinv, *self._work)
        if bad >= 0:
            self._rho = None
            n = perm.shape[0]
            raise np.linalg.LinAlgError(f"backend 'qdldl' could not factorise the {n}x{n} matrix (singular or "
                                        f"not positive definite?): zero pivot at step {bad}")

    def ldl(self, rho: float):
        """(Lp, Li, Lx, Dinv, perm) of matrix(rho), factorised first if the held factor is of another rho."""
        self.prepare(rho)
        return self._arrays

    def solve(self, rho: float, rhs: np.ndarray) -> np.ndarray:
        """matrix(rho)^-1 rhs (qdldl's solve, the same operations: ``admmkit.linalg.compiled.ldl_solve``)."""
        factors = self.ldl(rho)
        start = time.perf_counter()
        b = np.asarray(rhs, dtype=np.float64)
        if b.shape != (factors[4].shape[0],):
            raise ValueError(f"rhs must have shape ({factors[4].shape[0]},), got {b.shape}")
        if not np.isfinite(b).all():
            raise ValueError("rhs must be finite (it contains nan or inf)")
        x = np.empty_like(b)
        with compiled_code(True):
            ldl_solve(*factors, b, np.empty_like(b), x)
        if not np.isfinite(x).all():
            raise np.linalg.LinAlgError("backend 'qdldl' returned a non-finite solution: the matrix is singular")
        self.solve_time += time.perf_counter() - start
        self.solves += 1
        return x

    def clear(self) -> None:
        """Forget the held factor's rho (the next one factorises anew; the order and symbolic phase are kept)."""
        self._rho = None
