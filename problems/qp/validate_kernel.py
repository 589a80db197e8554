"""The bounds of a QP checked in one compiled pass (numba): what :func:`admmkit.problems.qp.validate._validate`
asks of l and u.

In numpy the checks are five array operations (NaN in l, NaN in u, l = +inf or
u = -inf, l > u and its rows), about 25 us of overhead on a small QP, whose
whole solve is about a millisecond; this kernel answers them all in one pass.
Every answer is a comparison, so exactly numpy's.
"""
from __future__ import annotations

from admmkit.kernels import kernel


@kernel(cache=True)
def bound_facts(l, u):
    """(NaN in l, NaN in u, some l_i = +inf or u_i = -inf, the number of rows with l_i > u_i, the first such row
    or -1) of bounds of equal length."""
    nan_l, nan_u, wrong_inf, crossed, first = False, False, False, 0, -1
    for i in range(l.shape[0]):
        lo, up = l[i], u[i]
        if lo != lo:
            nan_l = True
        if up != up:
            nan_u = True
        if lo == float("inf") or up == -float("inf"):
            wrong_inf = True
        if lo > up:
            if first < 0:
                first = i
            crossed += 1
    return nan_l, nan_u, wrong_inf, crossed, first
