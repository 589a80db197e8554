"""The finest V-cycle level of a 2-D vector problem in node blocks: the kernels of :mod:`admmkit.linalg.vcycle` on BSR.

A 2-D elasticity (or any two-component) problem numbered node by node has a
finest matrix of 2 x 2 blocks, and smoothed aggregation with three
near-null vectors (two translations, one rotation) gives a prolongator of
2 x 3 blocks.  Stored in CSR, every value carries a 4-byte column index; in
BSR one index serves a whole block, so the finest level's sweeps read about
a third fewer bytes.  The kernels here are :mod:`admmkit.linalg.vcycle`'s, row by
row, on that storage, with the block sizes written into the code (numba
does not unroll a block loop whose length is a run-time value, and the
generic loop was slower than CSR): every sum runs over the same entries in
the same order (columns ascending), so the values are the CSR kernels' bit
for bit; the zeros a block may hold where CSR stores nothing add +-0 to a
sum and change no value.

:class:`BlockLevel` holds the finest level's storage and refreshes its
values from a new CSR matrix on the same pattern in one pass.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..kernel_cache import numba_stamped
from ..kernels import _u
from .kernel_threads import kernel_threads
from .symmetric import diagonal_positions, row_of

njit, prange = numba_stamped().njit, numba_stamped().prange  # numba with admmkit's cache stamps


# ---------------------------------------------------------------- rows of a 2 x 2 block row
@njit(cache=True, inline="always")
def _row_sum(indices, data, x, k0, k1, r, s):
    """s + sum over blocks k0..k1-1 of row r's two entries (columns ascending)."""
    for k in range(k0, k1):
        j = 2 * indices[_u(k)]
        at = 4 * k + 2 * r
        s += data[_u(at)] * x[_u(j)]
        s += data[_u(at + 1)] * x[_u(j + 1)]
    return s


@njit(cache=True, inline="always")
def _forward_block_row(indptr, indices, data, block_diagonal, inverse, b, x, I):
    """Rows 2I and 2I + 1 of a forward Gauss-Seidel sweep from zero (the entries left of each diagonal)."""
    kd = block_diagonal[_u(I)]
    i = 2 * I
    s = _row_sum(indices, data, x, indptr[_u(I)], kd, 0, 0.0)
    x[_u(i)] = (b[_u(i)] - s) * inverse[_u(i)]
    s = _row_sum(indices, data, x, indptr[_u(I)], kd, 1, 0.0)
    s += data[_u(4 * kd + 2)] * x[_u(i)]
    x[_u(i + 1)] = (b[_u(i + 1)] - s) * inverse[_u(i + 1)]


@njit(cache=True, inline="always")
def _restrict_block_row(indptr, indices, data, block_diagonal, x, P_indptr, P_indices, P_data, coarse_b, M):
    """Rows 2M and 2M + 1's residuals -sum_{j > i} a_ij x_j, scattered through P's 2 x 3 blocks."""
    kd = block_diagonal[_u(M)]
    for r in range(2):
        s = 0.0
        if r == 0:
            s += data[_u(4 * kd + 1)] * x[_u(2 * M + 1)]
        s = _row_sum(indices, data, x, kd + 1, indptr[_u(M + 1)], r, s)
        res = -s
        for k in range(P_indptr[_u(M)], P_indptr[_u(M + 1)]):
            j = 3 * P_indices[_u(k)]
            at = 6 * k + 3 * r
            coarse_b[_u(j)] += P_data[_u(at)] * res
            coarse_b[_u(j + 1)] += P_data[_u(at + 1)] * res
            coarse_b[_u(j + 2)] += P_data[_u(at + 2)] * res


# ---------------------------------------------------------------- the level's passes
@njit(cache=True)
def forward_restrict(indptr, indices, data, block_diagonal, inverse, b, x, P_indptr, P_indices, P_data, coarse_b,
                     lag):
    """:func:`admmkit.linalg.vcycle._forward_restrict` on 2 x 2 blocks (A) and 2 x 3 blocks (P); ``lag`` in block rows."""
    nb = indptr.shape[0] - 1
    coarse_b[:] = 0.0
    lag = min(lag, nb)
    for I in range(lag):
        _forward_block_row(indptr, indices, data, block_diagonal, inverse, b, x, I)
    for I in range(lag, nb):
        _forward_block_row(indptr, indices, data, block_diagonal, inverse, b, x, I)
        _restrict_block_row(indptr, indices, data, block_diagonal, x, P_indptr, P_indices, P_data, coarse_b, I - lag)
    for M in range(nb - lag, nb):
        _restrict_block_row(indptr, indices, data, block_diagonal, x, P_indptr, P_indices, P_data, coarse_b, M)


@njit(cache=True, inline="always")
def _prolong_block_row(P_indptr, P_indices, P_data, coarse_x, x, I):
    """x[2I], x[2I + 1] += (P coarse_x) on the block row's two rows (each summed in its stored order)."""
    s0 = 0.0
    s1 = 0.0
    for k in range(P_indptr[_u(I)], P_indptr[_u(I + 1)]):
        j = 3 * P_indices[_u(k)]
        a, b, d = coarse_x[_u(j)], coarse_x[_u(j + 1)], coarse_x[_u(j + 2)]
        s0 += P_data[_u(6 * k)] * a
        s0 += P_data[_u(6 * k + 1)] * b
        s0 += P_data[_u(6 * k + 2)] * d
        s1 += P_data[_u(6 * k + 3)] * a
        s1 += P_data[_u(6 * k + 4)] * b
        s1 += P_data[_u(6 * k + 5)] * d
    x[_u(2 * I)] = x[_u(2 * I)] + s0
    x[_u(2 * I + 1)] = x[_u(2 * I + 1)] + s1


@njit(cache=True, inline="always")
def _backward_block_row(indptr, indices, data, block_diagonal, inverse, x, b, I):
    """Rows 2I + 1, then 2I, of a backward Gauss-Seidel sweep."""
    kd = block_diagonal[_u(I)]
    k0, k1 = indptr[_u(I)], indptr[_u(I + 1)]
    i = 2 * I + 1
    s = _row_sum(indices, data, x, k0, kd, 1, 0.0)
    s += data[_u(4 * kd + 2)] * x[_u(i - 1)]
    s = _row_sum(indices, data, x, kd + 1, k1, 1, s)
    x[_u(i)] = (b[_u(i)] - s) * inverse[_u(i)]
    i = 2 * I
    s = _row_sum(indices, data, x, k0, kd, 0, 0.0)
    s += data[_u(4 * kd + 1)] * x[_u(i + 1)]
    s = _row_sum(indices, data, x, kd + 1, k1, 0, s)
    x[_u(i)] = (b[_u(i)] - s) * inverse[_u(i)]


@njit(cache=True)
def gauss_seidel_backward(indptr, indices, data, block_diagonal, inverse, x, b):
    """:func:`admmkit.linalg.vcycle._gauss_seidel_backward` on 2 x 2 blocks (rows 2I + 1, then 2I, from the last)."""
    nb = indptr.shape[0] - 1
    for step in range(nb):
        _backward_block_row(indptr, indices, data, block_diagonal, inverse, x, b, nb - 1 - step)


@njit(cache=True)
def prolong_backward(indptr, indices, data, block_diagonal, inverse, x, b, P_indptr, P_indices, P_data, coarse_x,
                     lag):
    """x += P coarse_x, then a backward sweep, in one pass: block row I - lag is corrected just before the
    sweep reaches block row I (row i's sweep reads x_j for j >= i - bandwidth), while it is in cache."""
    nb = indptr.shape[0] - 1
    lag = min(lag, nb)
    for step in range(lag):
        _prolong_block_row(P_indptr, P_indices, P_data, coarse_x, x, nb - 1 - step)
    for step in range(lag, nb):
        _prolong_block_row(P_indptr, P_indices, P_data, coarse_x, x, nb - 1 - step)
        _backward_block_row(indptr, indices, data, block_diagonal, inverse, x, b, nb - 1 - step + lag)
    for step in range(nb, nb + lag):
        _backward_block_row(indptr, indices, data, block_diagonal, inverse, x, b, nb - 1 - step + lag)


@njit(cache=True, parallel=True)
def prolong(P_indptr, P_indices, P_data, coarse_x, x, chunks):
    """x += P coarse_x for P in 2 x 3 blocks, each row summed in its stored order (block rows among threads)."""
    nb = P_indptr.shape[0] - 1
    for c in prange(chunks):
        for I in range(c * nb // chunks, (c + 1) * nb // chunks):
            _prolong_block_row(P_indptr, P_indices, P_data, coarse_x, x, I)


@njit(cache=True)
def _block_values(indptr, indices, data, block_indptr, block_indices, out, full):
    """out (BSR values, 2 x 2 blocks, zeros included) from a sorted CSR matrix whose entries the pattern holds
    (``full``: every block entry is stored, so every value of out is written and none needs zeroing first)."""
    if not full:
        out[:] = 0.0
    for I in range(block_indptr.shape[0] - 1):
        for r in range(2):
            i = 2 * I + r
            k = block_indptr[_u(I)]
            for jj in range(indptr[_u(i)], indptr[_u(i + 1)]):
                j = indices[_u(jj)]
                while block_indices[_u(k)] < j >> 1:
                    k += 1
                out[_u(4 * k + 2 * r + (j & 1))] = data[_u(jj)]


@njit(cache=True)
def _block_positions(indptr, indices, block_indptr, block_indices, R, positions, out):
    """out[q]: where the entry at ``positions[q]`` of a CSR matrix sits in the values of its R x R blocks
    (-1 if its block is not stored)."""
    for q in range(positions.shape[0]):
        p = positions[_u(q)]
        i, j = row_of(indptr, p), indices[_u(p)]
        I, J = i // R, j // R
        out[_u(q)] = -1
        for k in range(block_indptr[_u(I)], block_indptr[_u(I + 1)]):
            if block_indices[_u(k)] == J:
                out[_u(q)] = R * R * k + R * (i - R * I) + (j - R * J)
                break


# ---------------------------------------------------------------- the level
class BlockLevel:
    """The finest level's A in 2 x 2 blocks and P in 2 x 3 blocks, values in ``values`` precision.

    ``eligible(A, P)`` says whether a level can be stored so: an even order,
    P in BSR with 2 x 3 blocks, and every diagonal block present.
    ``refreshed(A)``: the same storage with the values of a new A on A's pattern.
    """

    #: the block sizes of A (R x R) and P (R x C)
    R, C = 2, 3
    #: the level's kernels: one pass down, one pass up, and the ascent's two passes for several threads
    descent, ascent = staticmethod(forward_restrict), staticmethod(prolong_backward)
    threaded = (prolong, gauss_seidel_backward)

    def __init__(self, A: sp.csr_matrix, P, values, pattern: BlockLevel | None = None):
        if pattern is None:
            blocks = A.tobsr(blocksize=(self.R, self.R))
            blocks.sort_indices()
            self.indptr = np.asarray(blocks.indptr, dtype=np.int64)
            self.indices = blocks.indices
            self.block_diagonal = np.empty(self.indptr.size - 1, dtype=np.int64)
            diagonal_positions(self.indptr, self.indices, self.block_diagonal)   # of the blocks (I, I)
            Pb = sp.bsr_matrix(P)
            Pb.sort_indices()
            self.P_indptr, self.P_indices = np.asarray(Pb.indptr, dtype=np.int64), Pb.indices
            self.P_data = Pb.data.astype(values).ravel()
            self.P_shape = Pb.shape
        else:
            self.__dict__.update({k: getattr(pattern, k) for k in ("indptr", "indices", "block_diagonal", "P_indptr",
                                                                   "P_indices", "P_data", "P_shape")})
        self.shape = A.shape
        self.data = np.empty(self.R * self.R * self.indices.size, dtype=values)
        self._values(A.indptr, A.indices, A.data, self.indptr, self.indices, self.data, A.nnz == self.data.size)

    @staticmethod
    def _values(indptr, indices, data, block_indptr, block_indices, out, full):
        """The kernel that writes a CSR matrix's values into the block layout."""
        _block_values(indptr, indices, data, block_indptr, block_indices, out, full)

    @classmethod
    def eligible(cls, A, P) -> bool:
        """A of an order divisible by R with P in BSR of R x C blocks (2 x 3 here: a 2-D vector problem with
        three near-null vectors)."""
        return (A.shape[0] % cls.R == 0 and A.shape[0] > 0 and sp.issparse(P) and P.format == "bsr"
                and P.blocksize == (cls.R, cls.C))

    def refreshed(self, A: sp.csr_matrix) -> BlockLevel:
        """The level of a new A on the same pattern (same blocks, same P)."""
        return type(self)(A, None, self.data.dtype, pattern=self)

    def block_positions(self, A: sp.csr_matrix, positions: np.ndarray) -> np.ndarray:
        """Where the entries at ``positions`` of the CSR matrix A (on this level's pattern) sit in ``data``;
        found once for a set of positions and kept (a refresh for a new rho rewrites the same ones)."""
        cached = getattr(self, "_positions", None)
        if cached is not None and cached[0] is positions:
            return cached[1]
        found = np.empty(positions.size, dtype=np.int64)
        _block_positions(np.asarray(A.indptr, dtype=np.int64), A.indices, self.indptr, self.indices, self.R,
                         np.asarray(positions, dtype=np.int64), found)
        if found.size and found.min() < 0:
            raise ValueError("an entry lies outside the level's block pattern")
        self._positions = (positions, found)
        return found

    def valid(self) -> bool:
        """Every block row holds its diagonal block (the sweeps divide by a_ii)."""
        return bool(np.all(self.block_diagonal >= 0))

    def cycle(self, b: np.ndarray, inverse: np.ndarray, bandwidth: int, correction, x: np.ndarray | None = None,
              coarse_b: np.ndarray | None = None) -> np.ndarray:
        """The level's part of a V-cycle from zero: descent, ``correction(coarse_b)``, ascent (x new, or the
        array ``x`` overwritten; ``coarse_b`` likewise)."""
        lag = (bandwidth + self.R - 1) // self.R             # in block rows
        x = np.empty(self.shape[0]) if x is None else x
        coarse_b = np.empty(self.P_shape[1]) if coarse_b is None else coarse_b
        self.descent(self.indptr, self.indices, self.data, self.block_diagonal, inverse, b, x,
                     self.P_indptr, self.P_indices, self.P_data, coarse_b, lag)
        coarse_x = correction(coarse_b)
        threads = kernel_threads()
        if threads == 1 or self.threaded is None:   # the correction a bandwidth ahead of the sweep, one pass
            self.ascent(self.indptr, self.indices, self.data, self.block_diagonal, inverse, x, b,
                        self.P_indptr, self.P_indices, self.P_data, coarse_x, lag)
        else:                                        # the correction's rows among the threads, then the sweep
            correct, sweep = self.threaded
            correct(self.P_indptr, self.P_indices, self.P_data, coarse_x, x, threads)
            sweep(self.indptr, self.indices, self.data, self.block_diagonal, inverse, x, b)
        return x
