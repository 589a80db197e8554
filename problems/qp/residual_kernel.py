"""OSQP's residuals of an iterate in one compiled pass (numba): what :func:`iterate_residuals` computes.

The loop tests termination every 25 iterations and OSQP's rule reads the
scaled residuals every 50; in numpy each test is a dozen array operations
and three sparse products, about 0.1 ms of Python overhead on a small QP.
This kernel makes the same products in the same order (scipy's CSC and CSR
mat-vecs), takes the inf-norms (exact in any order), and sums the three
inner products of the gap (x'Px, q'x, S(y)) in order, as OSQP's C does,
where numpy's BLAS sums them blockwise: the gap can differ in its last bits.
"""
from __future__ import annotations

import numpy as np

from admmkit.kernels import kernel

from admmkit.linalg.compiled import csc_matvec

from .kkt import ZERO_DEADZONE


@kernel(cache=True)
def _residuals(Pp, Pi, Pd, Ap, Ai, Ad, q, lo, up, w, E, D, xb, zb, lam, Axb):
    """(primal, primal scale, dual, dual scale, x'Px, q'x, S(y)) unscaled, then the four scaled norms."""
    n, m = xb.shape[0], zb.shape[0]
    Pxb = np.empty(n)
    csc_matvec(Pp, Pi, Pd, xb, Pxb)
    yb = np.empty(m)
    for i in range(m):
        yb[i] = lam[i] * w[i]
    primal = primal_scale = s_primal = s_primal_scale = 0.0
    s1 = s2 = 0.0
    for i in range(m):
        r = Axb[i] - zb[i]
        primal = max(primal, abs(r / E[i]))
        primal_scale = max(primal_scale, abs(Axb[i] / E[i]), abs(zb[i] / E[i]))
        s_primal = max(s_primal, abs(r))
        s_primal_scale = max(s_primal_scale, abs(Axb[i]), abs(zb[i]))
        y = yb[i]                                                   # S(y) with OSQP's projection (R3)
        if y > 0.0 and np.isfinite(up[i]) and abs(y) >= ZERO_DEADZONE:
            s1 += up[i] * y
        elif y < 0.0 and np.isfinite(lo[i]) and abs(y) >= ZERO_DEADZONE:
            s2 += lo[i] * y
    dual = dual_scale = s_dual = s_dual_scale = 0.0
    quad = lin = 0.0
    for j in range(n):
        a = 0.0                                                     # (A'y)_j, as scipy's CSR product of A'
        for p in range(Ap[j], Ap[j + 1]):
            a += Ad[p] * yb[Ai[p]]
        s = Pxb[j] + q[j] + a
        dual = max(dual, abs(s / D[j]))
        dual_scale = max(dual_scale, abs(Pxb[j] / D[j]), abs(a / D[j]), abs(q[j] / D[j]))
        s_dual = max(s_dual, abs(s))
        s_dual_scale = max(s_dual_scale, abs(Pxb[j]), abs(a), abs(q[j]))
        quad += xb[j] * Pxb[j]
        lin += q[j] * xb[j]
    return (primal, primal_scale, dual, dual_scale, quad, lin, s1 + s2,
            s_primal, s_primal_scale, s_dual, s_dual_scale)


def iterate_residuals_compiled(qp, xb, zb, lam, Axb=None, scaled: bool = False) -> dict:
    """:func:`admmkit.problems.qp.residuals.iterate_residuals` in one compiled pass (the same dict)."""
    ones_m, ones_n = qp._ones
    w = ones_m if qp.w is None else qp.w
    E, D, cinv = (qp.scaling.E, qp.scaling.D, 1.0 / qp.scaling.c) if qp.scaled else (ones_m, ones_n, 1.0)
    Ps, As = qp.Ps, qp.As
    if Axb is None:
        Axb = np.empty(qp.m)
        csc_matvec(As.indptr, As.indices, As.data, xb, Axb)
    (primal, primal_scale, dual, dual_scale, quad, lin, sup,
     sp_, sps, sd, sds) = _residuals(Ps.indptr, Ps.indices, Ps.data, As.indptr, As.indices, As.data, qp.qs,
                                     qp.ls, qp.us, w, E, D, xb, zb, lam, Axb)
    out = {"primal": primal, "primal_scale": primal_scale, "dual": cinv * dual, "dual_scale": cinv * dual_scale,
           "gap": cinv * (quad + lin + sup), "gap_scale": cinv * max(abs(quad), abs(lin), abs(sup))}
    if scaled:
        out.update(scaled_primal=sp_, scaled_primal_scale=sps, scaled_dual=sd, scaled_dual_scale=sds)
    return out
