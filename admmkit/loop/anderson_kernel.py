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
#: numba's options for these kernels.  ``_nrt=False``: they allocate nothing, and numba's reference counts of their
#: twenty-odd array arguments (an atomic add and a call per array, at entry and at every return) cost more than a
#: plain call's work (0.18 against 0.05 us).  ``error_model="numpy"``: no test for a zero divisor before each
#: division (none can be zero: rho > 0, a Cholesky pivot is the root of a positive number).  Neither changes a bit;
#: ``fastmath`` stays off.
OPTIONS = dict(cache=True, _nrt=False, error_model="numpy")
#: doubles in an AVX2 vector register; the Gram pass runs over the memory's columns padded to a multiple of it
VECTOR = 4


@kernel(**OPTIONS)
def _solve_gram(gram, count, regularization, rhs, chol, gamma):
    """gamma = (G + reg max diag(G) I)^-1 rhs over the first ``count`` slots, by Cholesky; False if it fails.

    chol = L, the lower Cholesky factor, a column at a time (each entry's sum over c in the order of c, as a row at
    a time would add it: the same bits, but a column's entries are independent sums, which the processor overlaps),
    with the forward solve L y = rhs alongside (y in ``gamma``); then L' gamma = y."""
    top = 0.0
    for a in range(count):
        top = max(top, gram[a, a])
    shift = regularization * top
    for b in range(count):
        s = gram[b, b] + shift                              # the diagonal entry L[b, b]
        for c in range(b):
            s -= chol[b, c] * chol[b, c]
        if not (s > 0.0) or not np.isfinite(s):
            return False
        d = math.sqrt(s)
        chol[b, b] = d
        for a in range(b + 1, count):                       # the column below it
            s = gram[a, b] + 0.0
            for c in range(b):
                s -= chol[a, c] * chol[b, c]
            chol[a, b] = s / d
        s = rhs[b]                                          # forward: L y = rhs
        for c in range(b):
            s -= chol[b, c] * gamma[c]
        gamma[b] = s / d
    for a in range(count - 1, -1, -1):                      # backward: L' gamma = y
        s = gamma[a]
        for c in range(a + 1, count):
            s -= chol[c, a] * gamma[c]
        gamma[a] = s / chol[a, a]
    for a in range(count):
        if not np.isfinite(gamma[a]):
            return False
    return True


@kernel(**OPTIONS)
def anderson_reads_state(ist):
    """Whether the next :func:`anderson_update` reads the state s the iteration starts from: a step is due (the
    k-th iteration since the last) or an extrapolation waits for the safeguard; else it is a plain step."""
    return ist[PENDING] == 1 or ist[CLOCK] + 1 >= ist[INTERVAL]


@kernel(**OPTIONS)
def anderson_update(rho, w, safeguard, regularization, s_u, s_l, f_u, f_l, out_u, out_l, ist, before, F_prev,
                    G_prev, plain, dF, dG, gram, g, acc, rhs, chol, gamma):
    """The next state (``out_u``, ``out_l``; they may be ``f_u``, ``f_l`` themselves) from the state (``s_u``,
    ``s_l``) an iteration started from and its image (``f_u``, ``f_l``); the memory (``dF``, ``dG``, ``gram``,
    ``F_prev``, ``G_prev``: stacked [u; lam] vectors), the fallback (``plain``, ``before[0]``) and the counters
    ``ist`` are updated in place (``acc``: scratch, 4 x the memory's columns).  Between steps of the interval, s is
    not read (:func:`anderson_reads_state`).  See the module docstring."""
    if not anderson_reads_state(ist):                       # between steps: plain
        ist[CLOCK] += 1
        _take(f_u, f_l, 0, out_u, out_l)
        return
    mem = dF.shape[0]
    g_norm = _residual(rho, w, s_u, s_l, f_u, f_l, g)
    if ist[PENDING] == 1:                                   # s was extrapolated: the safeguard looks at it
        ist[PENDING] = 0
        if not g_norm <= safeguard * before[0]:             # NaN counts as a rejection
            ist[REJECTED] += 1
            ist[STORED] = ist[NEXT] = ist[HAVE_PREV] = ist[CLOCK] = 0
            ist[SKIP] = ist[BACKOFF]
            ist[BACKOFF] = min(2 * ist[BACKOFF], BACKOFF_MAX)
            _take(plain, plain, f_u.shape[0], out_u, out_l)
            return
        ist[BACKOFF] = 1
        if ist[CLOCK] + 1 < ist[INTERVAL]:                  # accepted, and no step due: plain
            ist[CLOCK] += 1
            _take(f_u, f_l, 0, out_u, out_l)
            return
    ist[CLOCK] = 0
    p = -1
    if ist[HAVE_PREV] == 1:                                 # push (f - f_prev, g - g_prev) into the ring
        p = ist[NEXT]
        ist[NEXT] = (p + 1) % mem
        ist[STORED] = min(ist[STORED] + 1, mem)
    _push(p, f_u, f_l, g, F_prev, G_prev, dF, dG)
    ist[HAVE_PREV] = 1
    count = ist[STORED]
    extrapolate = count > 0 and ist[SKIP] == 0
    if ist[SKIP] > 0 and count > 0:                         # backing off after a rejection: plain
        ist[SKIP] -= 1
    _gram_row_and_rhs(w, rho, dG, g, p, count, extrapolate, gram, rhs, acc)
    if not extrapolate or not _solve_gram(gram, count, regularization, rhs, chol, gamma):
        _take(f_u, f_l, 0, out_u, out_l)
        return
    before[0] = g_norm
    _extrapolate(count, gamma, dF, f_u, f_l, plain, out_u, out_l)
    ist[PENDING] = 1
    ist[EXTRAPOLATED] += 1


@kernel(**OPTIONS)
def _take(u, l, offset, out_u, out_l):
    """out_u = u[:m], out_l = l[offset:offset + m] (m = len(out_u))."""
    for i in range(out_u.shape[0]):
        out_u[i] = u[i]
    for i in range(out_l.shape[0]):
        out_l[i] = l[offset + i]


@kernel(**OPTIONS)
def _residual(rho, w, s_u, s_l, f_u, f_l, g):
    """g = f - s (stacked) and its norm ||g||_W (the sums over i in order)."""
    m = w.shape[0]
    su = sl = 0.0
    for i in range(m):
        a = f_u[i] - s_u[i]
        b = f_l[i] - s_l[i]
        g[i], g[m + i] = a, b
        su += w[i] * a * a
        sl += w[i] * b * b
    return math.sqrt(max(rho * su + sl / rho, 0.0))


@kernel(**OPTIONS)
def _push(p, f_u, f_l, g, F_prev, G_prev, dF, dG):
    """dF[p] = f - f_prev, dG[:, p] = g - g_prev (when ``p >= 0``: the ring's slot), then f_prev = f, g_prev = g."""
    m = f_u.shape[0]
    if p >= 0:
        for i in range(m):
            dF[p, i] = f_u[i] - F_prev[i]
        for i in range(m):
            dF[p, m + i] = f_l[i] - F_prev[m + i]
        for i in range(2 * m):
            dG[i, p] = g[i] - G_prev[i]
    for i in range(m):
        F_prev[i] = f_u[i]
    for i in range(m):
        F_prev[m + i] = f_l[i]
    for i in range(2 * m):
        G_prev[i] = g[i]


@kernel(**OPTIONS)
def _extrapolate(count, gamma, dF, f_u, f_l, plain, out_u, out_l):
    """(A3): out = f - sum_{a < count} gamma_a dF_a, the terms subtracted in the order of a, two a pass; plain = f
    (the safeguard's fallback).  ``out`` may be ``f``."""
    m = f_u.shape[0]
    for i in range(m):
        plain[i], plain[m + i] = f_u[i], f_l[i]
    _take(f_u, f_l, 0, out_u, out_l)
    for a in range(0, count - 1, 2):
        c0, c1, d0, d1 = gamma[a], gamma[a + 1], dF[a], dF[a + 1]
        for i in range(m):
            out_u[i] = (out_u[i] - c0 * d0[i]) - c1 * d1[i]
        for i in range(m):
            out_l[i] = (out_l[i] - c0 * d0[m + i]) - c1 * d1[m + i]
    if count % 2 == 1:
        c, d = gamma[count - 1], dF[count - 1]
        for i in range(m):
            out_u[i] -= c * d[i]
        for i in range(m):
            out_l[i] -= c * d[m + i]


@kernel(**OPTIONS)
def _gram_row_and_rhs(w, rho, dG, g, p, count, extrapolate, gram, rhs, acc):
    """The new Gram row gram[p, q] = (dG_p, dG_q)_W (when ``p >= 0``) and (A2)'s right side rhs[q] = (dG_q, g)_W
    (when ``extrapolate``), q < ``count``, in one pass over the entries (dG_q is the column dG[:, q]).

    (a, b)_W = rho sum_{i<m} w_i a_i b_i + (sum_{i<m} w_i a_{m+i} b_{m+i}) / rho.  Each of the 4 ``count`` sums
    (``acc``'s rows) adds its terms (w_i a_i) b_i in the order of i, as a loop per sum would: the same bits, but
    the sums advance side by side over the contiguous row dG[i, :count], so the adds of one no longer wait for the
    one before (no ``fastmath``, no reassociation: one sum alone is a chain of dependent adds).  Two entries i at a
    time (one load and store of each sum per pair), and over :func:`_width` columns (the sums past ``count`` are
    not read): the compiled loop then runs in whole vectors."""
    m = w.shape[0]
    if p < 0 and not extrapolate:
        return
    width = _width(count, acc.shape[1])
    pp = max(p, 0)                                          # (p < 0: the row's sums are not read)
    for q in range(width):
        acc[0, q] = acc[1, q] = acc[2, q] = acc[3, q] = 0.0
    for half in range(2):                                   # u's entries (rows 0, 2), then lam's (rows 1, 3)
        row, right = acc[half], acc[2 + half]
        for k in range(0, m - 1, 2):
            i = half * m + k
            w0, w1, g0, g1, d0, d1 = w[k], w[k + 1], g[i], g[i + 1], dG[i], dG[i + 1]
            p0, p1 = w0 * d0[pp], w1 * d1[pp]
            for q in range(width):
                a, b = d0[q], d1[q]
                row[q] = (row[q] + p0 * a) + p1 * b
                right[q] = (right[q] + (w0 * a) * g0) + (w1 * b) * g1
        if m % 2 == 1:
            i = half * m + m - 1
            wk, gi, d = w[m - 1], g[i], dG[i]
            wp = wk * d[pp]
            for q in range(width):
                row[q] += wp * d[q]
                right[q] += (wk * d[q]) * gi
    for q in range(count):
        if p >= 0:
            gram[p, q] = gram[q, p] = rho * acc[0, q] + acc[1, q] / rho
        if extrapolate:
            rhs[q] = rho * acc[2, q] + acc[3, q] / rho


@kernel(**OPTIONS)
def _width(count, columns):
    """The columns the Gram pass runs over: ``count`` rounded up to whole vectors of VECTOR, at most ``columns``."""
    return min((count + VECTOR - 1) // VECTOR * VECTOR, columns)


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
        columns = (mem + VECTOR - 1) // VECTOR * VECTOR
        self.dF, self.dG = np.zeros((mem, n)), np.zeros((n, columns))
        self.gram, self.chol = np.zeros((mem, mem)), np.zeros((mem, mem))
        self.acc = np.zeros((4, columns))
        self.rhs, self.gamma = np.zeros(mem), np.zeros(mem)

    def reset(self) -> None:
        """Clear the memory, the pending fallback and the clock (the counters and the back-off stay)."""
        self.ist[STORED] = self.ist[NEXT] = self.ist[HAVE_PREV] = self.ist[PENDING] = self.ist[CLOCK] = 0

    def args(self):
        """The arrays in :func:`anderson_update`'s order, after ``out``."""
        return (self.ist, self.before, self.F_prev, self.G_prev, self.plain, self.dF, self.dG, self.gram,
                self.g, self.acc, self.rhs, self.chol, self.gamma)
