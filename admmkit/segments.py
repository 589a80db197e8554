"""Segments: the iterations whose records nobody reads, run by the plug-in in one compiled call.

The loop reads a record at a tested iteration (every ``check_every``-th and
the last), where the policy asks for one
(:meth:`admmkit.Policy.unchanged_until`), and at every iteration when a
callback, an accelerator or the full history is set (a callback with
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
:mod:`admmkit.compiled`.  With OSQP's settings (the test every 25
iterations, rho every 50) the loop's Python runs once in 25 iterations.

What a segment changes, and nothing else: its iterations get history rows
with rho and the time at the segment's end, and NaN for every norm (a lean
history computes none there either); a time limit is tested at its end.
"""
from __future__ import annotations

import importlib.util
import time

perf = time.perf_counter
#: True when numba is installed, asked without importing it so that ``import admmkit`` stays light
#: (a plug-in's kernel imports :mod:`admmkit.compiled` at its first segment)
AVAILABLE = importlib.util.find_spec("numba") is not None
#: a segment shorter than this is not worth the call
MIN_SEGMENT = 2


class FastForward:
    """Runs ``problem.segment`` up to the next iteration whose record is read (or does nothing, when it cannot).

    ``segments`` and ``iterations`` count the calls and the iterations they ran, ``seconds`` their time.
    """

    __slots__ = ("problem", "run", "enabled", "segments", "iterations", "seconds")

    def __init__(self, run, enabled: bool = True) -> None:
        problem = run.problem
        self.problem, self.run = problem, run
        watcher = run.callback is None or not getattr(run.callback, "every_record", True)   # e.g. a progress bar
        self.enabled = (enabled and AVAILABLE and callable(getattr(problem, "segment", None))
                        and watcher and run.history.mode == "lean")
        self.segments = self.iterations = 0
        self.seconds = 0.0

    def next_read(self, k: int) -> int:
        """The first iteration >= k whose record is read: a tested one, or one the policy reads."""
        every, last = self.run.check_every, self.run.max_iter - 1
        tested = min(k + (-(k + 1)) % every, last)
        return min(tested, self.run.policy.unchanged_until(k))

    def __call__(self, k: int, x, z, lam, Ax, rho: float):
        """(x, z, lam, Ax, k) after the iterations k .. j - 1 that nobody reads (j: :meth:`next_read`)."""
        if not self.enabled:
            return x, z, lam, Ax, k
        count = self.next_read(k) - k
        if count < MIN_SEGMENT:
            return x, z, lam, Ax, k
        t0 = perf()
        out = self.problem.segment(x, z, lam, Ax, rho, self.run.alpha, self.run.order, count)
        t1 = perf()
        self.seconds += t1 - t0
        if out is None:
            self.enabled = False
            return x, z, lam, Ax, k
        x, z, lam, Ax, done = out
        self.run.history.append_unread(k, done, rho, self.run.ctx, t1 - self.run.ctx.start)
        self.segments += 1
        self.iterations += done
        return x, z, lam, Ax, k + done
