"""The V-cycle levels of a 3-D vector problem in node blocks: :mod:`admmkit.linalg.vcycle`'s passes on BSR.

3-D elasticity numbered node by node has a finest matrix of 3 x 3 blocks, and
smoothed aggregation with its six rigid-body modes gives a prolongator of
3 x 6 blocks and coarse levels of 6 x 6 blocks (A and P).  In CSR every
value carries a 4-byte column index and every row is one chain of dependent
additions; here one index serves a block, and the R rows of a block row are
summed side by side, R independent chains over the same blocks (the
processor overlaps them).  At h = 1/32 (3.1e5 unknowns, 1.4e7 entries on the
finest level, 5.3e6 on the coarse one) the V-cycle took 0.053 s of CPU
against 0.104-0.113 s for the CSR levels of :mod:`admmkit.linalg.vcycle`.

The sums, row by row:

- forward sweep from zero: the CSR kernel's sums in its order (columns
  ascending), so its x is CSR's bit for bit (a zero a block holds where CSR
  stores nothing adds +-0);
- residual and restriction: from the blocks left of the diagonal only (A
  symmetric: smoothed aggregation's levels are, to round-off), in the same pass: once x_I is known, block (I, J) adds
  -A_IJ' x_I to row J's residual, which is complete a bandwidth later.  The
  descent reads the lower half of A instead of all of it; the residual's
  terms come in another order than CSR's (round-off);
- prolongation and backward sweep (one pass upwards): each block row's
  blocks from the last to the first (columns descending), so that the pass
  streams memory downwards throughout (reading each row upwards, in CSR's
  order, took 4 times as long at h = 1/16: the prefetcher lost the stream);
  in the sweep, row i's off-diagonal blocks first, then the diagonal block's
  entries a_ij (j != i, ascending), which need the rows below i just
  updated.  The same terms as CSR's rows in another order: these values
  differ from CSR's by round-off.

The kernels are made for each block size (R, C) by :func:`level_kernels`:
numba compiles the sizes as constants (and caches each pair on disk).
"""
from __future__ import annotations

import numpy as np

from ..kernel_cache import numba_stamped
from ..kernels import _u
from .vcycle_blocks import BlockLevel

njit = numba_stamped().njit  # numba with admmkit's cache stamps


@njit(cache=True, inline="always")
def _add_blocks_descending(indices, data, x, k_first, k_last, s, R, B, BB):
    """s[r] += the blocks k_last, k_last - 1, ..., k_first of row r < R (B columns a block, BB values).

    At module level, not in :func:`level_kernels`: numba's disk cache misses a kernel that calls another
    made in the same factory; inlined, it sees its caller's constant sizes."""
    for kk in range(k_last - k_first + 1):
        k = k_last - kk
        j = B * indices[_u(k)]
        for r in range(R):
            t = s[r]
            at = BB * k + B * r
            for c in range(B):
                t += data[_u(at + c)] * x[_u(j + c)]
            s[r] = t


def level_kernels(R: int, C: int):
    """(forward_restrict, prolong_backward, block_values) for A in R x R blocks and P in R x C blocks."""
    RR, RC = R * R, R * C

    @njit(cache=True)
    def forward_restrict(indptr, indices, data, block_diagonal, inverse, b, x, P_indptr, P_indices, P_data,
                         coarse_b, lag):
        """A forward sweep from zero and coarse_b = P' (b - A x), reading only the blocks left of the diagonal
        (A symmetric): once x_I is known, each block (I, J < I) gives row J's residual its term
        -A_IJ' x_I; row M's residual is complete ``lag`` block rows later (the bandwidth) and is then
        scattered through P's row M.  The residuals in between live in a ring of lag + 1 block rows."""
        nb = indptr.shape[0] - 1
        coarse_b[:] = 0.0
        lag = min(lag, nb)
        W = lag + 1
        ring = np.empty(R * W)
        s = np.empty(R)
        for step in range(nb + lag):
            I = step
            if I < nb:                                  # block row I of the sweep
                kd = block_diagonal[_u(I)]
                for r in range(R):
                    s[r] = 0.0
                for k in range(indptr[_u(I)], kd):
                    j = R * indices[_u(k)]
                    for r in range(R):
                        t = s[r]
                        at = RR * k + R * r
                        for c in range(R):
                            t += data[_u(at + c)] * x[_u(j + c)]
                        s[r] = t
                for r in range(R):
                    t = s[r]
                    for c in range(r):
                        t += data[_u(RR * kd + R * r + c)] * x[_u(R * I + c)]
                    x[_u(R * I + r)] = (b[_u(R * I + r)] - t) * inverse[_u(R * I + r)]
                slot = R * (I % W)                      # row I's residual: its diagonal block's upper part
                for r in range(R):
                    t = 0.0
                    for c in range(r + 1, R):
                        t += data[_u(RR * kd + R * r + c)] * x[_u(R * I + c)]
                    ring[slot + r] = -t
                for k in range(indptr[_u(I)], kd):      # and the rows above: A_JI x_I = A_IJ' x_I
                    at = R * (indices[_u(k)] % W)
                    for c in range(R):
                        t = ring[at + c]
                        for r in range(R):
                            t -= data[_u(RR * k + R * r + c)] * x[_u(R * I + r)]
                        ring[at + c] = t
            M = step - lag
            if M >= 0:                                  # block row M's residual, complete, through P's blocks
                slot = R * (M % W)
                for k in range(P_indptr[_u(M)], P_indptr[_u(M + 1)]):
                    j = C * P_indices[_u(k)]
                    for c in range(C):
                        t = coarse_b[_u(j + c)]
                        for r in range(R):
                            t += P_data[_u(RC * k + C * r + c)] * ring[slot + r]
                        coarse_b[_u(j + c)] = t

    @njit(cache=True)
    def prolong_backward(indptr, indices, data, block_diagonal, inverse, x, b, P_indptr, P_indices, P_data,
                         coarse_x, lag):
        """x += P coarse_x and a backward sweep in one pass, the correction ``lag`` block rows ahead; every
        block row's blocks read from the last (the whole pass streams memory downwards: reading each row
        upwards took 4 times as long)."""
        nb = indptr.shape[0] - 1
        lag = min(lag, nb)
        s = np.empty(R)
        for step in range(nb + lag):
            I = nb - 1 - step
            if I >= 0:                                  # x += P coarse_x on block row I
                for r in range(R):
                    s[r] = 0.0
                _add_blocks_descending(P_indices, P_data, coarse_x, P_indptr[_u(I)], P_indptr[_u(I + 1)] - 1, s, R, C,
                                           RC)
                for r in range(R):
                    x[_u(R * I + r)] = x[_u(R * I + r)] + s[r]
            I = nb - 1 - step + lag
            if I < nb:                                  # block row I of the backward sweep
                kd = block_diagonal[_u(I)]
                for r in range(R):
                    s[r] = 0.0
                _add_blocks_descending(indices, data, x, kd + 1, indptr[_u(I + 1)] - 1, s, R, R, RR)
                _add_blocks_descending(indices, data, x, indptr[_u(I)], kd - 1, s, R, R, RR)
                for rr in range(R):
                    r = R - 1 - rr
                    t = s[r]
                    for c in range(R):
                        if c != r:
                            t += data[_u(RR * kd + R * r + c)] * x[_u(R * I + c)]
                    x[_u(R * I + r)] = (b[_u(R * I + r)] - t) * inverse[_u(R * I + r)]

    @njit(cache=True)
    def block_values(indptr, indices, data, block_indptr, block_indices, out, full):
        """out (BSR values, R x R blocks, zeros included) from a sorted CSR matrix whose entries the pattern
        holds (``full``: every block entry is stored, none needs zeroing first)."""
        if not full:
            out[:] = 0.0
        for I in range(block_indptr.shape[0] - 1):
            for r in range(R):
                i = R * I + r
                k = block_indptr[_u(I)]
                for jj in range(indptr[_u(i)], indptr[_u(i + 1)]):
                    j = indices[_u(jj)]
                    J = j // R
                    while block_indices[_u(k)] < J:
                        k += 1
                    out[_u(RR * k + R * r + j - R * J)] = data[_u(jj)]

    return forward_restrict, prolong_backward, block_values


def _level_class(R: int, C: int, doc: str):
    """A :class:`admmkit.linalg.vcycle_blocks.BlockLevel` with R x R blocks of A, R x C of P and these kernels."""
    forward_restrict, prolong_backward, block_values = level_kernels(R, C)

    def _values(indptr, indices, data, block_indptr, block_indices, out, full):
        block_values(indptr, indices, data, block_indptr, block_indices, out, full)
    return type(f"BlockLevel{R}x{C}", (BlockLevel,), {
        "__doc__": doc, "R": R, "C": C, "__module__": __name__,
        "descent": staticmethod(forward_restrict), "ascent": staticmethod(prolong_backward), "threaded": None,
        "_values": staticmethod(_values)})


#: the finest level of 3-D elasticity: A in 3 x 3 node blocks, P in 3 x 6 (six rigid-body modes)
FinestLevel3D = _level_class(3, 6, "The finest level of a 3-D vector problem: A in 3 x 3 blocks, P in 3 x 6.")
#: a coarse level of six near-null vectors: A and P in 6 x 6 blocks
CoarseLevel6 = _level_class(6, 6, "A coarse level of six near-null vectors: A and P in 6 x 6 blocks.")

__all__ = ["level_kernels", "FinestLevel3D", "CoarseLevel6"]
