"""A[index][:, index] for a CSR matrix in one compiled pass over the selected rows (numba).

A finite element plug-in takes the rows and columns of its free dofs from
the assembled matrix, and the AMG x-step renumbers them node by node; scipy
does each as two fancy indexings (rows, then columns) and a sort.  At 1e6
unknowns (Example 1, 14e6 entries) ``K[free][:, free]`` took 0.9 s and the
node renumbering ``K[perm][:, perm]`` 1.0 s; :func:`principal_submatrix`
gives the same matrix (the same values at the same places, rows sorted) in a
single pass per row, sorting each short row by insertion.

Compiled only where it pays (issue #49): importing numba and loading these
two kernels costs about 0.7 s in a fresh process, where scipy's two steps
take 1 ms at Example 1, h = 1/40 (6,560 unknowns).  So ``compiled="auto"``
runs compiled when numba is imported in the process already or A has at least
:data:`COMPILED_MIN_NNZ` entries, and scipy otherwise: the same matrix, array
for array.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..kernels import _u, compiled_now, hand_written, njit

#: from this many entries of A, ``compiled="auto"`` takes the compiled pass even in a process without numba:
#: scipy's two steps cost about 64 ns an entry (0.9 s at 14e6), the compiled pass 7 ns plus ~0.7 s once
COMPILED_MIN_NNZ = 2_000_000


@njit(cache=True)
def _row_lengths(indptr, indices, rows, position, lengths):
    """lengths[i + 1] = the number of entries of row rows[i] whose column is kept (position >= 0)."""
    for i in range(rows.shape[0]):
        r = rows[_u(i)]
        count = 0
        for k in range(indptr[_u(r)], indptr[_u(r + 1)]):
            if position[_u(indices[_u(k)])] >= 0:
                count += 1
        lengths[_u(i + 1)] = count


@njit(cache=True)
def _fill_rows(indptr, indices, data, rows, position, out_indptr, out_indices, out_data):
    """Copy the kept entries of each selected row with their new columns, each row sorted by column."""
    for i in range(rows.shape[0]):
        r = rows[_u(i)]
        start = out_indptr[_u(i)]
        w = start
        for k in range(indptr[_u(r)], indptr[_u(r + 1)]):
            p = position[_u(indices[_u(k)])]
            if p >= 0:            # insertion into the sorted part of the row (rows hold a few dozen entries)
                v = data[_u(k)]
                j = w
                while j > start and out_indices[_u(j - 1)] > p:
                    out_indices[_u(j)] = out_indices[_u(j - 1)]
                    out_data[_u(j)] = out_data[_u(j - 1)]
                    j -= 1
                out_indices[_u(j)] = p
                out_data[_u(j)] = v
                w += 1


def principal_submatrix(A, index, compiled="auto") -> sp.csr_matrix:
    """B = A[index][:, index] in CSR with sorted rows: b_ij = a_(index_i, index_j).

    ``index``: distinct row numbers of the square matrix A (a selection such as
    the free dofs, or a permutation).  The values are copied, never summed, so
    B holds exactly A's numbers; A's duplicate entries, if any, stay duplicates.
    ``compiled``: True (the compiled pass, when numba is installed), False
    (scipy's fancy indexing) or "auto" (see the module docstring); the same B.
    """
    A = A if sp.issparse(A) and A.format == "csr" else sp.csr_matrix(A)
    n = A.shape[0]
    if A.shape != (n, n):
        raise ValueError(f"A must be square, got shape {A.shape}")
    index = np.asarray(index)
    if index.ndim != 1 or (index.size and not np.issubdtype(index.dtype, np.integer)):
        raise ValueError("index must be a one-dimensional array of integers")
    if index.size and (index.min() < 0 or index.max() >= n):
        raise ValueError(f"index must hold row numbers in 0..{n - 1}")
    position = np.full(n, -1, dtype=np.int64)
    position[index] = np.arange(index.size)
    if np.count_nonzero(position >= 0) != index.size:
        raise ValueError("index must not repeat a row")
    if compiled not in ("auto", True, False):
        raise ValueError(f"compiled must be 'auto', True or False, got {compiled!r}")
    if compiled == "auto":
        compiled = compiled_now() or A.nnz >= COMPILED_MIN_NNZ
    if not (hand_written() and compiled):   # scipy's indexing: the library path (no numba, library_kernels())
        return sp.csr_matrix(A[index][:, index], copy=True).sorted_indices()
    rows = index.astype(np.int64)
    indptr = np.asarray(A.indptr, dtype=np.int64)
    indices = np.asarray(A.indices)
    lengths = np.zeros(index.size + 1, dtype=np.int64)
    _row_lengths(indptr, indices, rows, position, lengths)
    out_indptr = np.cumsum(lengths)
    small = out_indptr[-1] < 2**31 - 1 and index.size < 2**31 - 1
    out_indices = np.empty(out_indptr[-1], dtype=np.int32 if small else np.int64)
    out_data = np.empty(out_indptr[-1], dtype=A.dtype)
    _fill_rows(indptr, indices, A.data, rows, position, out_indptr, out_indices, out_data)
    B = sp.csr_matrix((out_data, out_indices, out_indptr.astype(out_indices.dtype)), shape=(index.size, index.size))
    B.has_sorted_indices = True
    return B
