"""An independent solve of the discrete Tresca problem by cvxpy (Clarabel), to check ADMM against.

The discrete problem (docs/friction.md) is the convex second-order cone program

    min  1/2 u'Ku - f'u + sum_i mc_i s_i |t_i|   s.t.  B u <= g,  t = T u - w,

with t_i in R^{d-1} the slip of contact node i.  Its multipliers are the
tractions: the inequality's dual is M_c p_n (p_n the pressure) and the
equality's dual is M_c q up to sign (q the tangential traction); the sign is
fixed by the stationarity K u - f + B'M_c p_n + T'M_c q = 0.
"""
from __future__ import annotations

import numpy as np

from admmkit.problems.contact.model.operators import ContactOperators


def tresca_cvxpy(ops: ContactOperators, s: np.ndarray | None = None, tol: float = 1e-12):
    """(u, p_n, q) of the Tresca problem of ``ops`` with slip bound ``s`` (default: ops.friction.s).

    q is (d-1, n_c).  Needs cvxpy with Clarabel; raises RuntimeError unless Clarabel reports optimal.
    Clarabel's defaults (and tolerances of 1e-10 alone) left u 2.5e-6 off on the 3D block, whose ADMM
    solution had the lower objective; gap and feasibility 1e-12 with iterative refinement to 1e-15,
    static regularisation 1e-12 and the objective scaled to O(1) bring u and q to ~1e-7.
    """
    import cvxpy as cp

    if ops.T is None:
        raise ValueError("ops: no tangential operator T (assemble a scene with this version)")
    n_c = ops.n_c
    s = ops.friction.s if s is None else np.asarray(s, dtype=float)
    k = ops.T.shape[0] // n_c
    w = np.zeros((n_c, k)) if ops.friction is None or ops.friction.slide is None else ops.friction.slide
    u = cp.Variable(ops.n_free)
    t = cp.Variable((k, n_c))
    normal = ops.B @ u <= ops.g
    slip = cp.reshape(ops.T @ u, (k, n_c), order="C") - w.T == t
    length = cp.abs(t[0]) if k == 1 else cp.norm(t, 2, axis=0)
    objective = 0.5 * cp.quad_form(u, cp.psd_wrap(ops.K.tocsc())) - ops.f @ u + (ops.mc * s) @ length
    # a first, rough solve gives the objective's size J; the accurate one minimises objective / |J|
    # (objectives of 1e-2 left q 1.3e-6 off the ADMM solution on the 3D block, scaled to O(1) 1.4e-7)
    cp.Problem(cp.Minimize(objective), [normal, slip]).solve(solver="CLARABEL")
    scale = 1.0 / max(abs(float(objective.value)), 1e-300)
    problem = cp.Problem(cp.Minimize(scale * objective), [normal, slip])
    problem.solve(solver="CLARABEL", tol_gap_abs=tol, tol_gap_rel=tol, tol_feas=tol, tol_ktratio=1e-10, max_iter=1000,
                  iterative_refinement_reltol=1e-15, iterative_refinement_abstol=1e-15,
                  static_regularization_constant=1e-12)
    if problem.status != "optimal":
        raise RuntimeError(f"Clarabel: {problem.status}")
    p_n = normal.dual_value / ops.mc / scale
    q = np.asarray(slip.dual_value).reshape(k, n_c) / ops.mc / scale
    # the sign of an equality's dual is a convention: take the one that satisfies stationarity
    base = ops.K @ u.value - ops.f + ops.B.T @ (ops.mc * p_n)
    plus = ops.T.T @ (ops.mc * q).ravel()
    if np.abs(base + plus).max() > np.abs(base - plus).max():
        q = -q
    return u.value, p_n, q
