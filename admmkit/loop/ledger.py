"""What the loop keeps besides the iterates: the history, when to take ||r||, and the user's stops.

After the checks and the policy, :meth:`Ledger.close` ends an iteration: the
history gets its row, the callback sees the record, the loop notes whether
||r||_M was read, and the time limit is tested.

The taken ||r||: when ||r||_M (r = A x^{k+1} - z^{k+1} - c) was read in the last
iteration of the same kind (tested or not), the dual update takes it and writes
lam^{k+1} into r's memory (:func:`admmkit.loop.steps.dual_update_and_residual`): one
array fewer to allocate and write.  The numbers never depend on it (a record
recomputes r if ||r|| is read unexpectedly).  With alpha != 1 the dual update's
vector is not the record's r, and the iteration takes nothing.
"""
from __future__ import annotations

import time

from .checks import callback_answer
from .norms import LAZY_FIELDS
from .result import Status

perf = time.perf_counter
_R = LAZY_FIELDS.index("primal_residual")     # ||r||_M among a record's lazy norms


class Ledger:
    """The history, the callback, the time limit and ``take_r[check]`` (take ||r|| at a plain / tested iteration)."""

    __slots__ = ("history", "callback", "time_limit", "ctx", "take_r")

    def __init__(self, run) -> None:
        self.history, self.callback, self.time_limit, self.ctx = run.history, run.callback, run.time_limit, run.ctx
        self.take_r = [True, True]

    def close(self, rec, rho_next: float, check: bool, final: tuple | None) -> tuple | None:
        """Keep iteration ``rec.k`` and return how the run ends: ``final``, the callback's stop, the time
        limit, or None.

        The callback is called with every record, the last one included; its True ends the run
        with status ``stopped`` unless ``final`` already ends it (an answer other than None or a
        bool is a TypeError naming the callback, ``admmkit.loop.checks.callback_answer``).
        """
        self.history.append(rec, rho_next)
        if self.callback is not None and callback_answer(self.callback, self.callback(rec)) and final is None:
            final = Status.STOPPED, f"callback stopped the run at iteration {rec.k + 1}"
        self.take_r[check] = rec._vals[_R] is not None      # ||r|| read (not merely taken) in this iteration
        if final is None and self.time_limit is not None and perf() - self.ctx.start > self.time_limit:
            final = Status.TIME_LIMIT, f"time_limit={self.time_limit:g} s reached at iteration {rec.k + 1}"
        return final

    def finish(self, rec) -> None:
        """Complete the last record (every norm) and refresh its row of the history."""
        if rec is not None:
            self.history.replace_last(rec.complete())
