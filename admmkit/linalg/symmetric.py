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
blocks for a 2-D vector problem (the same values, a quarter fewer bytes).
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


class NodePairPattern(SymmetricPattern):
    """:class:`SymmetricPattern` for a matrix numbered node by node with two dofs per node (2-D vector problems).

    The strict upper triangle is stored as 2 x 2 blocks (I, J > I), one column index per block, plus the
    coupling a_(2I, 2I+1) inside each node: a product reads about a quarter fewer bytes (1e6 unknowns:
    0.012 -> 0.009 s) and gives :class:`SymmetricPattern`'s values bit for bit (the same sums and scatters in
    the same order; an entry the pattern does not store is a zero, which changes no sum).
    """

    def __init__(self, pattern: sp.csr_matrix):
        n = pattern.shape[0]
        if n % 2:
            raise ValueError(f"a node-pair pattern needs an even order, got {n}")
        indptr = np.asarray(pattern.indptr, dtype=np.int64)
        nb = n // 2
        self.block_indptr = np.empty(nb + 1, dtype=np.int64)
        _pair_blocks(indptr, pattern.indices, self.block_indptr, np.empty(0, dtype=np.int64))
        self.block_indices = np.empty(self.block_indptr[-1], dtype=np.int64)
        _pair_blocks(indptr, pattern.indices, self.block_indptr, self.block_indices)
        self.block_indices = self.block_indices.astype(np.int32 if nb < 2**31 - 1 else np.int64)
        index = np.int32 if pattern.nnz < 2**31 - 1 else np.int64
        self.positions = np.empty(4 * self.block_indices.size + nb, dtype=index)   # blocks, then the pairs
        pair = np.empty(nb, dtype=np.int64)
        _pair_positions(indptr, pattern.indices, self.block_indptr, self.block_indices,
                        self.positions[:4 * self.block_indices.size], pair)
        self.positions[4 * self.block_indices.size:] = pair
        self.diagonal = np.empty(n, dtype=np.int64)
        diagonal_positions(indptr, pattern.indices, self.diagonal)
        self.shape = pattern.shape

    def _gather(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The layout's values (zeros where the pattern stores nothing) and the diagonal."""
        data = np.empty(self.positions.size, dtype=values.dtype)
        _gather_or_zero(values, self.positions, data)
        return data, self._diagonal_values(values)

    def _apply(self, data: np.ndarray, diagonal: np.ndarray):
        """x -> A x from the layout's values ``data`` and the ``diagonal``."""
        offset = 4 * self.block_indices.size

        def apply(x, out=None):
            out = np.empty(self.shape[0]) if out is None else out
            _pair_matvec(self.block_indptr, self.block_indices, data, offset, diagonal,
                         np.ascontiguousarray(x, dtype=float), out)
            return out
        apply.writes_into = True
        apply.values = (data, diagonal)
        return apply


def pencil_products(pencil, blocksize: int = 1):
    """rho -> (x -> (K + rho D) x) for a :class:`admmkit.linalg.amg.PencilMatrix` in CSR: from the upper triangle
    (:class:`SymmetricPattern`, in node pairs for ``blocksize`` 2: a 2-D vector problem numbered node by node;
    a new rho updates D's entries only), or scipy's product with ``pencil.at(rho)`` without numba (or under
    :func:`admmkit.kernels.library_kernels`)."""
    from ..kernels import hand_written
    if not hand_written():
        return lambda rho: pencil.at(rho).__matmul__
    if blocksize == 2:
        return NodePairPattern(pencil.pattern).pencil_products(pencil.K_data, pencil.D_data)
    # D's few entries where the pencil knows them (not a gather of D's whole, mostly zero, values)
    entries = pencil.changed_entries() if hasattr(pencil, "changed_entries") else None
    return SymmetricPattern(pencil.pattern).pencil_products(pencil.K_data, pencil.D_data, entries)
