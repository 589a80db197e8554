"""When a run ends at a tested iteration: divergence, the stopping rule, or stalled iterates.

The loop tests every ``check_every``-th iteration and the last one (the
iterates never depend on it).  A test looks at the record in this order:

- divergence: a norm already computed is inf or NaN (if none is, ||r||_M is
  computed so that a blow-up is seen); the dual residual and scale are not
  watched in order "xz" without ``adjoint_norm``, where they are NaN by design;
- the stopping rule: it fired (its name, status ``converged``, or a
  :class:`admmkit.loop.stopping.Stop` with its own status and certificate; any
  other answer is a TypeError, :func:`admmkit.loop.stopping.verdict`);
- stalling: x, z and lam stopped changing before the rule fired.
"""
from __future__ import annotations

import math
import time

from .norms import LAZY_FIELDS
from .result import Status
from .stopping import verdict

perf = time.perf_counter
_isfinite = math.isfinite
#: the lazy fields a stall test looks at first (their indices in ``IterationRecord.computed()``)
_STALL = tuple(LAZY_FIELDS.index(name) for name in ("x_change", "z_change", "primal_residual"))
#: the lazy fields watched for divergence: all, or all but the dual residual and scale (NaN by design in order
#: "xz" without ``adjoint_norm``)
_WATCH_ALL = tuple(range(len(LAZY_FIELDS)))
_WATCH_NO_DUAL = tuple(i for i, name in enumerate(LAZY_FIELDS) if name not in ("dual_residual", "dual_scale"))


class Termination:
    """The tests of one run; ``seconds`` is the time they took, ``stopped_by`` what fired (or None)."""

    __slots__ = ("stop", "watched", "stopped_by", "seconds")

    def __init__(self, run) -> None:
        ctx = run.ctx
        self.stop = run.stop
        # the lazy fields whose non-finite value means divergence (a missing adjoint gives NaN legitimately)
        self.watched = _WATCH_ALL if ctx.has_adjoint or ctx.order == "zx" else _WATCH_NO_DUAL
        self.stopped_by, self.seconds = None, 0.0

    def check(self, rec) -> tuple | None:
        """(status, message) if the run ends at this iteration (diverged, the rule fired, stalled), else None."""
        t0 = perf()
        fired = verdict(self.stop, self.stop.fired(rec))     # its name, a Stop or None: else a TypeError
        vals = rec._vals                    # the lazy norms as they stand (rec.computed() without the copy)
        final = None
        if diverged(rec, vals, self.watched):
            final = Status.DIVERGED, f"non-finite iterate at iteration {rec.k + 1}"
        elif fired:
            self.stopped_by = fired
            final = getattr(fired, "status", Status.CONVERGED), f"{fired} fired at iteration {rec.k + 1}"
        elif stalled(rec, vals):
            final = Status.STALLED, f"iterates stopped changing at iteration {rec.k + 1} before {self.stop.name} fired"
        self.seconds += perf() - t0
        return final


def diverged(rec, vals, watched: tuple) -> bool:
    """A computed norm among ``watched`` is inf or NaN, or none is computed and ||r||_M is not finite."""
    for i in watched:
        v = vals[i]
        if v is not None and not _isfinite(v):
            return True
    return vals.count(None) == len(vals) and not _isfinite(rec.primal_residual)


def stalled(rec, vals) -> bool:
    """x, z and lam stopped changing (||x^{k+1} - x^k|| = ||z^{k+1} - z^k|| = ||r|| = 0); the computed norms first."""
    for i in _STALL:
        if vals[i] is not None and vals[i] != 0:
            return False
    return rec.x_change == 0 and rec.z_change == 0 and rec.primal_residual == 0
