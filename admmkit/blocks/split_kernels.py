"""The building blocks' compiled iteration (numba): :class:`admmkit.SplitProblem`'s steps, ``count`` times in one call.

One iteration of each order, as :mod:`admmkit.loop.steps`, ``SplitProblem`` and
:class:`admmkit.QuadraticXStep` compute it (w, b, v the temporaries they build)::

    order "xz":  w = M (rho (z + c) - lam);  b = A'w - q (+ sigma x);  x1 = K(rho)^-1 b     (12)
                 Ax1 = A x1;  h = alpha Ax1 + (1 - alpha)(z + c)
                 v = (h - c) + lam / rho;  z1 = prox_{g, 1/rho}^M(v)                      (11)
                 lam1 = lam + rho ((h - z1) - c)                                           (13)
    order "zx":  v = (Ax - c) + lam / rho;  z1 = prox(v);  h = alpha z1 + (1 - alpha)(Ax - c)
                 w = M (rho (h + c) - lam);  b = A'w - q (+ sigma x);  x1 = K(rho)^-1 b;  Ax1 = A x1
                 lam1 = lam + rho ((Ax1 - h) - c)

with h = Ax1 (xz) or z1 (zx) when alpha = 1 and the terms in c left out when
c = 0, as the Python steps leave them out.  Each line is the same
floating-point operations in the same order as the numpy it mirrors: A x and
A'w are scipy's ``csr_matvec`` (each row summed from 0 in storage order),
K(rho)^-1 b is qdldl's solve (:func:`admmkit.linalg.compiled.ldl_solve`) or the
diagonal solver's division, and the proxes below are numpy's elementwise
formulas (``np.maximum`` and ``np.minimum`` keep the second operand on a tie
and propagate a NaN; ``np.sign`` of a zero is +0).  An iteration whose
vectors are not all finite is not kept: the kernel returns before it, and the
loop's Python iteration meets the number where it would have anyway.
"""
from __future__ import annotations

import numpy as np

from ..kernels import all_finite, njit

from ..linalg.compiled import ldl_solve

#: the proxes with a kernel (``g_kind``): their formulas in :func:`prox`
ZERO, BOX, LOWER, UPPER, L1, CONSENSUS, CONSENSUS_M = range(7)


@njit(cache=True, inline="always")
def _max(a, b):
    """np.maximum(a, b): a if a > b or a is NaN, else b (b on a tie: max(-0., 0.) = 0.)."""
    return a if (a > b or a != a) else b


@njit(cache=True, inline="always")
def _min(a, b):
    """np.minimum(a, b): a if a < b or a is NaN, else b."""
    return a if (a < b or a != a) else b


@njit(cache=True, inline="always")
def _sign(a):
    """np.sign(a): 1, -1, +0 for either zero, NaN for NaN."""
    if a > 0.0:
        return 1.0
    if a < 0.0:
        return -1.0
    if a == 0.0:
        return 0.0
    return a


@njit(cache=True)
def csr_matvec(indptr, indices, data, x, y):
    """y = A x for the CSR matrix (indptr, indices, data), summed as scipy's ``csr_matvec`` (each row from 0)."""
    for i in range(y.shape[0]):
        s = 0.0
        for p in range(indptr[i], indptr[i + 1]):
            s += data[p] * x[indices[p]]
        y[i] = s


@njit(cache=True)
def prox(g_kind, v, out, lo, up, thr, blocks, W, wsum):
    """out = prox_{g, 1/rho}^M(v) for the prox ``g_kind``, as ``admmkit.blocks.prox`` computes it.

    BOX: min(max(v, lo), up); LOWER: max(v, lo); UPPER: min(v, up); L1:
    sign(v) max(abs(v) - thr, 0) with thr = t w (/ m); CONSENSUS: every block
    the mean of the ``blocks`` blocks (the blocks added in order from the
    first, as numpy's sum over axis 0, then divided by their number);
    CONSENSUS_M: sum_b W_b v_b / wsum (wsum = sum_b W_b).
    """
    p = v.shape[0]
    if g_kind == ZERO:
        for i in range(p):
            out[i] = v[i]
    elif g_kind == BOX:
        for i in range(p):
            out[i] = _min(_max(v[i], lo[i]), up[i])
    elif g_kind == LOWER:
        for i in range(p):
            out[i] = _max(v[i], lo[i])
    elif g_kind == UPPER:
        for i in range(p):
            out[i] = _min(v[i], up[i])
    elif g_kind == L1:
        for i in range(p):
            out[i] = _sign(v[i]) * _max(abs(v[i]) - thr[i], 0.0)
    else:
        size = p // blocks
        weighted = g_kind == CONSENSUS_M
        for j in range(size):
            s = W[j] * v[j] if weighted else v[j]
            for b in range(1, blocks):
                k = b * size + j
                s = s + (W[k] * v[k] if weighted else v[k])
            avg = s / wsum[j] if weighted else s / blocks
            for b in range(blocks):
                out[b * size + j] = avg


@njit(cache=True)
def x_step(rho, z, lam, x, c_zero, c, Tp, Ti, Td, m, q, sigma, direct, factors, denom, w, b, work, x1):
    """x1 = K(rho)^-1 (A'M (rho (z + c) - lam) - q + sigma x) (eq. (12)); False if b or x1 is not finite.

    ``Tp`` empty: A is the identity; ``m`` empty: M = I; ``direct``: qdldl's
    ``factors`` (Lp, Li, Lx, Dinv, perm), else the diagonal ``denom``.
    """
    p = z.shape[0]
    for i in range(p):
        s = rho * (z[i] if c_zero else z[i] + c[i]) - lam[i]
        w[i] = s if m.shape[0] == 0 else m[i] * s
    if Tp.shape[0] == 0:
        b[:] = w
    else:
        csr_matvec(Tp, Ti, Td, w, b)
    for j in range(b.shape[0]):
        b[j] = b[j] - q[j]
        if sigma != 0.0:
            b[j] = b[j] + sigma * x[j]
    if not all_finite(b, 0, b.shape[0]):
        return False
    if direct:
        Lp, Li, Lx, Dinv, perm = factors
        ldl_solve(Lp, Li, Lx, Dinv, perm, b, work, x1)
    else:
        for j in range(b.shape[0]):
            x1[j] = b[j] / denom[j]
    return all_finite(x1, 0, x1.shape[0])


@njit(cache=True)
def iterations(count, zx, rho, alpha, c_zero, c, Ap, Ai, Ad, Tp, Ti, Td, m, q, sigma, direct, factors, denom,
               g_kind, lo, up, thr, blocks, W, wsum, x, z, lam, Ax):
    """``count`` iterations of order zx (``zx``) or xz from (x, z, lam, Ax), the arrays overwritten;
    returns (done, x, z, lam, Ax), fewer than ``count`` done when an iteration met a non-finite number."""
    n, p = x.shape[0], z.shape[0]
    relaxed, beta = alpha != 1.0, 1.0 - alpha
    x1, z1, lam1, Ax1 = np.empty(n), np.empty(p), np.empty(p), np.empty(p)
    w, b, v, h, work = np.empty(p), np.empty(n), np.empty(p), np.empty(p), np.empty(n)
    for it in range(count):
        if zx:
            for i in range(p):                                              # (11): v = (A x - c) + lam / rho
                v[i] = (Ax[i] if c_zero else Ax[i] - c[i]) + lam[i] / rho
            if not all_finite(v, 0, p):
                return it, x, z, lam, Ax
            prox(g_kind, v, z1, lo, up, thr, blocks, W, wsum)
            for i in range(p):                                              # z_hat = alpha z1 + (1 - alpha)(Ax - c)
                h[i] = alpha * z1[i] + beta * (Ax[i] if c_zero else Ax[i] - c[i]) if relaxed else z1[i]
            if not x_step(rho, h, lam, x, c_zero, c, Tp, Ti, Td, m, q, sigma, direct, factors, denom,
                          w, b, work, x1):                                  # (12)
                return it, x, z, lam, Ax
            _apply(Ap, Ai, Ad, x1, Ax1)
            for i in range(p):                                              # (13)
                r = Ax1[i] - h[i]
                lam1[i] = lam[i] + rho * (r if c_zero else r - c[i])
        else:
            if not x_step(rho, z, lam, x, c_zero, c, Tp, Ti, Td, m, q, sigma, direct, factors, denom,
                          w, b, work, x1):                                  # x^{k+1}
                return it, x, z, lam, Ax
            _apply(Ap, Ai, Ad, x1, Ax1)
            for i in range(p):                                              # Ax_hat = alpha Ax1 + (1 - alpha)(z + c)
                h[i] = alpha * Ax1[i] + beta * (z[i] if c_zero else z[i] + c[i]) if relaxed else Ax1[i]
                v[i] = (h[i] if c_zero else h[i] - c[i]) + lam[i] / rho
            if not all_finite(v, 0, p):
                return it, x, z, lam, Ax
            prox(g_kind, v, z1, lo, up, thr, blocks, W, wsum)                # z^{k+1}
            for i in range(p):                                              # lam^{k+1}
                r = h[i] - z1[i]
                lam1[i] = lam[i] + rho * (r if c_zero else r - c[i])
        if not (all_finite(Ax1, 0, p) and all_finite(z1, 0, p) and all_finite(h, 0, p)
                and all_finite(lam1, 0, p)):
            return it, x, z, lam, Ax
        x, x1 = x1, x
        z, z1 = z1, z
        lam, lam1 = lam1, lam
        Ax, Ax1 = Ax1, Ax
    return count, x, z, lam, Ax


@njit(cache=True, inline="always")
def _apply(Ap, Ai, Ad, x, out):
    """out = A x (``Ap`` empty: the identity, a copy)."""
    if Ap.shape[0] == 0:
        out[:] = x
    else:
        csr_matvec(Ap, Ai, Ad, x, out)
