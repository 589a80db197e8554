"""OSQP's infeasibility tests (I1), (I2) compiled (numba): one pass each instead of a dozen small numpy calls.

A QP that has not converged yet runs both tests at every check (every 25
iterations under OSQP's settings); in numpy they cost about 40 us of
Python on a small QP, more than 25 iterations of its compiled segment.
The same tests as :func:`admmkit.problems.qp.infeasibility.primal_certificate`
and ``dual_certificate``: the products summed as scipy sums them, the dot
products (the support S(dy) and q'dx) summed in order, as OSQP's C sums
them, where numpy's BLAS may sum in another order.  A candidate either way
is only declared once the exact LP confirms it.
"""
from __future__ import annotations

import numpy as np

from admmkit.kernels import kernel

from .sparse_kernels import _worse      # max(m, abs(v)) that keeps a NaN, as np.max does

#: OSQP_DIVISION_TOL
DIVISION_TOL = 1e-30


@kernel(cache=True)
def primal_candidate(Ap, Ai, Ax, l, u, dy, eps, out):
    """(I1): writes the normalised, projected dy into ``out`` and returns True if it is a certificate candidate."""
    m, n = dy.shape[0], Ap.shape[0] - 1
    norm = 0.0
    for i in range(m):
        v = min(dy[i], 0.0) if np.isinf(u[i]) else dy[i]         # onto the polar of the recession cone
        v = max(v, 0.0) if np.isinf(l[i]) else v
        out[i] = v
        norm = _worse(norm, v)
    if not norm > DIVISION_TOL:
        return False
    support = 0.0
    for i in range(m):
        out[i] = out[i] / norm
        if out[i] > 0.0:
            support += u[i] * out[i]
        elif out[i] < 0.0:
            support += l[i] * out[i]
    if not support < 0.0:
        return False
    worst = 0.0
    for j in range(n):                                            # ||A'dy||_inf, A' by the columns of A
        s = 0.0
        for p in range(Ap[j], Ap[j + 1]):
            s += Ax[p] * out[Ai[p]]
        worst = _worse(worst, s)
    return worst < eps


@kernel(cache=True)
def dual_candidate(Pp, Pi, Px, q, Ap, Ai, Ax, l, u, dx, eps, out):
    """(I2): writes the normalised dx into ``out`` and returns True if it is a certificate candidate."""
    n, m = dx.shape[0], l.shape[0]
    norm = 0.0
    for j in range(n):
        norm = _worse(norm, dx[j])
    if not norm > DIVISION_TOL:
        return False
    qd = 0.0
    for j in range(n):
        out[j] = dx[j] / norm
        qd += q[j] * out[j]
    if not qd < 0.0:
        return False
    Pd = np.zeros(n)
    for j in range(n):
        for p in range(Pp[j], Pp[j + 1]):
            Pd[Pi[p]] += Px[p] * out[j]
    for j in range(n):
        if not abs(Pd[j]) < eps:
            return False
    Ad = np.zeros(m)
    for j in range(n):
        for p in range(Ap[j], Ap[j + 1]):
            Ad[Ai[p]] += Ax[p] * out[j]
    for i in range(m):
        if (np.isfinite(u[i]) and Ad[i] > eps) or (np.isfinite(l[i]) and Ad[i] < -eps):
            return False
    return True


@kernel(cache=True)
def dual_update_change(rho, alpha, Ax, z_prev, z, w, E, c, out):
    """dy = E M dlam / c with dlam = lam^{k+1} - lam^k = rho (alpha A x^{k+1} + (1 - alpha) z^k - z^{k+1}) (order xz),
    into ``out``: the operations of :func:`admmkit.problems.qp.infeasibility.iterate_deltas`, entry by entry."""
    for i in range(z.shape[0]):
        hat = Ax[i] if alpha == 1.0 else alpha * Ax[i] + (1.0 - alpha) * z_prev[i]
        out[i] = (E[i] * (w[i] * (rho * (hat - z[i])))) / c
