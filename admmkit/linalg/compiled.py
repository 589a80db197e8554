"""Compiled kernels of sparse linear algebra, each the same operations as its Python twin.

Made with :func:`admmkit.kernels.kernel` (compiled, or run as Python, as
:func:`admmkit.kernels.compiled_now` says), written so that each
floating-point operation is the one the Python path does, in the same order:

- :func:`ldl_solve`: qdldl's solve with its own factors
  (``CachedFactorization.ldl``): x = P (I + L)^-T D^-1 (I + L)^-1 P' b, as
  ``QDLDL_solve`` does (column-oriented forward solve, multiplication by
  1/D, row-oriented backward solve);
- :func:`csc_matvec`: y = A x for a CSC matrix, as scipy's ``csc_matvec``
  (y = 0, then columns in order); :func:`csc_rmatvec`: A' y.

The kernels that call these are compiled anew when this module changes:
:mod:`admmkit.kernel_cache` stamps every cached kernel with the source of
every file that holds kernels.
"""
from __future__ import annotations

from ..kernels import _u, kernel


@kernel(cache=True, inline="always")
def ldl_forward(Lp, Li, Lx, x, start):
    """x <- (I + L)^{-1} x in place, column by column from ``start`` (x[:start] is zero)."""
    for j in range(start, x.shape[0]):
        xj = x[j]
        for p in range(_u(Lp[j]), _u(Lp[j + 1])):
            x[_u(Li[p])] -= Lx[p] * xj


@kernel(cache=True, inline="always")
def ldl_backward(Lp, Li, Lx, x):
    """x <- (I + L)^{-T} x in place, row by row from the last."""
    for j in range(x.shape[0] - 1, -1, -1):
        s = x[j]
        for p in range(_u(Lp[j]), _u(Lp[j + 1])):
            s -= Lx[p] * x[_u(Li[p])]
        x[j] = s


@kernel(cache=True)
def ldl_solve(Lp, Li, Lx, Dinv, perm, b, work, out):
    """out = K^-1 b with K = P (I + L) D (I + L)' P' (qdldl's factors); ``work`` is scratch of length n.

    ``b`` and ``out`` may be the same array.  Indices are read as unsigned
    (``_u``): numba then skips its negative-index test on every access
    (measured 40 % faster in these loops); the arithmetic is unchanged.
    """
    n = perm.shape[0]
    for i in range(n):
        work[i] = b[_u(perm[i])]
    ldl_forward(Lp, Li, Lx, work, 0)                    # (I + L) y = b, column by column
    for i in range(n):                                  # y <- D^-1 y
        work[i] *= Dinv[i]
    ldl_backward(Lp, Li, Lx, work)                      # (I + L)' x = y, row by row
    for i in range(n):
        out[_u(perm[i])] = work[i]


@kernel(cache=True)
def csc_matvec(indptr, indices, data, x, y):
    """y = A x for the CSC matrix (indptr, indices, data), summed as scipy sums it."""
    y[:] = 0.0
    for j in range(x.shape[0]):
        xj = x[j]
        for p in range(_u(indptr[j]), _u(indptr[j + 1])):
            y[_u(indices[p])] += data[p] * xj


@kernel(cache=True)
def csc_rmatvec(indptr, indices, data, y, out):
    """out = A' y for the CSC matrix (indptr, indices, data): column j's dot with y, summed as scipy sums the
    CSR product of A' (from 0, in the stored order)."""
    for j in range(out.shape[0]):
        s = 0.0
        for p in range(_u(indptr[j]), _u(indptr[j + 1])):
            s += data[p] * y[_u(indices[p])]
        out[j] = s
