"""An independent reference solve of a QP with cvxpy (Clarabel), for checks only."""
from __future__ import annotations

import numpy as np

from .problem import QP


def solve_with_cvxpy(qp: QP, solver: str = "CLARABEL", **solver_options) -> tuple[np.ndarray, np.ndarray, float]:
    """Return (x, lam, objective) of ``qp`` from cvxpy.

    lam follows admmkit's sign convention for l <= A x <= u (positive at an
    active upper bound, negative at an active lower bound).
    """
    import cvxpy as cp  # reference dependency, imported on use

    x = cp.Variable(qp.n)
    Ax = qp.A @ x
    fin_u, fin_l = np.isfinite(qp.u), np.isfinite(qp.l)
    upper = Ax[np.flatnonzero(fin_u)] <= qp.u[fin_u] if fin_u.any() else None
    lower = Ax[np.flatnonzero(fin_l)] >= qp.l[fin_l] if fin_l.any() else None
    cons = [con for con in (upper, lower) if con is not None]
    objective = 0.5 * cp.quad_form(x, cp.psd_wrap(qp.P)) + qp.q @ x + qp.r
    prob = cp.Problem(cp.Minimize(objective), cons)
    prob.solve(solver=solver, **solver_options)
    if prob.status not in ("optimal", "optimal_inaccurate"):
        raise RuntimeError(f"cvxpy/{solver} did not solve {qp.name}: status {prob.status}")
    lam = np.zeros(qp.m)
    if upper is not None:
        lam[fin_u] += upper.dual_value
    if lower is not None:
        lam[fin_l] -= lower.dual_value
    return np.asarray(x.value), lam, float(prob.value)
