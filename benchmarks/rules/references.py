"""The references of the problem families: cvxpy models of the discrete problems, Clarabel's tight solves, their duals, and the active-set polish of an interior-point solution."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def active_set_polish(d, x, y):
    """Solve the equality-constrained QP on the active set read off an interior-point solution.

    Active: the equality rows, and the rows whose slack at the matching bound
    is smaller than their multiplier (upper: y > 0, lower: y < 0).  Solves the
    KKT system [[P, A_a'], [A_a, 0]] [x; y_a] = [-q; b_a] by sparse LU (as OSQP's
    polish does) and returns (x, y, kkt) if the result is feasible with
    multipliers of the right sign, else None.  An interior point method at
    tolerance 1e-10 leaves errors of 1e-9 to 1e-7 in x; the polished solution is
    exact up to round-off when the active set is right.
    """
    import scipy.sparse.linalg as spla

    Ax = d.A @ x
    scale = max(float(np.abs(y).max(initial=0.0)), 1e-300)
    eq = np.isfinite(d.l) & (d.l == d.u)
    up = ~eq & np.isfinite(d.u) & (y > 0) & ((d.u - Ax) < np.abs(y) / scale * 1e-3 + 1e-9 * (1 + np.abs(d.u)))
    lo = ~eq & np.isfinite(d.l) & (y < 0) & ((Ax - d.l) < np.abs(y) / scale * 1e-3 + 1e-9 * (1 + np.abs(d.l)))
    act = np.flatnonzero(eq | up | lo)
    b = np.where(lo, d.l, d.u)[act]
    Aa = d.A[act]
    kkt = sp.bmat([[d.P, Aa.T], [Aa, None]], format="csc")
    try:
        sol = spla.splu(kkt).solve(np.concatenate([-d.q, b]))
    except RuntimeError:          # singular: degenerate active set
        return None
    if not np.all(np.isfinite(sol)):
        return None
    xp, yp = sol[:d.n], np.zeros(d.A.shape[0])
    yp[act] = sol[d.n:]
    Axp = d.A @ xp
    tol = 1e-9 * (1 + np.abs(Axp))
    feasible = np.all(Axp <= d.u + tol) and np.all(Axp >= d.l - tol)
    signs = np.all(yp[up] >= -1e-9 * scale) and np.all(yp[lo] <= 1e-9 * scale)
    if not (feasible and signs):
        return None
    return xp, yp, _qp_kkt(d, xp, yp)


def _qp_kkt(d, x, y) -> dict:
    """Inf-norm KKT residuals of l <= Ax <= u at (x, y): dual, infeasibility."""
    Ax = d.A @ x
    return {"dual": float(np.abs(d.P @ x + d.q + d.A.T @ y).max()),
            "infeasibility": float(np.abs(Ax - np.clip(Ax, d.l, d.u)).max(initial=0.0))}


def cvxpy_problem(d):
    """(problem, x variable, [(constraint, sign, row indices)]) of the QP in cvxpy."""
    import cvxpy as cp

    x = cp.Variable(d.n)
    objective = 0.5 * cp.quad_form(x, cp.psd_wrap(d.P)) + d.q @ x
    cons = []
    identity = d.kind == "obstacle"
    fin_u, fin_l = np.flatnonzero(np.isfinite(d.u)), np.flatnonzero(np.isfinite(d.l))
    eq = np.flatnonzero(np.isfinite(d.l) & (d.l == d.u))
    fin_u = np.setdiff1d(fin_u, eq)
    fin_l = np.setdiff1d(fin_l, eq)
    for rows, sign, kind in ((fin_u, 1.0, "u"), (fin_l, -1.0, "l"), (eq, 1.0, "eq")):
        if rows.size == 0:
            continue
        expr = (x if rows.size == d.n else x[rows]) if identity else d.A[rows] @ x
        if kind == "u":
            con = expr <= d.u[rows]
        elif kind == "l":
            con = expr >= d.l[rows]
        else:
            con = expr == d.u[rows]
        cons.append((con, sign, rows))
    return cp.Problem(cp.Minimize(objective), [c for c, _, _ in cons]), x, cons


def cvxpy_duals(d, cons) -> np.ndarray:
    """The multiplier y of l <= Ax <= u (positive at an upper bound) from the cvxpy constraints."""
    y = np.zeros(d.A.shape[0])
    for con, sign, rows in cons:
        if con.dual_value is not None:
            y[rows] += sign * np.asarray(con.dual_value).ravel()
    return y


def clarabel_solve(d, tol: float, **options):
    """cvxpy + Clarabel at gap/feasibility tolerance ``tol``: (x, y, status, stats)."""
    import cvxpy as cp

    prob, x, cons = cvxpy_problem(d)
    prob.solve(solver=cp.CLARABEL, tol_gap_abs=tol, tol_gap_rel=tol, tol_feas=tol, max_iter=500, **options)
    if x.value is None:
        raise RuntimeError(f"Clarabel returned no solution (status {prob.status})")
    return np.asarray(x.value), cvxpy_duals(d, cons), prob.status, prob.solver_stats


def pdas_form(d):
    """(K, f, B, g) of min 1/2 u'Ku - f'u s.t. Bu <= g, and the map mu -> lam, for contact/obstacle."""
    if d.kind == "contact":
        return d.P, -d.q, d.A, d.u, (lambda mu: mu / d.weights)
    if d.kind == "obstacle":
        return d.P, -d.q, -sp.identity(d.n, format="csc"), -d.l, (lambda mu: -mu / d.weights)
    raise ValueError(f"PDAS applies to contact and obstacle problems, not {d.kind}")
