"""Ruiz equilibration compiled (numba): the steps of :func:`admmkit.problems.qp.scaling.ruiz` in one call.

The same operations as the numpy steps in ``scaling.py``, entry by entry, with
one difference: the mean column norm of P is summed in order, as OSQP's
``vec_mean`` sums it, where numpy sums pairwise (the cost scaling c can then
differ in its last bits).  On a small QP the numpy steps cost about 0.3 ms
of Python overhead (ten steps of a dozen array operations); this kernel
costs microseconds.
"""
from __future__ import annotations

import numpy as np

from admmkit.kernels import kernel


@kernel(cache=True, inline="always")
def _limit(v, low, high):
    """OSQP's limit_scaling of one value: below ``low`` it counts as 1, above ``high`` as ``high``."""
    if v < low:
        return 1.0
    return min(v, high)


@kernel(cache=True)
def ruiz_steps(iterations, low, high, Pd, Pr, Pp, Ad, Ar, Ap, q, D, E):
    """``iterations`` Ruiz steps with cost scaling on the CSC arrays (data, rows, column pointers) of P and A and on
    q, D, E, in place, with OSQP's limits ``low``, ``high`` (MIN_SCALING, MAX_SCALING); returns the cost scaling c.
    The entries are visited in their stored order, column by column.

    Two passes over P per step: the first multiplies P by the last step's cost scaling (1 at the first step: no
    change) and takes the column maxima of its upper triangle, the second scales P <- D P D and takes the column
    maxima the cost scaling reads; the last step's cost scaling is applied after the loop (a product by 1 changes no
    bit).  Each entry gets the same operations in the same order as in four passes (read, scale by D, read, scale
    by c): the same bits."""
    n, m = D.shape[0], E.shape[0]
    d, e, cols = np.empty(n), np.empty(m), np.empty(n)
    c, c_step = 1.0, 1.0
    for _ in range(iterations):
        for j in range(n):                                 # KKT columns 1..n: triu(P), as OSQP stores it ...
            dj = 0.0
            for p in range(Pp[j], Pp[j + 1]):
                Pd[p] *= c_step                            # the last step's cost scaling, P <- c P (x 1: exact)
                if Pr[p] <= j:
                    dj = max(dj, abs(Pd[p]))
            d[j] = dj
        e[:] = 0.0
        for j in range(n):                                 # ... and A
            dj = d[j]
            for p in range(Ap[j], Ap[j + 1]):
                dj = max(dj, abs(Ad[p]))
                e[Ar[p]] = max(e[Ar[p]], abs(Ad[p]))       # KKT columns n+1..n+m: the rows of A
            d[j] = dj
        for j in range(n):
            d[j] = 1.0 / np.sqrt(_limit(d[j], low, high))
        for i in range(m):
            e[i] = 1.0 / np.sqrt(_limit(e[i], low, high))
        for j in range(n):                                 # P <- D P D, and the column maxima of its upper triangle
            dj, colj = d[j], 0.0
            for p in range(Pp[j], Pp[j + 1]):
                Pd[p] = (d[Pr[p]] * Pd[p]) * dj
                if Pr[p] <= j:
                    colj = max(colj, abs(Pd[p]))
            cols[j] = colj
        for j in range(n):                                 # A <- E A D
            dj = d[j]
            for p in range(Ap[j], Ap[j + 1]):
                Ad[p] = (e[Ar[p]] * Ad[p]) * dj
        qmax = 0.0
        for j in range(n):
            q[j] = d[j] * q[j]
            D[j] = D[j] * d[j]
            qmax = max(qmax, abs(q[j]))
        for i in range(m):
            E[i] = E[i] * e[i]
        total = 0.0
        for j in range(n):
            total += cols[j]
        c_step = 1.0 / _limit(max(total / n, _limit(qmax, low, high)), low, high)
        for j in range(n):
            q[j] = c_step * q[j]
        c *= c_step
    for p in range(Pd.shape[0]):                           # the last step's cost scaling
        Pd[p] *= c_step
    return c


@kernel(cache=True)
def has_tiny_rows(Ar, Ad, m, tiny):
    """Whether a row of A (CSC rows ``Ar``, data ``Ad``, m rows) has an inf-norm in (0, ``tiny``)."""
    nu = np.zeros(m)
    for p in range(Ad.shape[0]):
        nu[Ar[p]] = max(nu[Ar[p]], abs(Ad[p]))
    for i in range(m):
        if 0.0 < nu[i] < tiny:
            return True
    return False
