"""The coarse V-cycle levels of three near-null vectors in 3 x 3 blocks: :mod:`admmkit.linalg.vcycle`'s kernels on BSR.

Smoothed aggregation with three near-null vectors (2-D elasticity's rigid
motions) gives coarse levels whose unknowns come three per aggregate: their
matrices are made of 3 x 3 blocks, and so are the prolongators between two
such levels.  As :mod:`admmkit.linalg.vcycle_blocks` does for the finest level of a
2-D vector problem, these kernels run the level's passes on BSR storage,
one column index per block, with the block size written into the code:
every sum over the same entries in the same order as the CSR kernels, so
the values are theirs bit for bit (a zero a block holds where CSR stores
nothing changes no sum).  At 1e6 unknowns (Example 1) the first coarse
level has 1.7e5 rows and 5.5e6 entries.
"""
from __future__ import annotations

from ..kernel_cache import numba_stamped
from ..kernels import _u
from .vcycle_blocks import BlockLevel

njit = numba_stamped().njit  # numba with admmkit's cache stamps


@njit(cache=True, inline="always")
def _row_sum(indices, data, x, k0, k1, r, s):
    """s + sum over blocks k0..k1-1 of row r's three entries (columns ascending)."""
    for k in range(k0, k1):
        j = 3 * indices[_u(k)]
        at = 9 * k + 3 * r
        s += data[_u(at)] * x[_u(j)]
        s += data[_u(at + 1)] * x[_u(j + 1)]
        s += data[_u(at + 2)] * x[_u(j + 2)]
    return s


@njit(cache=True, inline="always")
def _forward_block_row(indptr, indices, data, block_diagonal, inverse, b, x, I):
    """Rows 3I, 3I + 1, 3I + 2 of a forward Gauss-Seidel sweep from zero."""
    kd = block_diagonal[_u(I)]
    for r in range(3):
        i = 3 * I + r
        s = _row_sum(indices, data, x, indptr[_u(I)], kd, r, 0.0)
        for c in range(r):
            s += data[_u(9 * kd + 3 * r + c)] * x[_u(3 * I + c)]
        x[_u(i)] = (b[_u(i)] - s) * inverse[_u(i)]


@njit(cache=True, inline="always")
def _restrict_block_row(indptr, indices, data, block_diagonal, x, P_indptr, P_indices, P_data, coarse_b, M):
    """Rows 3M + r's residuals -sum_{j > i} a_ij x_j, scattered through P's 3 x 3 blocks."""
    kd = block_diagonal[_u(M)]
    for r in range(3):
        s = 0.0
        for c in range(r + 1, 3):
            s += data[_u(9 * kd + 3 * r + c)] * x[_u(3 * M + c)]
        s = _row_sum(indices, data, x, kd + 1, indptr[_u(M + 1)], r, s)
        res = -s
        for k in range(P_indptr[_u(M)], P_indptr[_u(M + 1)]):
            j = 3 * P_indices[_u(k)]
            at = 9 * k + 3 * r
            coarse_b[_u(j)] += P_data[_u(at)] * res
            coarse_b[_u(j + 1)] += P_data[_u(at + 1)] * res
            coarse_b[_u(j + 2)] += P_data[_u(at + 2)] * res


@njit(cache=True)
def forward_restrict(indptr, indices, data, block_diagonal, inverse, b, x, P_indptr, P_indices, P_data, coarse_b,
                     lag):
    """:func:`admmkit.linalg.vcycle._forward_restrict` on 3 x 3 blocks (A and P); ``lag`` in block rows."""
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
    """x[3I + r] += (P coarse_x) on the block row's three rows (each summed in its stored order)."""
    for r in range(3):
        s = _row_sum(P_indices, P_data, coarse_x, P_indptr[_u(I)], P_indptr[_u(I + 1)], r, 0.0)
        x[_u(3 * I + r)] = x[_u(3 * I + r)] + s


@njit(cache=True, inline="always")
def _backward_block_row(indptr, indices, data, block_diagonal, inverse, x, b, I):
    """Rows 3I + 2, 3I + 1, 3I of a backward Gauss-Seidel sweep."""
    kd = block_diagonal[_u(I)]
    for rr in range(3):
        r = 2 - rr
        i = 3 * I + r
        s = _row_sum(indices, data, x, indptr[_u(I)], kd, r, 0.0)
        for c in range(3):
            if c != r:
                s += data[_u(9 * kd + 3 * r + c)] * x[_u(3 * I + c)]
        s = _row_sum(indices, data, x, kd + 1, indptr[_u(I + 1)], r, s)
        x[_u(i)] = (b[_u(i)] - s) * inverse[_u(i)]


@njit(cache=True)
def prolong_backward(indptr, indices, data, block_diagonal, inverse, x, b, P_indptr, P_indices, P_data, coarse_x,
                     lag):
    """x += P coarse_x and a backward sweep in one pass, the correction ``lag`` block rows ahead
    (:func:`admmkit.linalg.vcycle_blocks.prolong_backward` on 3 x 3 blocks)."""
    nb = indptr.shape[0] - 1
    lag = min(lag, nb)
    for step in range(lag):
        _prolong_block_row(P_indptr, P_indices, P_data, coarse_x, x, nb - 1 - step)
    for step in range(lag, nb):
        _prolong_block_row(P_indptr, P_indices, P_data, coarse_x, x, nb - 1 - step)
        _backward_block_row(indptr, indices, data, block_diagonal, inverse, x, b, nb - 1 - step + lag)
    for step in range(nb, nb + lag):
        _backward_block_row(indptr, indices, data, block_diagonal, inverse, x, b, nb - 1 - step + lag)


@njit(cache=True)
def _block_values(indptr, indices, data, block_indptr, block_indices, out, full):
    """out (BSR values, 3 x 3 blocks, zeros included) from a sorted CSR matrix whose entries the pattern holds
    (``full``: every block entry is stored, none needs zeroing first)."""
    if not full:
        out[:] = 0.0
    for I in range(block_indptr.shape[0] - 1):
        for r in range(3):
            i = 3 * I + r
            k = block_indptr[_u(I)]
            for jj in range(indptr[_u(i)], indptr[_u(i + 1)]):
                j = indices[_u(jj)]
                J = j // 3
                while block_indices[_u(k)] < J:
                    k += 1
                out[_u(9 * k + 3 * r + j - 3 * J)] = data[_u(jj)]


class BlockLevel3(BlockLevel):
    """A coarse level's A and P in 3 x 3 blocks, values in ``values`` precision (the patterns kept on refresh)."""

    R, C = 3, 3

    @staticmethod
    def _values(indptr, indices, data, block_indptr, block_indices, out, full):
        """The kernel that writes a CSR matrix's values into the 3 x 3 block layout."""
        _block_values(indptr, indices, data, block_indptr, block_indices, out, full)

    #: the level's kernels (one pass down, one pass up; no threaded ascent)
    descent, ascent, threaded = staticmethod(forward_restrict), staticmethod(prolong_backward), None
