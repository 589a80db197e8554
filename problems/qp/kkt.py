"""The KKT residuals of a QP answer in the user's problem (what ``QP.kkt`` and every result report)."""
from __future__ import annotations

import numpy as np

from admmkit.segments import AVAILABLE as NUMBA      # numba installed (asked once, without importing it)


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
        from .sparse_kernels import kkt_inf_norms
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
