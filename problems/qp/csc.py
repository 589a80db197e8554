"""A scipy CSC matrix of arrays a kernel made canonical, without scipy's constructor checks.

scipy's ``csc_matrix((data, indices, indptr), shape)`` checks its arrays
(index dtypes, their extent, the pattern's format): 15-40 us, more than
qdldl's factorisation of a small QP's KKT matrix, and a whole solve builds
a few such matrices (the KKT matrix, the scaled P and A).  Where the arrays
come from a kernel of this package that makes them canonical (sorted row
indices, no duplicates, ``indptr`` consistent), :func:`csc_of` sets them on
a new matrix directly (about 2 us).  ``LIGHT`` False (or a scipy whose
matrices do not keep these attributes) takes scipy's constructor: the same
matrix, checked.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

#: build matrices of canonical arrays without the constructor's checks (False: scipy's constructor)
LIGHT = True


def _fields_known() -> bool:
    """Whether this scipy's CSC matrix keeps exactly the attributes :func:`csc_of` sets (checked once)."""
    M = sp.csc_matrix((np.ones(1), np.zeros(1, np.int32), np.array([0, 1], np.int32)), shape=(1, 1))
    return set(M.__dict__) <= {"_shape", "maxprint", "indices", "indptr", "data", "_has_canonical_format",
                               "_has_sorted_indices"} and {"_shape", "maxprint"} <= set(M.__dict__)


_KNOWN = _fields_known()


def csc_of(data: np.ndarray, indices: np.ndarray, indptr: np.ndarray, shape: tuple[int, int]) -> sp.csc_matrix:
    """The CSC matrix (data, indices, indptr) of ``shape``, whose arrays are canonical (row indices sorted within
    each column, no duplicates) and share their memory with the matrix; ``LIGHT``: no constructor checks."""
    if not (LIGHT and _KNOWN):
        M = sp.csc_matrix((data, indices, indptr), shape=shape, copy=False)
        M.has_canonical_format = True
        return M
    M = sp.csc_matrix.__new__(sp.csc_matrix)
    M.__dict__.update(_shape=(int(shape[0]), int(shape[1])), maxprint=50, data=data, indices=indices,
                      indptr=indptr, _has_canonical_format=True, _has_sorted_indices=True)
    return M
