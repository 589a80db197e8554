"""The condensed mode's iteration compiled: its steps as kernels, and SADMM's iterations in one call (a segment).

At Example 1, h = 1/40 (80 contact dofs) an iteration of the condensed mode
is O(n_c^2) = 6,400 multiply-adds and SADMM needs 37 of them; in Python the
loop around them (the record, the rule, the test, the steps' wrappers) took
~235 us an iteration, 8.7 ms a run, against 44 ms for the factorisation and
solve of K the bench compares with (issue #49).  Here the steps of order
"zx" (alpha = 1) are kernels (:func:`z_step`, :func:`x_step`,
:func:`apply_A`), which the plug-in's Python steps call too when the run
is compiled, and :func:`segment_kernel` runs them in a loop
(:mod:`admmkit.loop.segments`): the same operations in the same order, so
the iterates of a segment are those of the Python steps bit for bit.

Inside the segment the kernel makes the loop's decisions where they are
"go on", conservatively:

- SADMM's rule (:class:`admmkit.policies.Summable`) keeps rho where
  w_k = ||lam^{k+1} - lam^k||_M / (rho ||A x^{k+1} - A x^k||_M) lies in
  [1/(1+tau), 1+tau]; the kernel goes on only where w_k is inside the band
  by a relative BAND_MARGIN (its norms are summed in another order than
  numpy's, so a w_k on the edge is the Python rule's to judge);
- at a tested iteration, the paper's stop (:class:`admmkit.RelativeChange`)
  fires where ||u^{k+1} - u^k||_K <= tol ||u^{k+1}||_K: the kernel goes on
  only where the change exceeds tol ||u^{k+1}||_K (1 + STOP_MARGIN), and
  every norm read is finite and below CEILING (the loop's divergence and
  stall tests cannot end the run there).

Anywhere else (rho would change, the stop might fire, a number out of
range) the segment ends with that iteration as the read one, and the loop's
Python makes its own decision on its own numbers: the iterations, the rho
path and the status are those of the Python loop.  Another rule or stop
ends the segment where the loop reads a record (``unchanged_until``, the
tested iterations).
"""
from __future__ import annotations

import numpy as np

from admmkit.kernels import _u, kernel

#: the relative distance from the edges of Summable's band [1/(1+tau), 1+tau] inside which the kernel keeps rho
BAND_MARGIN = 1e-9
#: the relative margin by which ||u^{k+1} - u^k||_K must exceed tol ||u^{k+1}||_K for the kernel to go on
STOP_MARGIN = 1e-6
#: a norm at or above this (or not finite) ends a segment: the loop's divergence test decides
CEILING = 1e100


@kernel(cache=True)
def cholesky_solve(R, b, x):
    """x with R'R x = b, R upper triangular (the upper triangle of LAPACK's potrf factor; the lower one is not
    read): R'y = b by dot products with R's columns, then R x = y by axpys with them (x holds y).  At n_c = 80,
    5 us where LAPACK's potrs took 9 (a copy of R by rows, for axpys both ways, saved 1.4 us for twice the
    memory)."""
    n = b.shape[0]
    for i in range(n):
        s = b[i]
        for j in range(_u(i)):                  # unsigned: no negative-index test in the inner loops
            s -= R[j, _u(i)] * x[j]
        x[i] = s / R[i, i]
    for j in range(n - 1, -1, -1):
        xj = x[j] / R[j, j]
        x[j] = xj
        for i in range(_u(j)):
            x[i] -= R[i, _u(j)] * xj


@kernel(cache=True)
def symmetric_times(C, w, out):
    """out = C w for a symmetric C, as C'w: row j of C times w_j added to out, j = 0, 1, ..."""
    m = w.shape[0]
    for i in range(m):
        out[i] = 0.0
    for j in range(m):
        wj = w[j]
        for i in range(_u(m)):
            out[i] += C[_u(j), i] * wj


@kernel(cache=True)
def z_step(g, Ax, lam, rho, out):
    """out = min(g, A x + lam/rho), eq. (11) (frictionless)."""
    for i in range(out.shape[0]):
        v = Ax[i] + lam[i] / rho
        out[i] = g[i] if g[i] < v else v


@kernel(cache=True)
def x_step(rho, z, lam, d0, R, C, x, Cw, rhs):
    """x = (1, w) with (M_c^{-1} + rho C) w = rho z - lam - rho d0 (R'R = M_c^{-1} + rho C), eq. (12), and
    Cw = C w (``rhs`` is work space)."""
    m = z.shape[0]
    for i in range(m):
        rhs[i] = rho * z[i] - lam[i] - rho * d0[i]
    w = x[1:]
    cholesky_solve(R, rhs, w)
    x[0] = 1.0
    symmetric_times(C, w, Cw)


@kernel(cache=True)
def apply_A(s, d0, Cw, out):
    """out = s d0 + C w, the normal displacement of u = s u0 + K^{-1} A'w on Gamma_C."""
    for i in range(out.shape[0]):
        out[i] = s * d0[i] + Cw[i]


@kernel(cache=True)
def mass_distance(mass, a, b):
    """||a - b||_M = sqrt(sum_i mass_i (a_i - b_i)^2)."""
    total = 0.0
    for i in range(a.shape[0]):
        d = a[i] - b[i]
        total += mass[i] * d * d
    return np.sqrt(total)


@kernel(cache=True)
def energy_distance(e0, d0, x, Cw, y, Cv):
    """||u_x - u_y||_K for x = (s, w), y = (t, v) with their C w, C v: sqrt of ds^2 e0 + 2 ds d0'dw + dw'(Cw - Cv)
    (ds = s - t, dw = w - v; y = 0, Cv = 0 gives ||u_x||_K)."""
    ds = x[0] - y[0]
    cross = 0.0
    quad = 0.0
    for i in range(d0.shape[0]):
        dw = x[i + 1] - y[i + 1]
        cross += d0[i] * dw
        quad += dw * (Cw[i] - Cv[i])
    return np.sqrt(max(ds * ds * e0 + 2.0 * ds * cross + quad, 0.0))


@kernel(cache=True)
def all_finite(v):
    """Whether every entry of v is finite."""
    for i in range(v.shape[0]):
        if not np.isfinite(v[i]):
            return False
    return True


@kernel(cache=True)
def go_on(k, every, knows_stop, tol, knows_rule, band_low, band_high, rho, mass, e0, d0,
          x, z, Ax, Cw, x0, Ax0, Cw0, zeros):
    """Whether the loop would go on after iteration k, whose inputs were (x0, A x0) and outputs (x, z, A x), at the
    same rho: True only where SADMM's rule (if ``knows_rule``) certainly keeps rho and, at a tested iteration
    ((k + 1) % every == 0), the stop (RelativeChange(tol), if ``knows_stop``) certainly does not fire and no norm
    it reads is out of range (the module docstring)."""
    r = mass_distance(mass, Ax, z)                      # ||r||_M: lam_change = rho ||r||_M (alpha = 1)
    dAx = mass_distance(mass, Ax, Ax0)
    num, den = rho * r, rho * dAx
    if not (num < CEILING and den < CEILING):
        return False
    if knows_rule:
        if not den > 0.0:
            return False
        w = num / den
        if not (band_low * (1.0 + BAND_MARGIN) < w < band_high * (1.0 - BAND_MARGIN)):
            return False                                # rho may change: the loop's event
    if (k + 1) % every == 0:
        if not knows_stop:
            return False
        change = energy_distance(e0, d0, x, Cw, x0, Cw0)
        size = energy_distance(e0, d0, x, Cw, zeros, zeros)
        if not (change < CEILING and size < CEILING):
            return False
        if not change > tol * size * (1.0 + STOP_MARGIN):
            return False                                # the stop may fire (or the iterates stalled)
    return True


@kernel(cache=True)
def segment_kernel(count, first, every, knows_stop, tol, knows_rule, band_low, band_high, decide,
                   rho, g, d0, mass, e0, R, C, x, z, lam, Ax, Cw, x0, z0, lam0, Ax0, Cw0,
                   x1, z1, lam1, Ax1, Cw1, rhs, zeros):
    """Up to ``count`` iterations of order zx from iteration ``first`` on the state (x, z, lam, Ax, Cw), updated in
    place; (x0, ..., Cw0) end as the inputs of the last iteration run.  With ``decide``, the segment ends after an
    iteration where :func:`go_on` says the loop must look.  Returns (done, kept): ``kept`` False when the
    segment stopped before an iteration whose outputs were not all finite (that iteration is not taken: the loop
    runs it in Python)."""
    m = z.shape[0]
    done = 0
    while done < count:
        z_step(g, Ax, lam, rho, z1)                                        # (11)
        x_step(rho, z1, lam, d0, R, C, x1, Cw1, rhs)                     # (12)
        apply_A(x1[0], d0, Cw1, Ax1)
        for i in range(m):                                                 # (13)
            lam1[i] = lam[i] + rho * (Ax1[i] - z1[i])
        if not (all_finite(x1) and all_finite(z1) and all_finite(lam1) and all_finite(Ax1)):
            return done, False
        x0[:] = x
        z0[:] = z
        lam0[:] = lam
        Ax0[:] = Ax
        Cw0[:] = Cw
        x[:] = x1
        z[:] = z1
        lam[:] = lam1
        Ax[:] = Ax1
        Cw[:] = Cw1
        done += 1
        if done == count:
            break
        if decide and not go_on(first + done - 1, every, knows_stop, tol, knows_rule, band_low, band_high, rho,
                                mass, e0, d0, x, z, Ax, Cw, x0, Ax0, Cw0, zeros):
            break
    return done, True


def known_stop(stop) -> float | None:
    """tol of the paper's stop ``RelativeChange(tol)`` itself (the test :func:`go_on` makes), else None."""
    from admmkit.loop.stopping import RelativeChange
    return stop.tol if type(stop) is RelativeChange else None


def known_rule(policy) -> tuple[float, float] | None:
    """SADMM's band (1/(1+tau), 1+tau) of :class:`admmkit.policies.Summable` itself, else None."""
    from admmkit.policies.summable import Summable
    if type(policy) is not Summable:
        return None
    return 1.0 / (1.0 + policy.tau), 1.0 + policy.tau


def run_segment(problem, factor, x, z, lam, Ax, Cw, rho: float, count: int, read: bool, check):
    """``CondensedContact.segment`` in order zx with alpha = 1: (x, z, lam, Ax, done) after ``done`` <= ``count``
    iterations, with ``read`` also ``last`` (the read iteration's inputs and None for the relaxed vector; None when
    a non-finite step ended the segment early), and the (x, C w) of the last two iterates for the plug-in's norms.
    ``factor`` is R, R'R = M_c^{-1} + rho C (upper triangular).

    ``check`` (:class:`admmkit.loop.segments.SegmentChecks`): the kernel decides at every iteration (:func:`go_on`)
    where the rule is Summable and the stop RelativeChange; another rule ends the segment at the first record it
    reads (``unchanged_until``), another stop at the first tested iteration."""
    decide = check is not None
    first, every = (check.first, check.every) if decide else (0, 1)
    tol = known_stop(check.stop) if decide else None
    band = known_rule(check.policy) if decide else None
    if decide and band is None:
        count = min(count, check.policy.unchanged_until(first) - first + 1)
    state = [np.array(v, dtype=np.float64) for v in (x, z, lam, Ax, Cw)]     # the loop's arrays are not written
    inputs = [np.empty_like(v) for v in state]
    done, kept = segment_kernel(int(count), int(first), int(every), tol is not None, 0.0 if tol is None else tol,
                                band is not None, *(band or (0.0, np.inf)), decide, float(rho), problem.g,
                                problem.d0, problem.w, float(problem.e0), factor, problem.C, *state, *inputs,
                                *work_space(problem, x.shape[0], z.shape[0]))
    x, z, lam, Ax, Cw = state
    last = None
    if read and kept and done and (decide or done == count):      # the last iteration run is the read one
        last = (inputs[0], inputs[1], inputs[2], inputs[3], None)
    return (x, z, lam, Ax, done, last), (inputs[0], inputs[4]), (x, Cw)


def work_space(problem, n: int, m: int) -> tuple:
    """The kernel's work arrays (x1, z1, lam1, Ax1, Cw1, rhs, zeros), made once per problem and size."""
    held = problem.__dict__.get("_segment_work")
    if held is None or held[0].shape[0] != n or held[1].shape[0] != m:
        held = problem._segment_work = (np.empty(n), *(np.empty(m) for _ in range(5)), np.zeros(n))
    return held
