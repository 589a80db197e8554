"""OSQP's penalty per row: the diagonal weights w of M (rho w_i is OSQP's rho_vec).

Equality rows weigh RHO_EQ_OVER_RHO_INEQ = 1e3, free rows (both bounds
infinite) FREE_ROW_WEIGHT, the others 1 (Stellato et al. 2020, section 5.2).
"""
from __future__ import annotations

import numpy as np

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
