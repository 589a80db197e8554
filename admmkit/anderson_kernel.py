"""Anderson's update (eqs. (A2)-(A3) of :mod:`admmkit.acceleration`) as one kernel on arrays, for the loop and segments.

A problem whose inner product is a weighted dot product, (a, b)_M = sum_i
w_i a_i b_i (``problem.inner_weights()``: the QP's row weights), has its
Anderson steps made here, by :func:`anderson_update`, from the loop's
Python iteration and from the problem's compiled segment alike: the same
kernel, the same operations in the same order, so a run with Anderson is
the same bit for bit whether its iterations run in Python or in a segment
(:mod:`admmkit.segments`).  Without numba the kernel runs as Python (the same
bits, slower).

The state s = (u, lam) is held as one vector [u; lam] of length 2 m; the
norm (A1) is ||s||_W^2 = rho sum_i w_i u_i^2 + sum_i w_i lam_i^2 / rho.  The
memory is a ring of ``m`` difference pairs (dF, dG) with their Gram matrix;
(A2) is solved by a Cholesky factorisation of the Gram matrix plus
``regularization`` times its largest diagonal entry (no extrapolation when it
is not positive definite or a number is not finite).

The safeguard (SCS 3): an extrapolated state whose residual ||g||_W exceeds
``safeguard`` times that of the state before it is rejected, the memory is
cleared and the run goes on from the plain image of the state before it.
Rejections back off: after a rejection the next ``b`` proposals are plain
(memory still gathered), b doubling with each rejection that follows (up to
BACKOFF_MAX) and back to 1 after an accepted extrapolation.  So where
extrapolation keeps failing (HS268 at 1e-6: 1310 of 1376 rejected, the run
stalled at the cap) the iteration becomes plain ADMM with rare probes, and
converges as plain ADMM does.
"""
from __future__ import annotations

import math

import numpy as np

from .acceleration import BACKOFF_MAX
from .compiled import kernel

#: the slots of the integer state ``ist``
STORED, NEXT, HAVE_PREV, PENDING, EXTRAPOLATED, REJECTED, SKIP, BACKOFF = range(8)
INT_SLOTS = 8


@kernel(cache=True)
def _w_dot(rho, w, a, b):
    """<a, b>_W of two stacked states [u; lam] (A1), summed in order."""
    m = w.shape[0]
    su = 0.0
    for i in range(m):
        su += w[i] * a[i] * b[i]
    sl = 0.0
    for i in range(m):
        sl += w[i] * a[m + i] * b[m + i]
    return rho * su + sl / rho


@kernel(cache=True)
def _w_dot_rows(rho, w, A, p, b):
    """<A[p], b>_W (a row of a memory array against a vector), summed in order."""
    m = w.shape[0]
    su = 0.0
    for i in range(m):
        su += w[i] * A[p, i] * b[i]
    sl = 0.0
    for i in range(m):
        sl += w[i] * A[p, m + i] * b[m + i]
    return rho * su + sl / rho


@kernel(cache=True)
def _solve_gram(gram, slots, count, regularization, rhs, chol, gamma):
    """gamma = (G + reg max diag(G) I)^-1 rhs over the first ``count`` slots, by Cholesky; False if it fails."""
    top = 0.0
    for a in range(count):
        top = max(top, gram[slots[a], slots[a]])
    shift = regularization * top
    for a in range(count):                                  # chol = lower Cholesky factor
        for b in range(a + 1):
            s = gram[slots[a], slots[b]] + (shift if a == b else 0.0)
            for c in range(b):
                s -= chol[a, c] * chol[b, c]
            if a == b:
                if not (s > 0.0) or not np.isfinite(s):
                    return False
                chol[a, a] = math.sqrt(s)
            else:
                chol[a, b] = s / chol[b, b]
    for a in range(count):                                  # forward: chol y = rhs
        s = rhs[a]
        for c in range(a):
            s -= chol[a, c] * gamma[c]
        gamma[a] = s / chol[a, a]
    for a in range(count - 1, -1, -1):                      # backward: chol' gamma = y
        s = gamma[a]
        for c in range(a + 1, count):
            s -= chol[c, a] * gamma[c]
        gamma[a] = s / chol[a, a]
    for a in range(count):
        if not np.isfinite(gamma[a]):
            return False
    return True


@kernel(cache=True)
def anderson_update(rho, w, safeguard, regularization, s, f, out, ist, before, F_prev, G_prev, plain, dF, dG, gram,
                    g, slots, rhs, chol, gamma):
    """The next state ``out`` (may be ``f`` itself) from the state ``s`` an iteration started from and its image
    ``f`` (stacked [u; lam]); the memory (``dF``, ``dG``, ``gram``, ``F_prev``, ``G_prev``), the fallback
    (``plain``, ``before[0]``) and the counters ``ist`` are updated in place.  See the module docstring."""
    n = f.shape[0]
    mem = dF.shape[0]
    for i in range(n):
        g[i] = f[i] - s[i]
    g_norm = math.sqrt(max(_w_dot(rho, w, g, g), 0.0))
    if ist[PENDING] == 1:                                   # s was extrapolated: the safeguard looks at it
        ist[PENDING] = 0
        if not g_norm <= safeguard * before[0]:             # NaN counts as a rejection
            ist[REJECTED] += 1
            ist[STORED] = ist[NEXT] = ist[HAVE_PREV] = 0
            ist[SKIP] = ist[BACKOFF]
            ist[BACKOFF] = min(2 * ist[BACKOFF], BACKOFF_MAX)
            for i in range(n):
                out[i] = plain[i]
            return
        ist[BACKOFF] = 1
    if ist[HAVE_PREV] == 1:                                 # push (f - f_prev, g - g_prev) into the ring
        p = ist[NEXT]
        for i in range(n):
            dF[p, i] = f[i] - F_prev[i]
            dG[p, i] = g[i] - G_prev[i]
        ist[NEXT] = (p + 1) % mem
        ist[STORED] = min(ist[STORED] + 1, mem)
        for q in range(ist[STORED]):                        # the slots in use are 0 .. STORED - 1
            gram[p, q] = gram[q, p] = _w_dot_rows(rho, w, dG, p, dG[q])
    for i in range(n):
        F_prev[i] = f[i]
        G_prev[i] = g[i]
    ist[HAVE_PREV] = 1
    count = ist[STORED]
    if count == 0:
        for i in range(n):
            out[i] = f[i]
        return
    if ist[SKIP] > 0:                                       # backing off after a rejection: plain
        ist[SKIP] -= 1
        for i in range(n):
            out[i] = f[i]
        return
    for a in range(count):                                  # (A2): the normal equations over the stored slots
        slots[a] = a
        rhs[a] = _w_dot_rows(rho, w, dG, a, g)
    if not _solve_gram(gram, slots, count, regularization, rhs, chol, gamma):
        for i in range(n):
            out[i] = f[i]
        return
    for i in range(n):
        plain[i] = f[i]
    before[0] = g_norm
    for i in range(n):                                      # (A3)
        v = f[i]
        for a in range(count):
            v -= gamma[a] * dF[a, i]
        out[i] = v
    ist[PENDING] = 1
    ist[EXTRAPOLATED] += 1


class AndersonArrays:
    """The arrays :func:`anderson_update` works on, for memory ``mem`` and states of length ``n`` (= 2 m)."""

    def __init__(self, mem: int, n: int) -> None:
        self.ist = np.zeros(INT_SLOTS, dtype=np.int64)
        self.ist[BACKOFF] = 1
        self.before = np.zeros(1)
        self.F_prev, self.G_prev, self.plain, self.g = (np.zeros(n) for _ in range(4))
        self.dF, self.dG = np.zeros((mem, n)), np.zeros((mem, n))
        self.gram, self.chol = np.zeros((mem, mem)), np.zeros((mem, mem))
        self.slots = np.zeros(mem, dtype=np.int64)
        self.rhs, self.gamma = np.zeros(mem), np.zeros(mem)

    def reset(self) -> None:
        """Clear the memory and the pending fallback (the counters and the back-off stay)."""
        self.ist[STORED] = self.ist[NEXT] = self.ist[HAVE_PREV] = self.ist[PENDING] = 0

    def args(self):
        """The arrays in :func:`anderson_update`'s order, after ``out``."""
        return (self.ist, self.before, self.F_prev, self.G_prev, self.plain, self.dF, self.dG, self.gram,
                self.g, self.slots, self.rhs, self.chol, self.gamma)
