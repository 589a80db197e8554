"""The AMG V-cycle and the CSR products of CG in compiled kernels (numba).

:class:`VCycle` runs the V-cycle of a pyamg hierarchy whose levels are CSR
and whose smoothers are one forward Gauss-Seidel sweep before and one
backward sweep after the coarse-grid correction (what
:class:`admmkit.linalg.amg.AMGPreconditioner` builds), with pyamg's floating-point
cycle up to round-off (1e-15 relative with double-precision values):

- the forward sweep starts from x = 0, so it reads only the lower triangle
  of each sorted row: pyamg's sweep adds a_ij * 0 for the upper entries,
  which changes no sum; both sweeps multiply by 1 / a_ii instead of dividing
  (0.0129 -> 0.0121 s forward, 0.0168 -> 0.0148 s backward at 1e6 rows: the
  division sat in the sweep's chain of dependent rows);
- the residual after that sweep is -sum_{j>i} a_ij x_j (the sweep zeroed the
  rest of b_i - (A x)_i), half a product, and the restriction R r = P' r
  scatters P's rows in order; both run inside the forward sweep, a bandwidth
  behind it (:func:`_forward_restrict`), where the sweep's chain of dependent
  rows leaves the core idle: at 1e6 rows the three passes took 0.031 s, the
  one pass 0.024 s, with the same values bit for bit;
- the correction x += P x_c is one pass over rows, every row summed in its
  stored order by one thread, so splitting the rows among threads changes no
  bit: the iterates do not depend on the thread count;
- the finest level of a 2-D vector problem (2 x 2 node blocks, a 2 x 3 block
  prolongator: elasticity with its three rigid modes) runs on BSR storage
  (:mod:`admmkit.linalg.vcycle_blocks`), one column index per block: the same sums
  in the same order; at 1e6 rows its three passes 0.043 -> 0.031 s; the
  coarse levels of three near-null vectors likewise in 3 x 3 blocks
  (:mod:`admmkit.linalg.vcycle_blocks3`); with one kernel thread the correction
  x += P x_c runs inside the backward sweep, a bandwidth ahead of it;
- the coarsest level is pyamg's own coarse solver.

:func:`csr_product` gives y = A x for CG in the same way.  The Gauss-Seidel
sweeps stay sequential (a multithreaded sweep would be another smoother).
Threads: :func:`kernel_threads` (one unless ``$ADMMKIT_KERNEL_THREADS`` asks for more).
numba is imported through :func:`admmkit.kernel_cache.numba_stamped`, so an edited kernel file
recompiles the cached kernels (their stamps hold every kernel file's source).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..kernel_cache import numba_stamped
from .kernel_threads import THREADS_VARIABLE, kernel_threads  # noqa: F401  (THREADS_VARIABLE: re-exported)
from ..kernels import _u
from .vcycle_blocks import BlockLevel
from .vcycle_blocks3 import BlockLevel3
from .vcycle_blocks3d import CoarseLevel6, FinestLevel3D
from .vcycle_blockgs3d import FinestLevel3DBlockGS
from .vcycle_jacobi3d import FinestLevel3DJacobi

njit, prange = numba_stamped().njit, numba_stamped().prange  # numba with admmkit's cache stamps

#: the block storages of a level: the finest (2-D: 2 x 2 blocks, P 2 x 3; 3-D: 3 x 3, P 3 x 6), then the coarse
#: ones (3 x 3 and 6 x 6 blocks: three and six near-null vectors); ``blocks3d=False`` leaves out the 3-D ones
FINEST_LEVELS, COARSE_LEVELS = (BlockLevel, FinestLevel3D), (BlockLevel3, CoarseLevel6)
#: the finest level's smoothers by name: Gauss-Seidel (forward before, backward after the correction) everywhere;
#: on the finest level of a 3-D vector problem also block Gauss-Seidel (3 x 3 node blocks solved exactly,
#: :mod:`admmkit.linalg.vcycle_blockgs3d`) or damped 3 x 3 block Jacobi (:mod:`admmkit.linalg.vcycle_jacobi3d`)
SMOOTHERS = {"gauss_seidel": FinestLevel3D, "block_gauss_seidel": FinestLevel3DBlockGS,
             "block_jacobi": FinestLevel3DJacobi}


# ---------------------------------------------------------------- kernels
@njit(cache=True, parallel=True)
def _csr_matvec(indptr, indices, data, x, out, chunks, accumulate):
    """out = A x, or out += A x if ``accumulate`` (A x summed first, then added: the value of
    ``out += A @ x``); rows split into ``chunks`` contiguous ranges (one per thread)."""
    n = indptr.shape[0] - 1
    for c in prange(chunks):
        for i in range(c * n // chunks, (c + 1) * n // chunks):
            s = 0.0
            for jj in range(indptr[_u(i)], indptr[_u(i + 1)]):
                s += data[_u(jj)] * x[_u(indices[_u(jj)])]
            out[_u(i)] = out[_u(i)] + s if accumulate else s


@njit(cache=True, inline="always")
def _forward_row(indptr, indices, data, diagonal, inverse, b, x, i):
    """Row i of a forward Gauss-Seidel sweep from x = 0: the entries left of the diagonal, times 1 / a_ii."""
    s = 0.0
    for jj in range(indptr[_u(i)], diagonal[_u(i)]):
        s += data[_u(jj)] * x[_u(indices[_u(jj)])]
    x[_u(i)] = (b[_u(i)] - s) * inverse[_u(i)]


@njit(cache=True, inline="always")
def _restrict_residual_row(indptr, indices, data, diagonal, x, P_indptr, P_indices, P_data, coarse_b, m):
    """Add row m's residual r_m = -sum_{j > m} a_mj x_j, times P's row m, to coarse_b (R r = P' r by rows)."""
    s = 0.0
    for jj in range(diagonal[_u(m)] + 1, indptr[_u(m + 1)]):
        s += data[_u(jj)] * x[_u(indices[_u(jj)])]
    r = -s
    for jj in range(P_indptr[_u(m)], P_indptr[_u(m + 1)]):
        coarse_b[_u(P_indices[_u(jj)])] += P_data[_u(jj)] * r


@njit(cache=True)
def _forward_restrict(indptr, indices, data, diagonal, inverse, b, x, P_indptr, P_indices, P_data, coarse_b, lag):
    """The descent of a V-cycle level in one pass: x = one forward Gauss-Seidel sweep for A x = b from zero,
    and coarse_b = P' (b - A x).

    Right after the sweep, b - A x is -sum_{j > i} a_ij x_j in row i (the sweep zeroed the rest, to
    round-off): half a product.  Row m's residual needs x up to row m + ``lag`` (the pattern's bandwidth),
    so it is formed, and scattered through P's row m, ``lag`` rows behind the sweep, while those rows are
    still in cache; each sum runs in the order of the separate passes (the sweep, the residual, the scatter
    of P's rows in order), so the values are theirs bit for bit.
    """
    n = indptr.shape[0] - 1
    coarse_b[:] = 0.0
    lag = min(lag, n)
    for i in range(lag):
        _forward_row(indptr, indices, data, diagonal, inverse, b, x, i)
    for i in range(lag, n):
        _forward_row(indptr, indices, data, diagonal, inverse, b, x, i)
        _restrict_residual_row(indptr, indices, data, diagonal, x, P_indptr, P_indices, P_data, coarse_b, i - lag)
    for m in range(n - lag, n):
        _restrict_residual_row(indptr, indices, data, diagonal, x, P_indptr, P_indices, P_data, coarse_b, m)


@njit(cache=True)
def _bandwidth(indptr, indices):
    """max |i - j| over the stored entries a_ij of a sorted CSR pattern (0 for a diagonal one)."""
    width = 0
    for i in range(indptr.shape[0] - 1):
        if indptr[_u(i + 1)] > indptr[_u(i)]:
            width = max(width, i - indices[_u(indptr[_u(i)])], indices[_u(indptr[_u(i + 1)] - 1)] - i)
    return width


@njit(cache=True)
def _diagonal_positions(indptr, indices):
    """The position of a_ii in each sorted row i (that of the first entry past the diagonal, minus one,
    if a row stores no diagonal)."""
    n = indptr.shape[0] - 1
    out = np.empty(n, dtype=np.int64)
    for i in range(n):
        k = indptr[_u(i)]
        while k < indptr[_u(i + 1)] and indices[_u(k)] < i:
            k += 1
        out[_u(i)] = k if k < indptr[_u(i + 1)] and indices[_u(k)] == i else k - 1
    return out


@njit(cache=True)
def _gauss_seidel_backward(indptr, indices, data, diagonal, inverse, x, b):
    """One backward Gauss-Seidel sweep (pyamg's ``gauss_seidel(sweep="backward")``, times 1 / a_ii)."""
    n = indptr.shape[0] - 1
    for k in range(n):
        i = n - 1 - k
        s = 0.0
        for jj in range(indptr[_u(i)], diagonal[_u(i)]):
            s += data[_u(jj)] * x[_u(indices[_u(jj)])]
        for jj in range(diagonal[_u(i)] + 1, indptr[_u(i + 1)]):
            s += data[_u(jj)] * x[_u(indices[_u(jj)])]
        x[_u(i)] = (b[_u(i)] - s) * inverse[_u(i)]


# ---------------------------------------------------------------- wrappers
def _sorted_csr(M):
    """M itself if it is CSR (else converted), with its indices sorted in place."""
    if not (sp.issparse(M) and M.format == "csr"):
        M = M.tocsr()
    if not M.has_sorted_indices:
        M.sort_indices()
    return M


class _Stored:
    """A CSR matrix's index arrays with its values in a given dtype (the kernels' arguments)."""

    def __init__(self, M, values):
        self.indptr, self.indices, self.shape = M.indptr, M.indices, M.shape
        self.data = M.data if M.data.dtype == values else M.data.astype(values)


def _stored(M, values) -> _Stored:
    """M's arrays for the kernels, the values converted to ``values`` (the indices shared, not copied)."""
    return _Stored(M, np.dtype(values))


def _inverse_diagonal(indices: np.ndarray, data: np.ndarray, at: np.ndarray, values, checked=False) -> np.ndarray:
    """1 / a_ii in double precision from the values at the diagonal positions ``at``, as stored in ``values``
    (``checked``: ``at`` is known to hold every row's diagonal, as for a pattern checked before)."""
    if not checked and at.shape[0] and not np.array_equal(indices[np.clip(at, 0, None)], np.arange(at.shape[0])):
        raise ValueError("every row of an AMG level needs its diagonal entry (the matrix is SPD)")
    return 1.0 / data[at].astype(values).astype(np.float64)


def _same_array(a: np.ndarray, b: np.ndarray) -> bool:
    """a and b are the same memory (one array, or views of it as scipy's constructors make: they slice the
    index arrays they are given), with the same shape and type."""
    return (a is b or (a.__array_interface__["data"][0] == b.__array_interface__["data"][0]
                       and a.shape == b.shape and a.dtype == b.dtype and a.strides == b.strides))


def csr_product(A):
    """x -> A x for a CSR matrix A by :func:`_csr_matvec` (rows among numba's threads; scipy's values)."""
    A = _sorted_csr(A)

    def product(x):
        out = np.empty(A.shape[0])
        _csr_matvec(A.indptr, A.indices, A.data, np.ascontiguousarray(x, dtype=float), out, kernel_threads(), False)
        return out
    return product


class VCycle:
    """z = V(r): the V-cycle of a pyamg ``MultilevelSolver`` (CSR levels, forward/backward Gauss-Seidel).

    Built once per hierarchy (rebuild it when the levels' matrices change).
    The levels' A are sorted in place; P is kept in sorted CSR and the
    restriction R = P' is applied from it (no copy of R); a level in node
    blocks keeps A and P in BSR instead (``block[lvl]``: :class:`admmkit.linalg.vcycle_blocks.BlockLevel` on the
    finest level, :class:`admmkit.linalg.vcycle_blocks3.BlockLevel3` below; ``first``: the former).  ``values=np.float32``
    keeps a single-precision copy of their values for the cycle (the indices
    shared): a third less memory traffic per stored entry, the arithmetic
    still in double precision.  The cycle is then exactly the V-cycle of the
    rounded hierarchy, still a symmetric positive definite operator, so CG
    keeps its guarantees; its iterates differ from double precision's by the
    inner tolerance, not the round-off.
    """

    def __init__(self, ml, values=np.float64, P=None, pattern_of: VCycle | None = None, blocks3d: bool = True,
                 smoother: str = "gauss_seidel"):
        if smoother not in SMOOTHERS:
            raise ValueError(f"smoother must be one of {', '.join(SMOOTHERS)}, got {smoother!r}")
        levels = ml.levels
        self.blocks3d, self.smoother = blocks3d, smoother
        for level in levels[:-1]:
            level.A = _sorted_csr(level.A)
        self.values = values
        self.coarse_solver, self.coarse_A = ml.coarse_solver, levels[-1].A
        self.n = levels[0].A.shape[0]
        self.levels = len(levels) - 1          # the levels with smoothers
        # per pattern: a refresh keeps every level's pattern (the very arrays), and with it these
        self._patterns = [(level.A.indptr, level.A.indices) for level in levels[:-1]]
        old = pattern_of._patterns if pattern_of is not None else [(None, None)] * len(self._patterns)
        kept = [b is not None and _same_array(a, b) and _same_array(c, d)
                for (a, c), (b, d) in zip(self._patterns, old)]
        self.block = [_block_level(lvl, level, values, pattern_of.block[lvl] if kept[lvl] else None, blocks3d,
                                   smoother)
                      for lvl, level in enumerate(levels[:-1])]
        self.A = [None if block else _stored(level.A, values) for level, block in zip(levels, self.block)]
        # R = P': no copy of R.  ``P``: the prolongators of a cycle on the same hierarchy (a Galerkin refresh
        # changes the levels' A only)
        self.P = [None if block else P[lvl] if P is not None and P[lvl] is not None
                  else _stored(_sorted_csr(level.P), values)
                  for lvl, (level, block) in enumerate(zip(levels, self.block))]
        self._bandwidth = [pattern_of._bandwidth[lvl] if kept[lvl] else _bandwidth(*pattern)
                           for lvl, pattern in enumerate(self._patterns)]
        self._diagonal = [pattern_of._diagonal[lvl] if kept[lvl] else _diagonal_positions(*pattern)
                          for lvl, pattern in enumerate(self._patterns)]
        self._inverse = [_inverse_diagonal(level.A.indices, (level.A if self.block[lvl] else self.A[lvl]).data, at,
                                           values, checked=kept[lvl])
                         for lvl, (level, at) in enumerate(zip(levels[:-1], self._diagonal))]
        # work arrays, one per level and kept from cycle to cycle (a refresh keeps them too): x of the coarse
        # levels (each is read by its parent's ascent before the next cycle writes it) and every level's
        # coarse right-hand side; new 8 MB arrays in every cycle cost page faults (3D block, 1e6 unknowns)
        self._work = (pattern_of._work if pattern_of is not None else
                      [(np.empty(level.A.shape[0]) if lvl else None, np.empty(level.P.shape[1]))
                       for lvl, level in enumerate(levels[:-1])])

    @property
    def first(self) -> BlockLevel | None:
        """The finest level in 2 x 2 node blocks, if it is stored so."""
        return self.block[0] if self.block and type(self.block[0]) is BlockLevel else None

    def update_entries(self, lvl: int, A: sp.csr_matrix, positions: np.ndarray) -> None:
        """Level ``lvl``'s values at ``positions`` of its CSR pattern taken from A (the level's matrix, changed
        only there), in the cycle's storage, and 1 / a_ii of the rows whose diagonal is among them: the values
        :meth:`refreshed` would give, without laying out the whole level again."""
        values = A.data[positions]
        block = self.block[lvl]
        rows = np.searchsorted(A.indptr, positions, side="right") - 1
        if block is not None:
            block.data[block.block_positions(A, positions)] = values   # rounded to the cycle's precision
            if hasattr(block, "update_rows"):                          # a block smoother's diagonal blocks
                block.update_rows((rows // block.R)[A.indices[positions] // block.R == rows // block.R])
        elif not np.may_share_memory(self.A[lvl].data, A.data):
            self.A[lvl].data[positions] = values
        rows = rows[A.indices[positions] == rows]
        self._inverse[lvl][rows] = 1.0 / A.data[self._diagonal[lvl][rows]].astype(self.values).astype(np.float64)

    def refreshed(self, ml) -> VCycle:
        """The cycle of the same hierarchy after a Galerkin refresh (new A on every level, the same P)."""
        return VCycle(ml, self.values, P=self.P, pattern_of=self, blocks3d=self.blocks3d, smoother=self.smoother)

    def __call__(self, r: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """The V-cycle applied to r from a zero initial guess (a new array, or written into ``out``)."""
        if not self.levels:
            z = self.coarse_solver(self.coarse_A, r)
            if out is None:
                return z
            out[...] = z
            return out
        return self._level(0, np.ascontiguousarray(r, dtype=float), out)

    def _correction(self, lvl: int, coarse_b: np.ndarray) -> np.ndarray:
        """The coarse-grid correction of level ``lvl``: the next level's cycle, or the coarsest solve."""
        if lvl == self.levels - 1:
            return np.asarray(self.coarse_solver(self.coarse_A, coarse_b), dtype=float)
        return self._level(lvl + 1, coarse_b)

    def _level(self, lvl: int, b: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Level ``lvl``'s part of the cycle for the right-hand side b; x in ``out`` (the finest level), in the
        level's work array (the coarse ones) or new."""
        x, coarse_b = self._work[lvl]
        x = out if out is not None else x if x is not None else np.empty(b.shape[0])
        block = self.block[lvl]
        if block is not None:      # the level's passes in blocks (the CSR kernels' values)
            return block.cycle(b, self._inverse[lvl], self._bandwidth[lvl], lambda c: self._correction(lvl, c),
                               x=x, coarse_b=coarse_b)
        A, P = self.A[lvl], self.P[lvl]
        diagonal, inverse = self._diagonal[lvl], self._inverse[lvl]
        _forward_restrict(A.indptr, A.indices, A.data, diagonal, inverse, b, x,
                          P.indptr, P.indices, P.data, coarse_b, self._bandwidth[lvl])
        coarse_x = self._correction(lvl, coarse_b)
        _csr_matvec(P.indptr, P.indices, P.data, coarse_x, x, kernel_threads(), True)
        _gauss_seidel_backward(A.indptr, A.indices, A.data, diagonal, inverse, x, b)
        return x


def _block_level(lvl: int, level, values, old, blocks3d: bool = True, smoother: str = "gauss_seidel"):
    """A level's storage in blocks where its kernels have them: on the finest level 2 x 2 node blocks with a
    2 x 3 prolongator (:class:`BlockLevel`) or 3 x 3 with 3 x 6 (:class:`admmkit.linalg.vcycle_blocks3d.FinestLevel3D`),
    below 3 x 3 or 6 x 6 blocks in A and P (:class:`BlockLevel3`, :class:`admmkit.linalg.vcycle_blocks3d.CoarseLevel6`);
    else None (CSR).  ``blocks3d=False``: not the 3-D ones.  ``old``: the level of a cycle on the same pattern,
    refreshed with the new values.  ``smoother``: the class of a 3-D finest level (:data:`SMOOTHERS`)."""
    if old is not None:
        return old.refreshed(level.A)
    kinds = (FINEST_LEVELS if lvl == 0 else ()) + COARSE_LEVELS
    if not blocks3d:
        kinds = tuple(k for k in kinds if k not in (FinestLevel3D, CoarseLevel6))
    kind = next((k for k in kinds if k.eligible(level.A, level.P)), None)
    if kind is FinestLevel3D and lvl == 0:
        kind = SMOOTHERS[smoother]
    block = kind(level.A, level.P, values) if kind is not None else None
    return block if block is not None and block.valid() else None
