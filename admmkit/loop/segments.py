"""Segments: the iterations whose records nobody reads, run by the plug-in in one compiled call.

The loop reads a record at a tested iteration (every ``check_every``-th and
the last), where the policy asks for one
(:meth:`admmkit.Policy.unchanged_until`), and at every iteration when a
callback or the full history is set (a callback with
``every_record = False``, such as the command line's progress bar, is given
only the records of the iterations that run in Python, every tested one
among them).  In between, an iteration only moves the state (x, z, lam, A x)
to the next one, with rho fixed.  A plug-in that can run such iterations of
the run's order in one call implements

    problem.segment(x, z, lam, Ax, rho, alpha, order, count) -> (x, z, lam, Ax, done) or None

returning new arrays after ``done`` <= ``count`` iterations (fewer where a
step would meet a non-finite number: the loop's own iteration then meets the
failure where it would have anyway), or None where it cannot (another order,
another solver).  Its iterates must be those of the Python steps bit for
bit; the QP plug-in's (``admmkit.problems.qp.segment``) is built from
:mod:`admmkit.linalg.compiled`.  With OSQP's settings (the test every 25
iterations, rho every 50) the loop's Python runs once in 25 iterations.

A plug-in whose ``segment`` also takes ``read=True`` runs the read
iteration itself too: ``count`` iterations, the last of them the read one,
returning ``(x, z, lam, Ax, done, last)`` with ``last = (x_j, z_j, lam_j,
Ax_j, hat)``, the read iteration's inputs and its relaxed vector (None when
alpha = 1), when ``done == count``.  The loop then builds that iteration's
record from the segment's numbers instead of running its steps in Python
(:meth:`FastForward.serve`): the same bits, about 25 us less per test on a
small QP.

A plug-in whose ``segment`` also takes ``check`` makes the loop's decisions at
tested iterations itself where they are "go on": ``check`` is a
:class:`SegmentChecks` (the tested iterations, the index of the segment's
first iteration, the stopping rule and the policy), ``count`` runs to the
last iteration, and the segment ends after the first iteration where the
loop's Python must look (the rule would fire, the policy would change rho or
reads a record the plug-in does not compute, a norm is out of range), which
it returns as the read one, as above.  It must end there whenever the loop
would not go on, so the run (iterates, iterations, status, rho) is the one
without it; only the history rows of the iterations tested in the segment
have NaN norms.  The QP plug-in does so for OSQP's test and rule
(``admmkit.problems.qp.segment_checks``).  Not with a callback (it sees every
tested record) unless the callback has ``every_tested = False`` (it is content
with the records of the iterations that run in Python: a deadline, a
statistic of rho); with an accelerator only where ``segment`` takes ``accel``
too (below), whose steps then follow the tested iterations it goes on from;
under a time limit a segment runs at most TIME_LIMIT_CHECKS tested iterations.

With an accelerator, the loop takes its step after every iteration: a
plug-in whose ``segment`` takes ``accel`` takes those steps itself, between
the iterations it runs (all but a read last one, whose step the loop takes):
``accel`` is the accelerator's ``kernel_state()`` (Anderson bound to a
weighted inner product: its weights, safeguard, regularization and the
arrays of ``admmkit.loop.anderson_kernel``, updated in place; restarted fast
ADMM's: its weights, eta and the arrays of ``admmkit.loop.fast_kernel``), and
its steps must be the loop's bit for bit.  Other accelerators (a user's own)
run every iteration in Python.

The first iteration of a run runs in Python, so that what the plug-in's
own steps return is checked (``admmkit.loop.checks.check_step``) before a
segment, which bypasses them, runs; unless the plug-in sets
``trusted_steps = True`` (its steps are the package's own, checked by its
tests: the QP plug-in), whose segments may start at the first iteration.

What a segment changes, and nothing else: its iterations get history rows
with rho and the time at the segment's end, and NaN for every norm (a lean
history computes none there either); a time limit is tested at its end.
"""
from __future__ import annotations

import functools
import importlib.util
import inspect
import time

perf = time.perf_counter
#: True when numba is installed, asked without importing it so that ``import admmkit`` stays light
#: (a plug-in's kernel imports :mod:`admmkit.linalg.compiled` at its first segment)
AVAILABLE = importlib.util.find_spec("numba") is not None
#: a segment shorter than this is not worth the call
MIN_SEGMENT = 2
#: under a time limit, a segment that tests in its kernel runs at most this many tested iterations (the limit is
#: tested when a segment ends)
TIME_LIMIT_CHECKS = 4


class SegmentChecks:
    """What a segment that makes the loop's tests needs: the iterations k with (k + 1) % ``every`` == 0 are tested,
    the segment's first iteration is ``first``, and the run's stopping rule ``stop`` and ``policy``."""

    __slots__ = ("every", "first", "stop", "policy")

    def __init__(self, every: int, first: int, stop, policy) -> None:
        self.every, self.first, self.stop, self.policy = every, first, stop, policy


class FastForward:
    """Runs ``problem.segment`` up to the next iteration whose record is read (or does nothing, when it cannot).

    ``segments`` and ``iterations`` count the calls and the iterations they ran, ``seconds`` their time.
    """

    __slots__ = ("problem", "run", "enabled", "reads", "tests", "start", "pending", "segments", "iterations",
                 "seconds", "accel")

    def __init__(self, run, enabled: bool = True, accel=None) -> None:
        problem = run.problem
        self.problem, self.run, self.accel = problem, run, accel
        watcher = run.callback is None or not getattr(run.callback, "every_record", True)   # e.g. a progress bar
        self.enabled = (enabled and AVAILABLE and callable(getattr(problem, "segment", None))
                        and watcher and run.history.mode == "lean")
        if accel is not None:           # an accelerator: only a segment that takes its steps itself
            self.enabled = self.enabled and accel.kernel_state() is not None and _takes(type(problem), "accel")
        self.reads = self.enabled and _takes(type(problem), "read")
        sees_tests = run.callback is not None and getattr(run.callback, "every_tested", True)
        self.tests = self.reads and not sees_tests and _takes(type(problem), "check")
        self.start = 0 if getattr(problem, "trusted_steps", False) is True else 1   # the first iteration a segment runs
        self.pending = None             # (x_j, the read iteration's outputs) when the segment ran it
        self.segments = self.iterations = 0
        self.seconds = 0.0

    def next_read(self, k: int) -> int:
        """The first iteration >= k whose record is read: a tested one, or one the policy reads."""
        every, last = self.run.check_every, self.run.max_iter - 1
        tested = min(k + (-(k + 1)) % every, last)
        return min(tested, self.run.policy.unchanged_until(k))

    def __call__(self, k: int, x, z, lam, Ax, rho: float):
        """(x, z, lam, Ax, k) after the iterations k .. j - 1 that nobody reads (j: :meth:`next_read`); where the
        plug-in runs the read iteration j too, its outputs wait for :meth:`serve`."""
        if not self.enabled or k < self.start:     # the first iteration in Python: its steps' returns are checked
            return x, z, lam, Ax, k
        run = self.run
        if self.tests:                      # to the last iteration: the plug-in ends where the loop must look
            count = run.max_iter - k
            if run.time_limit is not None:
                count = min(count, self.next_read(k) - k + 1 + (TIME_LIMIT_CHECKS - 1) * run.check_every)
        else:
            count = self.next_read(k) - k + self.reads          # with the read iteration, if the plug-in runs it
        if count < (1 if self.reads else MIN_SEGMENT):
            return x, z, lam, Ax, k
        t0 = perf()
        extra = {} if self.accel is None else {"accel": self.accel.kernel_state()}
        if self.tests:
            out = self.problem.segment(x, z, lam, Ax, rho, run.alpha, run.order, count, read=True,
                                       check=SegmentChecks(run.check_every, k, run.stop, run.policy), **extra)
        elif self.reads:
            out = self.problem.segment(x, z, lam, Ax, rho, self.run.alpha, self.run.order, count, read=True, **extra)
        else:
            out = self.problem.segment(x, z, lam, Ax, rho, self.run.alpha, self.run.order, count, **extra)
        t1 = perf()
        if self.accel is not None:
            self.accel.after_segment()
        self.seconds += t1 - t0
        if out is None:
            self.enabled = False
            return x, z, lam, Ax, k
        x, z, lam, Ax, done = out[:5]
        if self.reads and out[5] is not None:          # the read iteration ran: its inputs go to the loop
            x_j, z_j, lam_j, Ax_j, hat = out[5]
            self.pending = (x_j, (x, z, lam, Ax, hat))
            x, z, lam, Ax, done = x_j, z_j, lam_j, Ax_j, done - 1
        self.run.history.append_unread(k, done, rho, self.run.ctx, t1 - self.run.ctx.start)
        self.segments += 1
        self.iterations += done
        return x, z, lam, Ax, k + done

    def serve(self, iterate):
        """``iterate`` (of :mod:`admmkit.loop.steps`), answering from the segment when it ran this very iteration."""
        def served(x, z, lam, Ax, rho, take_r):
            pending, self.pending = self.pending, None
            if pending is not None and pending[0] is x:
                self.iterations += 1
                return (*pending[1], None, perf())     # ||r|| not taken: the record computes it if read
            return iterate(x, z, lam, Ax, rho, take_r)
        served.seconds = iterate.seconds
        return served


@functools.lru_cache(maxsize=None)
def _takes(kind: type, keyword: str) -> bool:
    """Whether ``kind.segment`` takes ``keyword`` (``read``, ``accel``; asked once per class)."""
    try:
        return keyword in inspect.signature(kind.segment).parameters
    except (TypeError, ValueError):
        return False
