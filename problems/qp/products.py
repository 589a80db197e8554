"""The two products the loop asks of the QP's scaled A: A x and ||A' M y||, compiled where numba is installed.

scipy's ``A @ x`` costs about 8 us on a 5 x 8 matrix, most of it the
wrapper's checks; one compiled call costs about 1 us.  The loop asks for
A x at every iteration that runs in Python (every tested one) and for
||A' M y|| at the start (does the problem have it?) and in the last record,
so on the small Maros-Meszaros problems these wrappers were a visible part of
a whole solve.  The kernels sum in scipy's order
(:func:`admmkit.linalg.compiled.csc_matvec`, :func:`admmkit.linalg.compiled.csc_rmatvec`),
so the iterates are the same bits either way; scipy where compiled code is
not chosen (:func:`admmkit.kernels.compiled_now`: a small QP, or numba missing).
"""
from __future__ import annotations

import math

import numpy as np

from admmkit.kernels import compiled_now

from admmkit.linalg.compiled import csc_matvec, csc_rmatvec


def apply_A(A, x: np.ndarray) -> np.ndarray:
    """A x for the CSC matrix ``A``."""
    if A.format != "csc" or not compiled_now():
        return A @ x
    out = np.empty(A.shape[0])
    csc_matvec(A.indptr, A.indices, A.data, np.ascontiguousarray(x, dtype=np.float64), out)
    return out


def adjoint_norm(A, y: np.ndarray) -> float:
    """||A' y||_2 for the CSC matrix ``A``, without forming A' (scipy's ``A.T @ y`` sums the same way)."""
    if A.format != "csc" or not compiled_now():
        return float(np.linalg.norm(A.T @ y))
    out = np.empty(A.shape[1])
    csc_rmatvec(A.indptr, A.indices, A.data, np.ascontiguousarray(y, dtype=np.float64), out)
    return float(np.linalg.norm(out))
