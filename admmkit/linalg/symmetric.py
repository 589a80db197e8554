"""y = A x for a symmetric CSR matrix from its strict upper triangle and its diagonal (numba).

Each stored off-diagonal entry a_ij (j > i) serves both a_ij x_j and a_ji x_i,
so a product reads about half the entries a full CSR product reads.  CG's
products with K + rho D are memory-bound: at 1e6 unknowns (Example 1, 14e6
entries) one took 0.012 s this way against 0.019-0.028 s for the full CSR
product on one thread.  Sequential (the scatter to y_j is a write to another
row); the sums run in another order than scipy's, so the values agree to
round-off (4e-16 relative), not bit for bit.  The upper triangle's pattern is
found once per pattern (:class:`SymmetricPattern`); a new rho only gathers
the values.  :class:`NodePairPattern` stores the same triangle in 2 x 2 node
blocks for a 2-D vector problem (the same values, a quarter fewer bytes),
:class:`NodeTriplePattern` in 3 x 3 blocks for a 3-D one (the same values,
its sums and scatters held in scalars a block at a time).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..kernels import _u, njit


@njit(cache=True)
def _symmetric_matvec(indptr, indices, data, diagonal, x, out):
    """out = A x with A = U + U' + diag: ``indptr, indices, data`` the strict upper triangle U (CSR)."""
    n = indptr.shape[0] - 1
    for i in range(n):
        out[_u(i)] = diagonal[_u(i)] * x[_u(i)]
    for i in range(n):
        xi = x[_u(i)]
        s = out[_u(i)]
        for jj in range(indptr[_u(i)], indptr[_u(i + 1)]):
            j = indices[_u(jj)]
            a = data[_u(jj)]
            s += a * x[_u(j)]
            out[_u(j)] += a * xi
        out[_u(i)] = s


@njit(cache=True)
def _count_upper(indptr, indices, counts):
    """counts[i + 1] = the number of entries right of the diagonal in row i."""
    for i in range(indptr.shape[0] - 1):
        c = 0
        for k in range(indptr[_u(i)], indptr[_u(i + 1)]):
            if indices[_u(k)] > i:
                c += 1
        counts[_u(i + 1)] = c


@njit(cache=True)
def _split_pattern(indptr, indices, upper_indptr, upper, diagonal):
    """upper: the positions of the strict upper triangle's entries, row by row (rows starting at
    ``upper_indptr``); diagonal[i]: the position of a_ii (the last one stored), or -1."""
    for i in range(indptr.shape[0] - 1):
        w = upper_indptr[_u(i)]
        diagonal[_u(i)] = -1
        for k in range(indptr[_u(i)], indptr[_u(i + 1)]):
            j = indices[_u(k)]
            if j > i:
                upper[_u(w)] = k
                w += 1
            elif j == i:
                diagonal[_u(i)] = k


class SymmetricPattern:
    """Where a CSR pattern's strict upper triangle and diagonal are, to make products with matrices on it.

    ``product(A)``: x -> A x for a symmetric A stored on this pattern (the
    same ``indptr``/``indices``, any values): its upper triangle is gathered
    (one pass over the values), the lower one never read.
    """

    def __init__(self, pattern: sp.csr_matrix):
        n = pattern.shape[0]
        index = np.int32 if pattern.nnz < 2**31 - 1 else np.int64     # positions kept: 4 bytes each if they fit
        indptr = np.asarray(pattern.indptr, dtype=np.int64)
        counts = np.zeros(n + 1, dtype=np.int64)
        _count_upper(indptr, pattern.indices, counts)
        self.indptr = np.cumsum(counts)
        self.upper = np.empty(self.indptr[-1], dtype=index)
        self.diagonal = np.empty(n, dtype=np.int64)
        _split_pattern(indptr, pattern.indices, self.indptr, self.upper, self.diagonal)
        self.indices = np.ascontiguousarray(pattern.indices[self.upper])
        self.shape = pattern.shape
        self._pattern_indptr = indptr

    def product(self, A):
        """x -> A x from A's upper triangle and diagonal (A symmetric, on this pattern)."""
        return self._apply(*self._gather(A.data))

    def _entries(self, entries: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(k, i): the upper triangle's entries k and the rows i whose diagonal lie among the pattern's
        positions ``entries`` (sorted), both ascending: ``flatnonzero`` of the gathered values of a matrix
        nonzero exactly there, without gathering it (D of contact: 7e3 of 4.5e7 entries)."""
        entries = np.asarray(entries, dtype=np.int64)
        at = np.minimum(np.searchsorted(self.upper, entries), max(self.upper.size - 1, 0))
        on_upper = at[self.upper[at] == entries] if self.upper.size else np.empty(0, dtype=np.int64)
        rows = np.searchsorted(self._pattern_indptr, entries, side="right") - 1
        on_diagonal = rows[self.diagonal[rows] == entries]
        return on_upper, on_diagonal

    def _gather(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The upper triangle's values and the diagonal (0 where none is stored) of values on this pattern."""
        return values[self.upper], self._diagonal_values(values)

    def _diagonal_values(self, values: np.ndarray) -> np.ndarray:
        """The diagonal of values on this pattern (0 where none is stored)."""
        return np.where(self.diagonal >= 0, values[np.maximum(self.diagonal, 0)], 0.0)

    def pencil_products(self, K_data: np.ndarray, D_data: np.ndarray, D_entries: np.ndarray | None = None):
        """rho -> (x -> (K + rho D) x) for K and D given by their values on this pattern.

        K's upper triangle and diagonal are gathered once; a new rho copies them and updates the entries
        where D is stored, each as K + rho D: the values of ``PencilMatrix.at(rho)`` bit for bit, without
        forming and gathering the whole matrix (at 1e6 unknowns, 14e6 entries against 4e3 of D).
        """
        K_upper, K_diagonal = self._gather(K_data)
        if D_entries is None:
            D_upper, D_diagonal = self._gather(D_data)
            on_upper, on_diagonal = np.flatnonzero(D_upper), np.flatnonzero(D_diagonal)
            D_upper, D_diagonal = D_upper[on_upper], D_diagonal[on_diagonal]
        else:
            on_upper, on_diagonal = self._entries(D_entries)
            D_upper, D_diagonal = D_data[self.upper[on_upper]], D_data[self.diagonal[on_diagonal]]

        def at(rho: float, into=None):
            """The product for rho: new, or ``into`` (a product this ``at`` returned) with D's entries
            rewritten in place for rho (the same values; no copy of the whole triangle)."""
            if into is None:
                data, diagonal = K_upper.copy(), K_diagonal.copy()
            else:
                data, diagonal = into.values
            data[on_upper] = K_upper[on_upper] + rho * D_upper
            diagonal[on_diagonal] = K_diagonal[on_diagonal] + rho * D_diagonal
            return into if into is not None else self._apply(data, diagonal)
        at.updates_in_place = True
        return at

    def _apply(self, data: np.ndarray, diagonal: np.ndarray):
        """x -> A x for the upper triangle's values ``data`` and the ``diagonal``."""
        def apply(x, out=None):
            out = np.empty(self.shape[0]) if out is None else out
            _symmetric_matvec(self.indptr, self.indices, data, diagonal, np.ascontiguousarray(x, dtype=float), out)
            return out
        apply.writes_into = True      # apply(x, out=buffer): pcg's products without a new array each
        apply.values = (data, diagonal)
        return apply


# ---------------------------------------------------------------- node pairs (2-D vector problems)
@njit(cache=True)
def _pair_merge(indices, a0, a1, b0, b1, I, out, w):
    """The block columns J > I of two sorted rows (entries a0..a1 and b0..b1), ascending and once each, written
    to out from w (if out has room; else only counted).  Returns the new w."""
    last = -1
    while a0 < a1 or b0 < b1:
        ja = indices[_u(a0)] // 2 if a0 < a1 else 1 << 62
        jb = indices[_u(b0)] // 2 if b0 < b1 else 1 << 62
        J = min(ja, jb)
        if ja == J:
            a0 += 1
        if jb == J:
            b0 += 1
        if J > I and J != last:
            if w < out.shape[0]:
                out[_u(w)] = J
            w += 1
            last = J
    return w


@njit(cache=True)
def _pair_blocks(indptr, indices, block_indptr, block_indices):
    """Count (``block_indices`` empty) or list the block columns J > I of each node pair (rows 2I, 2I + 1)."""
    w = 0
    for I in range(block_indptr.shape[0] - 1):
        block_indptr[_u(I)] = w
        w = _pair_merge(indices, indptr[_u(2 * I)], indptr[_u(2 * I + 1)], indptr[_u(2 * I + 1)],
                        indptr[_u(2 * I + 2)], I, block_indices, w)
    block_indptr[_u(block_indptr.shape[0] - 1)] = w


@njit(cache=True)
def _pair_positions(indptr, indices, block_indptr, block_indices, positions, pair):
    """positions[4k + 2r + c]: where a_(2I+r, 2J+c) of block k = (I, J) sits in the pattern (-1: not stored);
    pair[I]: where a_(2I, 2I+1) sits (-1: not stored)."""
    positions[:] = -1
    for I in range(block_indptr.shape[0] - 1):
        pair[_u(I)] = -1
        for r in range(2):
            i = 2 * I + r
            k = block_indptr[_u(I)]
            for q in range(indptr[_u(i)], indptr[_u(i + 1)]):
                j = indices[_u(q)]
                if r == 0 and j == i + 1:
                    pair[_u(I)] = q
                elif j >= 2 * I + 2:
                    while block_indices[_u(k)] < j // 2:
                        k += 1
                    positions[_u(4 * k + 2 * r + j - 2 * (j // 2))] = q


@njit(cache=True)
def _pair_matvec(block_indptr, block_indices, data, pair_offset, diagonal, x, out):
    """out = A x from the node-pair layout: ``data`` holds the blocks (I, J > I) 2 x 2 each, then a_(2I, 2I+1)
    from ``pair_offset`` on.  Each row's sum and each scatter in the order of :func:`_symmetric_matvec`."""
    for i in range(x.shape[0]):
        out[_u(i)] = diagonal[_u(i)] * x[_u(i)]
    for I in range(block_indptr.shape[0] - 1):
        i = 2 * I
        x0, x1 = x[_u(i)], x[_u(i + 1)]
        a = data[_u(pair_offset + I)]
        s = out[_u(i)] + a * x1
        out[_u(i + 1)] += a * x0
        for k in range(block_indptr[_u(I)], block_indptr[_u(I + 1)]):
            j = 2 * block_indices[_u(k)]
            a = data[_u(4 * k)]
            s += a * x[_u(j)]
            out[_u(j)] += a * x0
            a = data[_u(4 * k + 1)]
            s += a * x[_u(j + 1)]
            out[_u(j + 1)] += a * x0
        out[_u(i)] = s
        s = out[_u(i + 1)]
        for k in range(block_indptr[_u(I)], block_indptr[_u(I + 1)]):
            j = 2 * block_indices[_u(k)]
            a = data[_u(4 * k + 2)]
            s += a * x[_u(j)]
            out[_u(j)] += a * x1
            a = data[_u(4 * k + 3)]
            s += a * x[_u(j + 1)]
            out[_u(j + 1)] += a * x1
        out[_u(i + 1)] = s


@njit(cache=True, inline="always")
def row_of(indptr, p):
    """The row i of a CSR matrix holding the entry at position ``p``: indptr[i] <= p < indptr[i + 1] (bisection)."""
    lo, hi = 0, indptr.shape[0] - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if indptr[_u(mid)] <= p:
            lo = mid
        else:
            hi = mid
    return lo


@njit(cache=True)
def _gather_or_zero(values, positions, out):
    """out[k] = values[positions[k]], or 0 where positions[k] is -1."""
    for k in range(positions.shape[0]):
        p = positions[_u(k)]
        out[_u(k)] = values[_u(p)] if p >= 0 else 0.0


@njit(cache=True)
def diagonal_positions(indptr, indices, diagonal):
    """diagonal[i]: the position of a_ii (the last one stored), or -1, in a CSR pattern (or of the diagonal
    block in a BSR one)."""
    for i in range(indptr.shape[0] - 1):
        diagonal[_u(i)] = -1
        for k in range(indptr[_u(i)], indptr[_u(i + 1)]):
            if indices[_u(k)] == i:
                diagonal[_u(i)] = k


class NodeBlockPattern(SymmetricPattern):
    """:class:`SymmetricPattern` in node blocks of ``size`` dofs: the strict upper triangle as size x size blocks
    (I, J > I), one column index per block, then the couplings inside each node (``positions``), the product by
    the subclass's kernel ``_matvec``.  :class:`NodePairPattern` (2-D) and :class:`NodeTriplePattern` (3-D)."""

    #: dofs per node
    size: int
    #: the product kernel: (block_indptr, block_indices, data, inner_offset, diagonal, x, out)
    _matvec = None

    def _block_columns(self, indptr: np.ndarray, pattern: sp.csr_matrix, blocks) -> type:
        """Set ``block_indptr`` and ``block_indices`` (each node's block columns J > I, listed by the kernel
        ``blocks``: counted first, then filled) and return the index dtype of the pattern's positions."""
        nb = pattern.shape[0] // self.size
        self.block_indptr = np.empty(nb + 1, dtype=np.int64)
        blocks(indptr, pattern.indices, self.block_indptr, np.empty(0, dtype=np.int64))
        self.block_indices = np.empty(self.block_indptr[-1], dtype=np.int64)
        blocks(indptr, pattern.indices, self.block_indptr, self.block_indices)
        self.block_indices = self.block_indices.astype(np.int32 if nb < 2**31 - 1 else np.int64)
        return np.int32 if pattern.nnz < 2**31 - 1 else np.int64

    def _gather(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The layout's values (zeros where the pattern stores nothing) and the diagonal."""
        data = np.empty(self.positions.size, dtype=values.dtype)
        _gather_or_zero(values, self.positions, data)
        return data, self._diagonal_values(values)

    def _apply(self, data: np.ndarray, diagonal: np.ndarray):
        """x -> A x from the layout's values ``data`` and the ``diagonal``."""
        offset, matvec = self.size * self.size * self.block_indices.size, self._matvec

        def apply(x, out=None):
            out = np.empty(self.shape[0]) if out is None else out
            matvec(self.block_indptr, self.block_indices, data, offset, diagonal,
                   np.ascontiguousarray(x, dtype=float), out)
            return out
        apply.writes_into = True
        apply.values = (data, diagonal)
        return apply


class NodePairPattern(NodeBlockPattern):
    """:class:`SymmetricPattern` for a matrix numbered node by node with two dofs per node (2-D vector problems).

    The strict upper triangle is stored as 2 x 2 blocks (I, J > I), one column index per block, plus the
    coupling a_(2I, 2I+1) inside each node: a product reads about a quarter fewer bytes (1e6 unknowns:
    0.012 -> 0.009 s) and gives :class:`SymmetricPattern`'s values bit for bit (the same sums and scatters in
    the same order; an entry the pattern does not store is a zero, which changes no sum).
    """

    size, _matvec = 2, staticmethod(_pair_matvec)

    def __init__(self, pattern: sp.csr_matrix):
        n = pattern.shape[0]
        if n % 2:
            raise ValueError(f"a node-pair pattern needs an even order, got {n}")
        indptr = np.asarray(pattern.indptr, dtype=np.int64)
        nb = n // 2
        index = self._block_columns(indptr, pattern, _pair_blocks)
        self.positions = np.empty(4 * self.block_indices.size + nb, dtype=index)   # blocks, then the pairs
        pair = np.empty(nb, dtype=np.int64)
        _pair_positions(indptr, pattern.indices, self.block_indptr, self.block_indices,
                        self.positions[:4 * self.block_indices.size], pair)
        self.positions[4 * self.block_indices.size:] = pair
        self.diagonal = np.empty(n, dtype=np.int64)
        diagonal_positions(indptr, pattern.indices, self.diagonal)
        self.shape = pattern.shape



# ---------------------------------------------------------------- node triples (3-D vector problems)
@njit(cache=True)
def _triple_blocks(indptr, indices, block_indptr, block_indices):
    """Count (``block_indices`` empty) or list the block columns J > I of each node I (rows 3I, 3I + 1,
    3I + 2, each sorted), ascending and once each."""
    w = 0
    none = 1 << 62
    for I in range(block_indptr.shape[0] - 1):
        block_indptr[_u(I)] = w
        a0, a1, a2 = indptr[_u(3 * I)], indptr[_u(3 * I + 1)], indptr[_u(3 * I + 2)]
        e0, e1, e2 = a1, a2, indptr[_u(3 * I + 3)]
        last = -1
        while a0 < e0 or a1 < e1 or a2 < e2:
            j0 = indices[_u(a0)] // 3 if a0 < e0 else none
            j1 = indices[_u(a1)] // 3 if a1 < e1 else none
            j2 = indices[_u(a2)] // 3 if a2 < e2 else none
            J = min(j0, j1, j2)
            a0 += j0 == J
            a1 += j1 == J
            a2 += j2 == J
            if J > I and J != last:
                if w < block_indices.shape[0]:
                    block_indices[_u(w)] = J
                w += 1
                last = J
    block_indptr[_u(block_indptr.shape[0] - 1)] = w


@njit(cache=True)
def _triple_positions(indptr, indices, block_indptr, block_indices, positions, inner):
    """positions[9k + 3r + c]: where a_(3I+r, 3J+c) of block k = (I, J > I) sits in the pattern (-1: not
    stored); inner[3I + q]: where a_(3I, 3I+1), a_(3I, 3I+2), a_(3I+1, 3I+2) sit (q = 0, 1, 2; -1: not stored)."""
    positions[:] = -1
    inner[:] = -1
    for I in range(block_indptr.shape[0] - 1):
        for r in range(3):
            i = 3 * I + r
            k = block_indptr[_u(I)]
            for q in range(indptr[_u(i)], indptr[_u(i + 1)]):
                j = indices[_u(q)]
                if i < j < 3 * I + 3:
                    inner[_u(3 * I + r + j - 3 * I - 1)] = q
                elif j >= 3 * I + 3:
                    while block_indices[_u(k)] < j // 3:
                        k += 1
                    positions[_u(9 * k + 3 * r + j - 3 * (j // 3))] = q


@njit(cache=True)
def _triple_entries(indptr, indices, block_indptr, block_indices, entries, layout, rows):
    """For each pattern position in ``entries``: layout[q], its place in the node-triple layout's values (the
    blocks, then the inner entries from 9 * (number of blocks) on; -1 for an entry on or below the diagonal),
    and rows[q], its row if it is a diagonal entry (else -1)."""
    offset = 9 * block_indices.shape[0]
    for q in range(entries.shape[0]):
        p = entries[_u(q)]
        i, j = row_of(indptr, p), indices[_u(p)]
        I, r = i // 3, i - 3 * (i // 3)
        layout[_u(q)], rows[_u(q)] = -1, -1
        if j == i:
            rows[_u(q)] = i
        elif i < j < 3 * I + 3:
            layout[_u(q)] = offset + 3 * I + r + j - 3 * I - 1
        elif j >= 3 * I + 3:
            for k in range(block_indptr[_u(I)], block_indptr[_u(I + 1)]):
                if block_indices[_u(k)] == j // 3:
                    layout[_u(q)] = 9 * k + 3 * r + j - 3 * (j // 3)
                    break


@njit(cache=True)
def _triple_matvec(block_indptr, block_indices, data, inner_offset, diagonal, x, out):
    """out = A x from the node-triple layout: ``data`` holds the blocks (I, J > I) 3 x 3 each (rows in turn),
    then a_(3I, 3I+1), a_(3I, 3I+2), a_(3I+1, 3I+2) from ``inner_offset`` on.  Each row's sum and each
    scatter in the order of :func:`_symmetric_matvec`: the node's inner entries first (row 3I's scatters
    reach rows 3I + 1 and 3I + 2 before their sums start), then each block's three rows, whose sums and
    scatters (into out[3J + c]: rows 3I, 3I + 1, 3I + 2 in turn) are kept in scalars."""
    for i in range(x.shape[0]):
        out[_u(i)] = diagonal[_u(i)] * x[_u(i)]
    for I in range(block_indptr.shape[0] - 1):
        i = 3 * I
        x0, x1, x2 = x[_u(i)], x[_u(i + 1)], x[_u(i + 2)]
        at = inner_offset + i
        a01, a02, a12 = data[_u(at)], data[_u(at + 1)], data[_u(at + 2)]
        s0 = out[_u(i)]
        s0 += a01 * x1
        out[_u(i + 1)] += a01 * x0
        s0 += a02 * x2
        out[_u(i + 2)] += a02 * x0
        s1 = out[_u(i + 1)]
        s1 += a12 * x2
        out[_u(i + 2)] += a12 * x1
        s2 = out[_u(i + 2)]
        for k in range(block_indptr[_u(I)], block_indptr[_u(I + 1)]):
            j = 3 * block_indices[_u(k)]
            y0, y1, y2 = x[_u(j)], x[_u(j + 1)], x[_u(j + 2)]
            at = 9 * k
            b00, b01, b02 = data[_u(at)], data[_u(at + 1)], data[_u(at + 2)]
            b10, b11, b12 = data[_u(at + 3)], data[_u(at + 4)], data[_u(at + 5)]
            b20, b21, b22 = data[_u(at + 6)], data[_u(at + 7)], data[_u(at + 8)]
            s0 += b00 * y0
            s0 += b01 * y1
            s0 += b02 * y2
            s1 += b10 * y0
            s1 += b11 * y1
            s1 += b12 * y2
            s2 += b20 * y0
            s2 += b21 * y1
            s2 += b22 * y2
            out[_u(j)] = _scatter(out[_u(j)], b00, b10, b20, x0, x1, x2)
            out[_u(j + 1)] = _scatter(out[_u(j + 1)], b01, b11, b21, x0, x1, x2)
            out[_u(j + 2)] = _scatter(out[_u(j + 2)], b02, b12, b22, x0, x1, x2)
        out[_u(i)] = s0
        out[_u(i + 1)] = s1
        out[_u(i + 2)] = s2


@njit(cache=True, inline="always")
def _scatter(t, a0, a1, a2, x0, x1, x2):
    """t + a0 x0 + a1 x1 + a2 x2, added one by one (a block column's three rows in turn)."""
    t += a0 * x0
    t += a1 * x1
    t += a2 * x2
    return t


class NodeTriplePattern(NodeBlockPattern):
    """:class:`SymmetricPattern` for a matrix numbered node by node with three dofs per node (3-D vector
    problems).

    The strict upper triangle is stored as 3 x 3 blocks (I, J > I), one column index per block, plus the
    three couplings inside each node.  The product's sums and scatters are those of
    :class:`SymmetricPattern` in the same order, so its values are the same bit for bit (an entry the
    pattern does not store is a zero, which changes no sum); held in scalars a block at a time, it took
    6.5 ms against 8.3 ms at h = 1/32 (3.1e5 unknowns, the block3d scene).
    """

    size, _matvec = 3, staticmethod(_triple_matvec)

    def __init__(self, pattern: sp.csr_matrix):
        n = pattern.shape[0]
        if n % 3:
            raise ValueError(f"a node-triple pattern needs an order divisible by 3, got {n}")
        indptr = np.asarray(pattern.indptr, dtype=np.int64)
        index = self._block_columns(indptr, pattern, _triple_blocks)
        self.positions = np.empty(9 * self.block_indices.size + n, dtype=index)   # blocks, then the inner entries
        inner = np.empty(n, dtype=np.int64)
        _triple_positions(indptr, pattern.indices, self.block_indptr, self.block_indices,
                          self.positions[:9 * self.block_indices.size], inner)
        self.positions[9 * self.block_indices.size:] = inner
        self.upper = self.positions       # each value's place in the pattern, as SymmetricPattern.upper
        self.diagonal = np.empty(n, dtype=np.int64)
        diagonal_positions(indptr, pattern.indices, self.diagonal)
        self.shape = pattern.shape
        self._pattern = (indptr, pattern.indices)

    def _entries(self, entries: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(k, i): the layout's places k and the rows i whose diagonal lie among the pattern's positions
        ``entries``, both ascending (:meth:`SymmetricPattern._entries` for this layout)."""
        entries = np.asarray(entries, dtype=np.int64)
        layout, rows = np.empty(entries.size, dtype=np.int64), np.empty(entries.size, dtype=np.int64)
        _triple_entries(*self._pattern, self.block_indptr, self.block_indices, entries, layout, rows)
        return np.sort(layout[layout >= 0]), np.sort(rows[rows >= 0])



def pencil_products(pencil, blocksize: int = 1):
    """rho -> (x -> (K + rho D) x) for a :class:`admmkit.linalg.amg.PencilMatrix` in CSR: from the upper triangle
    (:class:`SymmetricPattern`, in node pairs for ``blocksize`` 2: a 2-D vector problem numbered node by node,
    in node triples (:class:`NodeTriplePattern`) for ``blocksize`` 3: a 3-D one; a new rho updates D's entries
    only), or scipy's product with ``pencil.at(rho)`` without numba (or under
    :func:`admmkit.kernels.library_kernels`)."""
    from ..kernels import hand_written
    if not hand_written():
        return lambda rho: pencil.at(rho).__matmul__
    if blocksize == 2:
        return NodePairPattern(pencil.pattern).pencil_products(pencil.K_data, pencil.D_data)
    # D's few entries where the pencil knows them (not a gather of D's whole, mostly zero, values)
    entries = pencil.changed_entries() if hasattr(pencil, "changed_entries") else None
    kind = NodeTriplePattern if blocksize == 3 else SymmetricPattern
    return kind(pencil.pattern).pencil_products(pencil.K_data, pencil.D_data, entries)
