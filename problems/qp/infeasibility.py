"""Infeasibility certificates from successive ADMM iterates (Banjac, Goulart, Stellato & Boyd 2019; OSQP ``auxil.c``).

When a QP is primal infeasible, dy = y^{k+1} - y^k converges to a nonzero
certificate; when it is dual infeasible (unbounded below), dx = x^{k+1} - x^k
does.  Both are tested in the user's problem, normalised by their inf-norm:

    primal:  A'dy ~ 0  and  S(dy) = u' max(dy, 0) + l' min(dy, 0) < 0,                       (I1)
             ||A'dy||_inf < eps_prim_inf ||dy||_inf, after dy is projected onto the
             polar of the recession cone of [l, u] (OSQP_ZERO... as OSQP);
    dual:    q'dx < 0,  ||P dx||_inf < eps_dual_inf ||dx||_inf  and  A dx in the recession     (I2)
             cone of [l, u]: (A dx)_i <= eps ||dx|| where u_i < inf, >= -eps ||dx|| where l_i > -inf.

A primal certificate proves that no x has l <= A x <= u (Farkas: for such x,
dy'A x <= S(dy) < 0 contradicts A'dy = 0); a dual one is a direction along
which the objective decreases without bound while staying feasible.

Tests (I1)-(I2) pass to a tolerance (OSQP's 1e-4), and a feasible, bounded QP
can pass them: on PRIMALC1, 2 and 5 a dx with ||P dx|| = 7e-6 and q'dx = -1
passed, though the objective along it turns up after t ~ 1e5.  So a
candidate is confirmed before it is declared, by the exact conditions as
linear programs in the user's (unscaled) data, solved by HiGHS:

    primal:  min S(y)  s.t.  A'y = 0,  |y| <= 1,  y_i >= 0 where l_i = -inf, <= 0 where u_i = inf    (C1)
    dual:    min q'd   s.t.  P d = 0,  |d| <= 1,  (A d)_i <= 0 where u_i < inf, >= 0 where l_i > -inf (C2)

A negative optimum (below CONFIRM_TOL relative to the data) is an exact
certificate, which is the one returned; an optimum of 0 proves there is
none, and the loop goes on.  The verdict belongs to the problem, not to the
iterates, so it is computed once per QP.
"""
from __future__ import annotations

import numpy as np

from admmkit.loop.segments import AVAILABLE as NUMBA      # numba installed (asked once, without importing it)

from .problem import QP

#: OSQP_DIVISION_TOL = 1 / OSQP_INFTY
DIVISION_TOL = 1e-30
#: a confirming LP's optimum must be below -CONFIRM_TOL x (the scale of q, or of the finite bounds)
CONFIRM_TOL = 1e-7


def _inf(v: np.ndarray) -> float:
    return float(np.max(np.abs(v), initial=0.0))


def project_polar_recession_cone(dy: np.ndarray, l: np.ndarray, u: np.ndarray) -> np.ndarray:
    """dy with components pushing against an infinite bound set to 0 (OSQPVectorf_project_polar_reccone)."""
    dy = np.where(np.isinf(u), np.minimum(dy, 0.0), dy)
    return np.where(np.isinf(l), np.maximum(dy, 0.0), dy)


def _support(dy: np.ndarray, l: np.ndarray, u: np.ndarray) -> float:
    pos, neg = np.maximum(dy, 0.0), np.minimum(dy, 0.0)
    return float(np.where(pos > 0, u, 0.0) @ pos + np.where(neg < 0, l, 0.0) @ neg)


def primal_certificate(qp: QP, dy: np.ndarray, eps: float) -> np.ndarray | None:
    """The normalised certificate (I1) if ``dy`` (a change of the user's y) proves primal infeasibility, else None.

    In one compiled pass where numba is installed (``infeasibility_kernel``)."""
    if NUMBA:
        from .infeasibility_kernel import primal_candidate
        out = np.empty(qp.m)
        A = qp.A
        return out if primal_candidate(A.indptr, A.indices, A.data, qp.l, qp.u, np.asarray(dy, dtype=float),
                                       float(eps), out) else None
    dy = project_polar_recession_cone(np.asarray(dy, dtype=float), qp.l, qp.u)
    norm = _inf(dy)
    if norm <= DIVISION_TOL:
        return None
    dy = dy / norm
    if _support(dy, qp.l, qp.u) < 0.0 and _inf(qp.At @ dy) < eps:
        return dy
    return None


def dual_certificate(qp: QP, dx: np.ndarray, eps: float) -> np.ndarray | None:
    """The normalised certificate (I2) if ``dx`` (a change of the user's x) proves dual infeasibility, else None.

    In one compiled pass where numba is installed (``infeasibility_kernel``)."""
    dx = np.asarray(dx, dtype=float)
    if NUMBA:
        from .infeasibility_kernel import dual_candidate
        out = np.empty(qp.n)
        P, A = qp.P, qp.A
        return out if dual_candidate(P.indptr, P.indices, P.data, qp.q, A.indptr, A.indices, A.data, qp.l, qp.u,
                                     dx, float(eps), out) else None
    norm = _inf(dx)
    if norm <= DIVISION_TOL:
        return None
    dx = dx / norm
    if not (qp.q @ dx < 0.0 and _inf(qp.P @ dx) < eps):
        return None
    Adx = qp.A @ dx
    if np.any(np.isfinite(qp.u) & (Adx > eps)) or np.any(np.isfinite(qp.l) & (Adx < -eps)):
        return None
    return dx


def check_primal_certificate(qp: QP, y: np.ndarray) -> dict:
    """What makes ``y`` a primal infeasibility certificate, normalised by ||y||_inf: ||A'y||_inf and S(y) (want ~0 and < 0)."""
    y = np.asarray(y, dtype=float) / max(_inf(y), DIVISION_TOL)
    return {"At_y": _inf(qp.At @ y), "support": _support(y, qp.l, qp.u),
            "pushes_infinite_bound": bool(np.any((y > 0) & np.isinf(qp.u)) or np.any((y < 0) & np.isinf(qp.l)))}


def check_dual_certificate(qp: QP, x: np.ndarray) -> dict:
    """What makes ``x`` a dual infeasibility certificate, normalised: ||P x||_inf, q'x (< 0), and the worst violation of
    A x in the recession cone of [l, u]."""
    x = np.asarray(x, dtype=float) / max(_inf(x), DIVISION_TOL)
    Ax = qp.A @ x
    up = np.where(np.isfinite(qp.u), np.maximum(Ax, 0.0), 0.0)
    lo = np.where(np.isfinite(qp.l), np.maximum(-Ax, 0.0), 0.0)
    return {"P_x": _inf(qp.P @ x), "q_x": float(qp.q @ x), "cone_violation": max(_inf(up), _inf(lo))}


def iterate_deltas(qp: QP, rec) -> tuple[np.ndarray | None, np.ndarray]:
    """(dx, dy) of the user's problem between the record's iterate and the previous one.

    dy from the dual update's vector (public fields of the record): order xz
    lam^{k+1} - lam^k = rho (alpha A x^{k+1} + (1 - alpha) z^k - z^{k+1}),
    order zx rho (A x^{k+1} - alpha z^{k+1} - (1 - alpha) A x^k); dy = E M dlam / c.
    dx = D (x^{k+1} - x^k) from :meth:`QP.delta_x` (OSQP's relaxed x when the QP relaxes
    x), None when the QP does not know x^k.
    """
    dx = qp.delta_x(rec.x)
    if dx is not None and qp.scaled:
        dx = qp.scaling.unscale_x(dx)
    return dx, _dual_change(qp, rec)


def _dual_change(qp: QP, rec) -> np.ndarray:
    """dy = E M (lam^{k+1} - lam^k) / c from the record's public fields (one compiled pass in order xz)."""
    a = rec.alpha
    if rec.order == "xz":
        if NUMBA and (a == 1.0 or rec.z_prev is not None):
            from .infeasibility_kernel import dual_update_change
            ones, dy = qp._ones[0], np.empty(qp.m)
            E, c = (qp.scaling.E, qp.scaling.c) if qp.scaled else (ones, 1.0)
            dual_update_change(rec.rho, a, rec.Ax, rec.z if a == 1.0 else rec.z_prev, rec.z,
                               ones if qp.w is None else qp.w, E, c, dy)
            return dy
        hat = rec.Ax if a == 1.0 else a * rec.Ax + (1.0 - a) * rec.z_prev
        dlam = rec.rho * (hat - rec.z)
    else:
        hat = rec.z if a == 1.0 else a * rec.z + (1.0 - a) * rec.Ax_prev
        dlam = rec.rho * (rec.Ax - hat)
    return qp.multiplier(dlam)


def confirmed_certificate(qp: QP, kind: str) -> np.ndarray | None:
    """The exact certificate of (C1) (``kind="primal"``) or (C2) (``"dual"``) for ``qp``, or None if there is none.

    Cached on the QP: the answer depends on the data only.
    """
    cache = qp.__dict__.setdefault("_infeasibility_verdicts", {})
    if kind not in cache:
        cache[kind] = _confirm_primal(qp) if kind == "primal" else _confirm_dual(qp)
    return cache[kind]


def _confirm_primal(qp: QP) -> np.ndarray | None:
    """(C1) with y = yp - yn, yp, yn in [0, 1] (yp = 0 where u = inf, yn = 0 where l = -inf)."""
    import scipy.sparse as sp
    from scipy.optimize import linprog
    fin_u, fin_l = np.isfinite(qp.u), np.isfinite(qp.l)
    c = np.concatenate([np.where(fin_u, qp.u, 0.0), -np.where(fin_l, qp.l, 0.0)])
    At = sp.csr_matrix(qp.At)
    bounds = [(0.0, 1.0 if f else 0.0) for f in fin_u] + [(0.0, 1.0 if f else 0.0) for f in fin_l]
    res = linprog(c, A_eq=sp.hstack([At, -At]).tocsc(), b_eq=np.zeros(qp.n), bounds=bounds, method="highs")
    scale = max(1.0, float(np.max(np.abs(c), initial=0.0)))
    if res.status != 0 or res.fun >= -CONFIRM_TOL * scale:
        return None
    y = res.x[:qp.m] - res.x[qp.m:]
    return y / max(_inf(y), DIVISION_TOL)


def _confirm_dual(qp: QP) -> np.ndarray | None:
    """(C2): min q'd over |d| <= 1 with P d = 0 and A d in the recession cone of [l, u]."""
    import scipy.sparse as sp
    from scipy.optimize import linprog
    A = sp.csr_matrix(qp.A)
    fin_u, fin_l = np.isfinite(qp.u), np.isfinite(qp.l)
    A_ub = sp.vstack([A[fin_u], -A[fin_l]]).tocsc()
    res = linprog(qp.q, A_ub=A_ub if A_ub.shape[0] else None, b_ub=np.zeros(A_ub.shape[0]) if A_ub.shape[0] else None,
                  A_eq=sp.csc_matrix(qp.P) if qp.P.nnz else None, b_eq=np.zeros(qp.n) if qp.P.nnz else None,
                  bounds=[(-1.0, 1.0)] * qp.n, method="highs")
    scale = max(1.0, _inf(qp.q))
    if res.status != 0 or res.fun >= -CONFIRM_TOL * scale:
        return None
    return res.x / max(_inf(res.x), DIVISION_TOL)
