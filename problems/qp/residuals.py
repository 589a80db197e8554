"""The residuals of a QP iterate: OSQP's (in the user's problem, from a possibly scaled iterate) and the neutral ones.

OSQP 1.x (``src/auxil.c``), for x, z, y of the user's problem:

    primal      ||A x - z||_inf,               scale max(||A x||_inf, ||z||_inf)              (R1)
    dual        ||P x + q + A'y||_inf,         scale max(||P x||_inf, ||A'y||_inf, ||q||_inf) (R2)
    gap         x'Px + q'x + S(y),             scale max(|x'Px|, |q'x|, |S(y)|)               (R3)

with S(y) = u' max(y, 0) + l' min(y, 0), the support function of [l, u],
after y is projected onto the polar of the recession cone of [l, u] (a
component pushing against an infinite bound is set to 0) and entries below
1e-15 are rounded to 0.  OSQP computes them on its scaled vectors and
unscales the norms (E^-1, D^-1, 1/c); so does :func:`iterate_residuals`.

The neutral criteria (qpbenchmark's, Caron et al.) judge any solver's (x, y)
in the user's problem with absolute tolerances:

    primal  ||A x - clip(A x, l, u)||_inf,  dual  ||P x + q + A'y||_inf,  gap  |x'Px + q'x + S(y)|   (N)

with y projected first: a harness sees no multiplier of an infinite bound, so
a component of y pushing against one is dropped (and counts in the dual residual).
"""
from __future__ import annotations

import numpy as np

from admmkit.loop.segments import AVAILABLE as NUMBA      # numba installed (asked once, without importing it)

from .kkt import ZERO_DEADZONE, osqp_residuals, support  # noqa: F401  (defined beside the KKT residuals; re-exported)
from .problem import QP
from .sparse_kernels import neutral_norms

def _inf(v: np.ndarray) -> float:
    return float(np.max(np.abs(v), initial=0.0))


def iterate_residuals(qp: QP, xb: np.ndarray, zb: np.ndarray, lam: np.ndarray, Axb: np.ndarray | None = None,
                      scaled: bool = False) -> dict:
    """(R1)-(R3) of the user's problem from the loop's iterate (xb, zb, lam), computed as OSQP does.

    With ``scaled=True`` the dict also holds OSQP's scaled quantities for its rho estimate:
    ``scaled_primal``, ``scaled_primal_scale``, ``scaled_dual``, ``scaled_dual_scale``.
    """
    Axb = qp.As @ xb if Axb is None else Axb
    yb = lam if qp.w is None else qp.w * lam
    Pxb = qp.Ps @ xb
    Atyb = qp.Ats @ yb
    r = Axb - zb
    s = Pxb + qp.qs + Atyb
    quad, lin, sup = float(xb @ Pxb), float(qp.qs @ xb), support(yb, qp.ls, qp.us)
    if qp.scaled:
        E, D, cinv = qp.scaling.E, qp.scaling.D, 1.0 / qp.scaling.c
        out = {"primal": _inf(r / E), "primal_scale": max(_inf(Axb / E), _inf(zb / E)),
               "dual": cinv * _inf(s / D), "dual_scale": cinv * max(_inf(Pxb / D), _inf(Atyb / D), _inf(qp.qs / D)),
               "gap": cinv * (quad + lin + sup), "gap_scale": cinv * max(abs(quad), abs(lin), abs(sup))}
    else:
        out = {"primal": _inf(r), "primal_scale": max(_inf(Axb), _inf(zb)),
               "dual": _inf(s), "dual_scale": max(_inf(Pxb), _inf(Atyb), _inf(qp.qs)),
               "gap": quad + lin + sup, "gap_scale": max(abs(quad), abs(lin), abs(sup))}
    if scaled:
        out.update(scaled_primal=_inf(r), scaled_primal_scale=max(_inf(Axb), _inf(zb)),
                   scaled_dual=_inf(s), scaled_dual_scale=max(_inf(Pxb), _inf(Atyb), _inf(qp.qs)))
    return out


def neutral_residuals(qp: QP, x: np.ndarray, y: np.ndarray) -> dict:
    """(N): the neutral criteria's primal residual, dual residual and duality gap of (x, y) in the user's problem.

    One compiled pass where numba is installed
    (``sparse_kernels.neutral_norms``: the same
    primal and dual, the gap's sums in order)."""
    if NUMBA and np.isfinite(x).all() and np.isfinite(y).all():
        P, A = qp.P, qp.A
        values = neutral_norms(P.indptr, P.indices, P.data, qp.q, A.indptr, A.indices, A.data, qp.l, qp.u,
                               np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        return dict(zip(("primal", "dual", "gap"), map(float, values)))
    Ax = qp.A @ x
    Px = qp.P @ x
    y = np.where(np.isinf(qp.u), np.minimum(y, 0.0), y)       # a harness sees no multiplier of an infinite bound
    y = np.where(np.isinf(qp.l), np.maximum(y, 0.0), y)
    return {"primal": _inf(Ax - np.clip(Ax, qp.l, qp.u)),
            "dual": _inf(Px + qp.q + qp.At @ y),
            "gap": abs(float(x @ Px + qp.q @ x) + support(y, qp.l, qp.u, project=False))}


def neutral_satisfied(res: dict, eps: float) -> bool:
    """All three of (N) at most ``eps`` (absolute)."""
    return res["primal"] <= eps and res["dual"] <= eps and res["gap"] <= eps
