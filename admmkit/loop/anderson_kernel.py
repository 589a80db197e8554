"""Anderson's update (eqs. (A2)-(A3) of :mod:`admmkit.loop.acceleration`) as one kernel on arrays, for the loop and segments.

A problem whose inner product is a weighted dot product, (a, b)_M = sum_i
w_i a_i b_i (``problem.inner_weights()``: the QP's row weights), has its
Anderson steps made here, by :func:`anderson_update`, from the loop's
Python iteration and from the problem's compiled segment alike: the same
kernel, the same operations in the same order, so a run with Anderson is
the same bit for bit whether its iterations run in Python or in a segment
(:mod:`admmkit.loop.segments`).  Without numba the kernel runs as Python (the same
bits, slower).

The state s = (u, lam) comes as its two arrays (a segment's z and lam,
updated in place); the memory holds stacked vectors [u; lam] of length 2 m
(dF as rows, dF[a, :], for (A3)'s pass over the entries; dG as columns,
dG[:, a], so that the Gram pass runs over the memory in contiguous slots); the
norm (A1) is ||s||_W^2 = rho sum_i w_i u_i^2 + sum_i w_i lam_i^2 / rho.  The
memory is a ring of ``m`` difference pairs (dF, dG) with their Gram matrix;
(A2) is solved by a Cholesky factorisation of the Gram matrix plus
``regularization`` times its largest diagonal entry (no extrapolation when it
is not positive definite or a number is not finite).

The interval (SCS >= 3.2's ``acceleration_interval``, k): a step is taken
after every k-th iteration only, on the pair (s, f = T(s)) of that
iteration, so the memory's differences are between states k iterations
apart; the other iterations are plain (s_{k+1} = f) and cost one test of the
clock.  The clock (``ist[CLOCK]``, the iterations since the last step)
restarts with the memory.  A segment asks :func:`anderson_reads_state` before
an iteration whether it must keep the state s the iteration starts from.

The safeguard (SCS 3): an extrapolated state whose residual ||g||_W exceeds
``safeguard`` times that of the state before it is rejected, the memory is
cleared and the run goes on from the plain image of the state before it.  It
looks at the iteration right after the extrapolation (as SCS's
``aa_safeguard``), whatever the interval.
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

from ..kernels import kernel

#: this kernel's number among a compiled segment's accelerator modes (0 none, 1 Anderson's, 2 fast ADMM's)
MODE = 1
#: the longest run of plain proposals after a rejection (the back-off doubles up to it)
BACKOFF_MAX = 1024
#: the slots of the integer state ``ist``
STORED, NEXT, HAVE_PREV, PENDING, EXTRAPOLATED, REJECTED, SKIP, BACKOFF, INTERVAL, CLOCK = range(10)
INT_SLOTS = 10


@kernel(cache=True)
def _solve_gram(gram, count, regularization, rhs, chol, gamma):
    """gamma = (G + reg max diag(G) I)^-1 rhs over the first ``count`` slots, by Cholesky; False if it fails."""
    top = 0.0
    for a in range(count):
        top = max(top, gram[a, a])
    shift = regularization * top
    for a in range(count):                                  # chol = lower Cholesky factor
        for b in range(a + 1):
            s = gram[a, b] + (shift if a == b else 0.0)
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
def anderson_reads_state(ist):
    """Whether the next :func:`anderson_update` reads the state s the iteration starts from: a step is due (the
    k-th iteration since the last) or an extrapolation waits for the safeguard; else it is a plain step."""
    return ist[PENDING] == 1 or ist[CLOCK] + 1 >= ist[INTERVAL]


@kernel(cache=True)
def anderson_update(rho, w, safeguard, regularization, s_u, s_l, f_u, f_l, out_u, out_l, ist, before, F_prev,
                    G_prev, plain, dF, dG, gram, g, acc, rhs, chol, gamma):
    """The next state (``out_u``, ``out_l``; they may be ``f_u``, ``f_l`` themselves) from the state (``s_u``,
    ``s_l``) an iteration started from and its image (``f_u``, ``f_l``); the memory (``dF``, ``dG``, ``gram``,
    ``F_prev``, ``G_prev``: stacked [u; lam] vectors), the fallback (``plain``, ``before[0]``) and the counters
    ``ist`` are updated in place (``acc``: scratch, 4 x the memory).  Between steps of the interval, s is not
    read (:func:`anderson_reads_state`).  See the module docstring."""
    m = w.shape[0]
    if not anderson_reads_state(ist):                       # between steps: plain
        ist[CLOCK] += 1
        for i in range(m):
            out_u[i], out_l[i] = f_u[i], f_l[i]
        return
    mem = dF.shape[0]
    su = sl = 0.0
    for i in range(m):                                      # g = f - s and ||g||_W, one pass
        a = f_u[i] - s_u[i]
        b = f_l[i] - s_l[i]
        g[i], g[m + i] = a, b
        su += w[i] * a * a
        sl += w[i] * b * b
    g_norm = math.sqrt(max(rho * su + sl / rho, 0.0))
    if ist[PENDING] == 1:                                   # s was extrapolated: the safeguard looks at it
        ist[PENDING] = 0
        if not g_norm <= safeguard * before[0]:             # NaN counts as a rejection
            ist[REJECTED] += 1
            ist[STORED] = ist[NEXT] = ist[HAVE_PREV] = ist[CLOCK] = 0
            ist[SKIP] = ist[BACKOFF]
            ist[BACKOFF] = min(2 * ist[BACKOFF], BACKOFF_MAX)
            for i in range(m):
                out_u[i], out_l[i] = plain[i], plain[m + i]
            return
        ist[BACKOFF] = 1
        if ist[CLOCK] + 1 < ist[INTERVAL]:                  # accepted, and no step due: plain
            ist[CLOCK] += 1
            for i in range(m):
                out_u[i], out_l[i] = f_u[i], f_l[i]
            return
    ist[CLOCK] = 0
    p = -1
    if ist[HAVE_PREV] == 1:                                 # push (f - f_prev, g - g_prev) into the ring
        p = ist[NEXT]
        ist[NEXT] = (p + 1) % mem
        ist[STORED] = min(ist[STORED] + 1, mem)
    for i in range(m):                                      # ... and keep f, g as the next f_prev, g_prev
        if p >= 0:
            dF[p, i] = f_u[i] - F_prev[i]
            dF[p, m + i] = f_l[i] - F_prev[m + i]
            dG[i, p] = g[i] - G_prev[i]
            dG[m + i, p] = g[m + i] - G_prev[m + i]
        F_prev[i], F_prev[m + i] = f_u[i], f_l[i]
        G_prev[i], G_prev[m + i] = g[i], g[m + i]
    ist[HAVE_PREV] = 1
    count = ist[STORED]
    extrapolate = count > 0 and ist[SKIP] == 0
    if ist[SKIP] > 0 and count > 0:                         # backing off after a rejection: plain
        ist[SKIP] -= 1
    _gram_row_and_rhs(w, rho, dG, g, p, count, extrapolate, gram, rhs, acc)
    if not extrapolate or not _solve_gram(gram, count, regularization, rhs, chol, gamma):
        for i in range(m):
            out_u[i], out_l[i] = f_u[i], f_l[i]
        return
    before[0] = g_norm
    for i in range(m):                                      # the fallback, and out = f
        plain[i], plain[m + i] = f_u[i], f_l[i]
        out_u[i], out_l[i] = f_u[i], f_l[i]
    for a in range(count):                                  # (A3): out = f - sum_a gamma_a dF_a, a in order
        c = gamma[a]
        for i in range(m):
            out_u[i] -= c * dF[a, i]
            out_l[i] -= c * dF[a, m + i]
    ist[PENDING] = 1
    ist[EXTRAPOLATED] += 1


@kernel(cache=True)
def _gram_row_and_rhs(w, rho, dG, g, p, count, extrapolate, gram, rhs, acc):
    """The new Gram row gram[p, q] = (dG_p, dG_q)_W (when ``p >= 0``) and (A2)'s right side rhs[q] = (dG_q, g)_W
    (when ``extrapolate``), q < ``count``, in one pass over the entries (dG_q is the column dG[:, q]).

    (a, b)_W = rho sum_{i<m} w_i a_i b_i + (sum_{i<m} w_i a_{m+i} b_{m+i}) / rho.  Each of the 4 ``count`` sums
    (``acc``'s rows) adds its terms (w_i a_i) b_i in the order of i, as a loop per sum would: the same bits, but
    the sums advance side by side over the contiguous row dG[i, :count], so the adds of one no longer wait for the
    one before (no ``fastmath``, no reassociation: one sum alone is a chain of dependent adds)."""
    m = w.shape[0]
    if p < 0 and not extrapolate:
        return
    for q in range(count):
        acc[0, q] = acc[1, q] = acc[2, q] = acc[3, q] = 0.0
    for half in range(2):                                   # u's entries (rows 0, 2), then lam's (rows 1, 3)
        row, right = acc[half], acc[2 + half]
        for k in range(m):
            i = half * m + k
            wk, gi, d = w[k], g[i], dG[i]
            if p >= 0 and extrapolate:
                wp = wk * d[p]
                for q in range(count):
                    row[q] += wp * d[q]
                    right[q] += (wk * d[q]) * gi
            elif p >= 0:
                wp = wk * d[p]
                for q in range(count):
                    row[q] += wp * d[q]
            else:
                for q in range(count):
                    right[q] += (wk * d[q]) * gi
    for q in range(count):
        if p >= 0:
            gram[p, q] = gram[q, p] = rho * acc[0, q] + acc[1, q] / rho
        if extrapolate:
            rhs[q] = rho * acc[2, q] + acc[3, q] / rho


class AndersonArrays:
    """The arrays :func:`anderson_update` works on, for memory ``mem``, states of length ``n`` (= 2 m) and a step
    every ``interval`` iterations."""

    mode = MODE

    def __init__(self, mem: int, n: int, interval: int = 1) -> None:
        self.ist = np.zeros(INT_SLOTS, dtype=np.int64)
        self.ist[BACKOFF] = 1
        self.ist[INTERVAL] = interval
        self.before = np.zeros(1)
        self.F_prev, self.G_prev, self.plain, self.g = (np.zeros(n) for _ in range(4))
        self.dF, self.dG = np.zeros((mem, n)), np.zeros((n, mem))
        self.gram, self.chol = np.zeros((mem, mem)), np.zeros((mem, mem))
        self.acc = np.zeros((4, mem))
        self.rhs, self.gamma = np.zeros(mem), np.zeros(mem)

    def reset(self) -> None:
        """Clear the memory, the pending fallback and the clock (the counters and the back-off stay)."""
        self.ist[STORED] = self.ist[NEXT] = self.ist[HAVE_PREV] = self.ist[PENDING] = self.ist[CLOCK] = 0

    def args(self):
        """The arrays in :func:`anderson_update`'s order, after ``out``."""
        return (self.ist, self.before, self.F_prev, self.G_prev, self.plain, self.dF, self.dG, self.gram,
                self.g, self.acc, self.rhs, self.chol, self.gamma)
