"""The KKT residuals of a QP answer in the user's problem (what ``QP.kkt`` and every result report), OSQP's (R1)-(R3)
with the support function S(y) of [l, u], and their relative form (``QP.kkt_relative``, the check of a stop)."""
from __future__ import annotations

import numpy as np

from admmkit.loop.segments import AVAILABLE as NUMBA      # numba installed (asked once, without importing it)

from .sparse_kernels import kkt_inf_norms, osqp_norms


def _inf(v) -> float:
    return float(np.max(np.abs(v), initial=0.0))


def kkt_residuals(qp, x: np.ndarray, z: np.ndarray, lam: np.ndarray) -> dict:
    """KKT residuals (inf-norms) of the user's QP at the user's x and the loop's (z, lam), OSQP's definitions and more.

    primal: ||A x - z||_inf (OSQP), infeasibility: distance of A x to the box,
    dual: ||P x + q + A' y||_inf, complementarity: max of y_i times the
    slack of the bound it pushes against, sign: max ``|y_i|`` pushing against
    an infinite bound; y = E M lam / c and z = E^-1 zb are the user's.
    """
    if qp.scaled:
        z = qp.scaling.unscale_z(z)
    y = qp.multiplier(lam)
    if NUMBA:                               # one compiled pass, the same values (small QPs: 3 us, not 60)
        P, A = qp.P, qp.A
        values = kkt_inf_norms(P.indptr, P.indices, P.data, qp.q, A.indptr, A.indices, A.data, qp.l, qp.u,
                               np.asarray(x, dtype=float), np.asarray(z, dtype=float), np.asarray(y, dtype=float))
        return dict(zip(("primal", "infeasibility", "dual", "complementarity", "sign"), map(float, values)))
    Ax = qp.A @ x
    y_pos, y_neg = np.maximum(y, 0.0), np.maximum(-y, 0.0)
    fin_u, fin_l = np.isfinite(qp.u), np.isfinite(qp.l)
    comp_u = y_pos[fin_u] * np.abs(qp.u[fin_u] - Ax[fin_u])
    comp_l = y_neg[fin_l] * np.abs(Ax[fin_l] - qp.l[fin_l])
    return {
        "primal": _inf(Ax - z),
        "infeasibility": _inf(Ax - np.clip(Ax, qp.l, qp.u)),
        "dual": _inf(qp.P @ x + qp.q + qp.At @ y),
        "complementarity": max(_inf(comp_u), _inf(comp_l)),
        "sign": max(_inf(y_pos[~fin_u]), _inf(y_neg[~fin_l])),
    }


#: OSQP_ZERO_DEADZONE in double precision
ZERO_DEADZONE = 1e-15


def support(y: np.ndarray, l: np.ndarray, u: np.ndarray, project: bool = True) -> float:
    """S(y) = u' max(y, 0) + l' min(y, 0); with ``project`` y is first projected as OSQP does (R3), else inf where
    y pushes against an infinite bound (N)."""
    y_pos, y_neg = np.maximum(y, 0.0), np.minimum(y, 0.0)
    if project:
        y_pos = np.where(np.isfinite(u) & (np.abs(y_pos) >= ZERO_DEADZONE), y_pos, 0.0)
        y_neg = np.where(np.isfinite(l) & (np.abs(y_neg) >= ZERO_DEADZONE), y_neg, 0.0)
    elif np.any(y_pos[~np.isfinite(u)] > 0) or np.any(y_neg[~np.isfinite(l)] < 0):
        return float("inf")
    up = np.where(y_pos != 0, u, 0.0)
    lo = np.where(y_neg != 0, l, 0.0)
    return float(up @ y_pos + lo @ y_neg)


def osqp_residuals(qp, x: np.ndarray, z: np.ndarray, y: np.ndarray, Ax: np.ndarray | None = None) -> dict:
    """(R1)-(R3) at (x, z, y) of the user's problem: residuals and the norms the relative tolerances scale with.

    Where numba is installed and no ``Ax`` is given, the norms come from one compiled pass
    (``sparse_kernels.osqp_norms``: the same values bit for bit, a small QP's 0.1 ms of numpy calls in a few us)
    and the three dot products from numpy, as below."""
    if NUMBA and Ax is None:
        P, A = qp.P, qp.A
        x = np.asarray(x, dtype=float)
        primal, primal_scale, dual, dual_scale, Px, up, y_pos, lo, y_neg = osqp_norms(
            P.indptr, P.indices, P.data, qp.q, A.indptr, A.indices, A.data, qp.l, qp.u,
            np.asarray(x, dtype=float), np.asarray(z, dtype=float), np.asarray(y, dtype=float), ZERO_DEADZONE)
        quad, lin, sup = float(x @ Px), float(qp.q @ x), float(up @ y_pos + lo @ y_neg)
        return {"primal": primal, "primal_scale": primal_scale, "dual": dual, "dual_scale": dual_scale,
                "gap": quad + lin + sup, "gap_scale": max(abs(quad), abs(lin), abs(sup))}
    return _osqp_residuals_numpy(qp, x, z, y, Ax)


def _osqp_residuals_numpy(qp, x, z, y, Ax=None) -> dict:
    """:func:`osqp_residuals` in numpy steps (without numba, or with a given A x)."""
    Ax = qp.A @ x if Ax is None else Ax
    Px = qp.P @ x
    Aty = qp.At @ y
    quad, lin, sup = float(x @ Px), float(qp.q @ x), support(y, qp.l, qp.u)
    return {
        "primal": _inf(Ax - z), "primal_scale": max(_inf(Ax), _inf(z)),
        "dual": _inf(Px + qp.q + Aty), "dual_scale": max(_inf(Px), _inf(Aty), _inf(qp.q)),
        "gap": quad + lin + sup, "gap_scale": max(abs(quad), abs(lin), abs(sup)),
    }


def kkt_relative(qp, x: np.ndarray, z: np.ndarray, lam: np.ndarray) -> dict:
    """The relative KKT measures of a QP answer, for :func:`admmkit.solve`'s check of a stop (``converged`` or
    ``converged_inaccurate``): OSQP's (R1)-(R3) in the user's problem, each divided by its own scale,

        primal  ||A x - z||_inf / max(||A x||_inf, ||z||_inf, 1),
        dual    ||P x + q + A'y||_inf / max(||P x||_inf, ||q||_inf, ||A'y||_inf, 1),
        gap     |x'Px + q'x + S(y)| / max(|x'Px|, |q'x|, |S(y)|, 1),

    at the user's x and the loop's (z, lam) (unscaled here: z = E^-1 zb, y = E M lam / c).  Each scale is
    floored at 1, as OSQP's test eps_abs + eps_rel scale is with eps_abs = eps_rel: where every term of a
    condition vanishes at the solution (TAME: P x = q = A'y = 0), a round-off residual of 1e-17 over a scale
    of 1e-17 is no error of 100 %.  Without these measures the check fell back on the ADMM residuals of the
    last record, which a relative-change stop can meet far from the QP's solution.
    """
    if qp.scaled:
        z = qp.scaling.unscale_z(z)
    res = osqp_residuals(qp, np.asarray(x, dtype=float), np.asarray(z, dtype=float), qp.multiplier(lam))
    return {name: _relative(abs(res[name]), res[name + "_scale"]) for name in ("primal", "dual", "gap")}


def _relative(residual: float, scale: float) -> float:
    """residual / max(scale, 1): relative where the scale exceeds 1, absolute below it."""
    return residual / max(scale, 1.0)
