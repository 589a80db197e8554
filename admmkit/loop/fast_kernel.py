"""Restarted fast ADMM's step (eqs. (A4)-(A6) of :mod:`admmkit.loop.acceleration`) as one kernel on arrays.

As :mod:`admmkit.loop.anderson_kernel` for Anderson: a problem whose inner
product is a weighted dot product, (a, b)_M = sum_i w_i a_i b_i
(``problem.inner_weights()``: the QP's row weights), has the steps of
:class:`admmkit.loop.acceleration.FastADMM` made here, by :func:`fast_update`,
from the loop's Python iteration and from the problem's compiled segment
alike, so a run with it is the same bit for bit whichever runs its iterations.
Without numba the kernel runs as Python (the same bits, slower).

The state s = (u, lam) comes as its two arrays; the combined residual (A4) is

    c_k = ||f_k - s_k||_W^2 = rho sum_i w_i g_u,i^2 + sum_i w_i g_lam,i^2 / rho,

summed as :func:`admmkit.loop.anderson_kernel.anderson_update` sums ||g||_W^2.
The memory is the previous image f_{k-1} (``f_prev``, the stacked [u; lam] of
length 2 m), the momentum a_k and c_{k-1} (``ac``) and the integer state
``ist``: whether f_prev holds an image, whether s_k was extrapolated, the
extrapolations since the last restart (the momentum phase), the back-off
(plain steps left, the next back-off's length), the patience, the counts
of extrapolations, restarts and failed phases, and the failed phases in a
row (short ones: fewer than SHORT extrapolations) with the number of them
that ends momentum (``give_up``).

A restart after an extrapolated s_k goes back to f_{k-1} (Goldstein et al.);
after a plain one it keeps f_k (going back would repeat the iteration just
made).  The safeguard (A6): a restart that ends a momentum phase of fewer than
``patience`` extrapolations fails it, and the next b steps are plain, b
doubling with each failure (up to BACKOFF_MAX) and back to 1 after a phase
that lasted; momentum starts afresh after them.  The global fallback (A7):
the ``give_up``-th *short* failed phase in a row (fewer than SHORT
extrapolations: momentum did not get going) turns momentum off for good (a
back-off of FOREVER steps), so that a problem where momentum fails at once
loses at most that many probes (each a wasted iteration and a nudge to the
rho path) and is plain ADMM after them; a longer phase, failed or not,
starts the count again (a LASSO whose phases of 5-13 extrapolations fail
the patience of 16 but cut its iterations 7-fold keeps its momentum).  A plain step of the back-off
reads nothing but its count (:func:`fast_reads_state`), so where momentum
keeps failing the iterations cost what plain ones cost.

Where kernels run as Python (numba not imported, ``compiled_code(False)``)
the loop takes :func:`fast_update_numpy` instead: the same operations on
whole arrays (the sums left to right by ``np.cumsum``, as the kernel adds
them), so the same bits at numpy's speed rather than a Python loop over the
entries (HS118: 255 against 126 us an iteration).
"""
from __future__ import annotations

import math

import numpy as np

from ..kernels import kernel

#: this kernel's number among a compiled segment's accelerator modes (0 none, 1 Anderson's, 2 fast ADMM's)
MODE = 2
#: the longest run of plain steps after a failed momentum phase (the back-off doubles up to it; Anderson's too)
BACKOFF_MAX = 1024
#: the slots of the integer state ``ist``: f_prev holds an image; s_k was extrapolated; the counts of extrapolations
#: and restarts; the extrapolations of the current momentum phase; plain steps left; the next back-off; the
#: patience; the count of failed phases; the short failed phases in a row; the number of them that ends momentum (A7)
HAVE_PREV, EXTRAPOLATED, RESTARTS, MOMENTUM, PHASE, SKIP, BACKOFF, PATIENCE, FAILED, STREAK, LIMIT = range(11)
INT_SLOTS = 11
#: the back-off that never ends, momentum off for good (A7)
FOREVER = 1 << 62
#: a failed phase of fewer extrapolations than this is short, momentum did not get going (A7)
SHORT = 4
#: the slots of the float state ``ac``: the momentum a_k and the last combined residual c_{k-1}
A, C = range(2)


@kernel(cache=True)
def fast_reads_state(ist):
    """Whether the next :func:`fast_update` reads the state s the iteration starts from (not in a back-off)."""
    return ist[SKIP] == 0


@kernel(cache=True)
def momentum_step(ist, ac, c):
    """(A5)'s bookkeeping where c_k < eta c_{k-1} (or no image is held yet): a_{k+1} and c_k stored, the counts of a
    momentum phase.  Returns beta = (a_k - 1) / a_{k+1} and whether s_{k+1} is extrapolated (an image f_{k-1} is
    held and beta != 0)."""
    a_next = (1.0 + math.sqrt(1.0 + 4.0 * ac[A] ** 2)) / 2.0
    beta = (ac[A] - 1.0) / a_next
    ac[A], ac[C] = a_next, c
    momentum = ist[HAVE_PREV] == 1 and beta != 0.0
    if momentum:
        ist[EXTRAPOLATED] += 1
        ist[PHASE] += 1
    ist[MOMENTUM] = 1 if momentum else 0
    ist[HAVE_PREV] = 1
    return beta, momentum


@kernel(cache=True)
def restart(ist, ac):
    """A restart's bookkeeping (A5)-(A7): no momentum; a phase shorter than the patience fails and backs off, and
    the ``give_up``-th short failed phase in a row (fewer than SHORT extrapolations) ends momentum for good.  Returns whether s_k was extrapolated (the step then goes back to f_{k-1}, else it keeps f_k)."""
    ist[RESTARTS] += 1
    if ist[PHASE] < ist[PATIENCE]:                              # a failed momentum phase: back off (A6)
        ist[FAILED] += 1
        ist[SKIP] = ist[BACKOFF]
        ist[BACKOFF] = min(2 * ist[BACKOFF], BACKOFF_MAX)
        ist[STREAK] = ist[STREAK] + 1 if ist[PHASE] < SHORT else 0
        if ist[LIMIT] > 0 and ist[STREAK] >= ist[LIMIT]:     # momentum never got going: off for good (A7)
            ist[SKIP] = FOREVER
    else:
        ist[BACKOFF] = 1
        ist[STREAK] = 0
    back = ist[MOMENTUM] == 1
    ist[PHASE] = ist[MOMENTUM] = 0
    ac[A] = 1.0
    if ist[SKIP] > 0:                                           # momentum starts afresh after the back-off
        ist[HAVE_PREV] = 0
        ac[C] = math.inf
    return back


@kernel(cache=True)
def fast_update(rho, w, eta, s_u, s_l, f_u, f_l, out_u, out_l, ist, ac, f_prev):
    """The next state (``out_u``, ``out_l``; they may be ``f_u``, ``f_l`` themselves) from the state (``s_u``,
    ``s_l``) an iteration started from and its image (``f_u``, ``f_l``): in a back-off f itself (s not read);
    else the momentum step (A5) when c_k < ``eta`` c_{k-1} (or no image is held yet), a restart otherwise.
    ``ist``, ``ac`` and ``f_prev`` are updated in place (see the module docstring)."""
    m = w.shape[0]
    if ist[SKIP] > 0:                                       # backing off: plain
        ist[SKIP] -= 1
        for i in range(m):
            out_u[i], out_l[i] = f_u[i], f_l[i]
        return
    su = sl = 0.0
    for i in range(m):                                      # c_k = ||f - s||_W^2 (A4)
        a = f_u[i] - s_u[i]
        b = f_l[i] - s_l[i]
        su += w[i] * a * a
        sl += w[i] * b * b
    c = rho * su + sl / rho
    if ist[HAVE_PREV] == 0 or c < eta * ac[C]:
        beta, momentum = momentum_step(ist, ac, c)
        for i in range(m):                                  # (A5), and f becomes f_prev
            fu, fl = f_u[i], f_l[i]
            if momentum:
                out_u[i] = fu + beta * (fu - f_prev[i])
                out_l[i] = fl + beta * (fl - f_prev[m + i])
            else:
                out_u[i], out_l[i] = fu, fl
            f_prev[i], f_prev[m + i] = fu, fl
        return
    if restart(ist, ac):                                    # s_k extrapolated: back to f_{k-1}
        if ist[HAVE_PREV] == 1:                             # (not backing off)
            ac[C] = ac[C] / eta
        for i in range(m):
            out_u[i], out_l[i] = f_prev[i], f_prev[m + i]
        return
    if ist[HAVE_PREV] == 1:                                 # s_k plain: keep f_k, the new f_{k-1}
        ac[C] = c
    for i in range(m):
        out_u[i], out_l[i] = f_u[i], f_l[i]
        f_prev[i], f_prev[m + i] = f_u[i], f_l[i]


def fast_update_numpy(rho, w, eta, s_u, s_l, f_u, f_l, out_u, out_l, ist, ac, f_prev):
    """:func:`fast_update` on whole arrays with numpy, bit for bit: each elementwise operation is the kernel's, and
    ``np.cumsum`` adds the terms of c_k left to right as the kernel's loop does (``np.sum`` would pair them)."""
    m = w.shape[0]
    if ist[SKIP] > 0:                                       # backing off: plain
        ist[SKIP] -= 1
        out_u[:], out_l[:] = f_u, f_l
        return
    a, b = f_u - s_u, f_l - s_l
    su = float(np.cumsum(w * a * a)[-1]) if m else 0.0
    sl = float(np.cumsum(w * b * b)[-1]) if m else 0.0
    c = rho * su + sl / rho
    if ist[HAVE_PREV] == 0 or c < eta * ac[C]:
        beta, momentum = momentum_step.py_func(ist, ac, c)  # the kernel's bookkeeping, as Python
        if momentum:                                        # (A5)
            out_u[:] = f_u + beta * (f_u - f_prev[:m])
            out_l[:] = f_l + beta * (f_l - f_prev[m:])
        else:
            out_u[:], out_l[:] = f_u, f_l
        f_prev[:m], f_prev[m:] = f_u, f_l
        return
    if restart.py_func(ist, ac):                            # the kernel's bookkeeping, as Python
        if ist[HAVE_PREV] == 1:
            ac[C] = ac[C] / eta
        out_u[:], out_l[:] = f_prev[:m], f_prev[m:]
        return
    if ist[HAVE_PREV] == 1:
        ac[C] = c
    out_u[:], out_l[:] = f_u, f_l
    f_prev[:m], f_prev[m:] = f_u, f_l


class FastArrays:
    """The arrays :func:`fast_update` works on, for states of length ``n`` (= 2 m), with the safeguard's
    ``patience`` (0: no back-off) and ``give_up`` (failed phases in a row after which momentum is off for good; 0:
    never).

    :meth:`args` lays them out in the slots of Anderson's arrays (``anderson_kernel.AndersonArrays.args``), the
    others empty, so that a compiled segment takes either with one signature (``MODE`` tells which)."""

    mode = MODE

    def __init__(self, n: int, patience: int = 0, give_up: int = 0) -> None:
        self.ist = np.zeros(INT_SLOTS, dtype=np.int64)
        self.ist[BACKOFF], self.ist[PATIENCE], self.ist[LIMIT] = 1, patience, give_up
        self.ac = np.array([1.0, math.inf])
        self.f_prev = np.zeros(n)

    def reset(self) -> None:
        """Restart (a change of rho): no momentum, no previous image; the back-off and the counts stay."""
        self.ist[HAVE_PREV] = self.ist[MOMENTUM] = self.ist[PHASE] = 0
        self.ac[A], self.ac[C] = 1.0, math.inf

    def args(self):
        """(ist, ac, f_prev) in the slots (ist, before, F_prev) of Anderson's arrays, empty arrays in the others."""
        v, mat = np.zeros(0), np.zeros((0, 0))
        return (self.ist, self.ac, self.f_prev, v, v, mat, mat, mat, v, mat, v, mat, v)
