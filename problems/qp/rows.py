"""OSQP's penalty per row: the diagonal weights w of M (rho w_i is OSQP's rho_vec).

Equality rows weigh RHO_EQ_OVER_RHO_INEQ = 1e3, free rows (both bounds
infinite) FREE_ROW_WEIGHT, the others 1 (Stellato et al. 2020, section 5.2).
"""
from __future__ import annotations

import numpy as np

from admmkit.kernels import compiled_now, kernel
from admmkit.loop.segments import AVAILABLE as NUMBA      # numba installed (asked once, without importing it)

#: OSQP_RHO_EQ_OVER_RHO_INEQ: weight of an equality row
EQ_ROW_WEIGHT = 1e3
#: weight in M of a row with both bounds infinite (its residual and lam are 0 after one iteration)
FREE_ROW_WEIGHT = 1e-5
#: OSQP_RHO_MIN: the x-step's penalty of a free row, whatever rho is (Q5)
FREE_ROW_PENALTY = 1e-6
#: OSQP_RHO_TOL: a row with u - l below this (in the scaled problem) is an equality row
EQ_TOL = 1e-4
ROW_WEIGHTS = ("uniform", "osqp")


def row_weights(l: np.ndarray, u: np.ndarray, kind: str = "osqp") -> np.ndarray | None:
    """The diagonal w of M: None for "uniform"; for "osqp" 1e3 on equality rows, FREE_ROW_WEIGHT on free rows, else 1."""
    if kind not in ROW_WEIGHTS:
        raise ValueError(f"row_weights must be one of {', '.join(ROW_WEIGHTS)}, got {kind!r}")
    if kind == "uniform":
        return None
    free = np.isinf(l) & np.isinf(u)
    with np.errstate(invalid="ignore"):
        eq = ~free & (u - l < EQ_TOL)
    w = np.ones(l.size)
    w[eq], w[free] = EQ_ROW_WEIGHT, FREE_ROW_WEIGHT
    return w


def weights_and_free_rows(l: np.ndarray, u: np.ndarray, kind: str = "osqp") -> tuple[np.ndarray | None, np.ndarray]:
    """(w, the free rows' indices) of the bounds l, u: :func:`row_weights` and, under "osqp", the rows with both
    bounds infinite (none under "uniform": no row has its own penalty).  Where compiled code runs, one pass of
    :func:`osqp_weights` (the same numbers) instead of a dozen numpy calls on a small QP."""
    if kind == "osqp" and NUMBA and compiled_now():
        return osqp_weights(l, u, EQ_TOL, EQ_ROW_WEIGHT, FREE_ROW_WEIGHT)
    w = row_weights(l, u, kind)
    free = np.flatnonzero(np.isinf(l) & np.isinf(u)) if w is not None else np.empty(0, int)
    return w, free


@kernel(cache=True)
def osqp_weights(l, u, eq_tol, eq_weight, free_weight):
    """OSQP's row weights of the bounds l, u (``eq_weight`` where u - l < ``eq_tol``, ``free_weight`` where both are
    infinite, else 1) and the free rows' indices, in one pass."""
    m = l.shape[0]
    w = np.ones(m)
    free = np.empty(m, np.int64)
    count = 0
    for i in range(m):
        if np.isinf(l[i]) and np.isinf(u[i]):
            w[i] = free_weight
            free[count] = i
            count += 1
        elif u[i] - l[i] < eq_tol:
            w[i] = eq_weight
    return w, free[:count].copy()
