"""Polishing during the run: OSQP's termination test, and a polished point that passes it ends the run early.

OSQP polishes once, after its test held at the requested accuracy
(:mod:`admmkit.problems.qp.polish`).  Polishing is a Newton-like step: once the
active set of the iterate is right, the reduced KKT system (P1) gives the
solution to round-off, however loose the iterate was.  So admmkit's preset
polishes *before* the test holds:

- at a check where OSQP's test holds at ``gate`` times the tolerances (the
  iterate is near the solution, and its active set likely right), the
  iterate is polished; while the tries fail, the waits between them are
  ``every`` iterations and then ``backoff`` times the wait before (2: 100,
  200, 400, ... iterations), since a try costs a factorisation of the reduced KKT system
  (a PRIMAL4 try about as much as its 50 iterations) and a failed one says
  the active set is still moving (iteration-based: deterministic);
- a try is skipped when the active set it would guess is the one of the
  last try, which failed (the same reduced system again), and when it holds
  more rows than x has entries (k > n) after such a degenerate try has
  failed: A_act then has dependent rows, (P1)'s multipliers are set by delta
  alone and refinement against the singular unregularised matrix drifts
  (on the 86 problems of qpbenchmark's class, 114 of 116 degenerate tries
  failed, QSCSD6's by a dual residual of 1e5; the two that passed, one
  surplus row on QSCAGR7, ended its runs, so the first degenerate try is
  made);
- the polished point (x, z = clip(A x, l, u), y) of the user's problem,
  y with no component pushing against an infinite bound (set to 0, as the
  gap's support function and a neutral harness see it), is put to OSQP's
  own test at the requested tolerances (residuals (R1), (R2)
  and the duality gap (R3), :func:`admmkit.problems.qp.kkt.osqp_residuals`);
  if it passes, the run stops "solved" with that point, else it goes on.

A "solved" of the iterate itself is confirmed by the same test on its (x,
z, y) computed in the user's problem (:meth:`PolishingTermination.confirmed`).
The status never rests on the iterate alone: a run ended by polishing returns the
polished point, and the test it passed is the one the result reports
(``QPResult.residuals``).  Every try counts in ``tries``.
"""
from __future__ import annotations

import numpy as np

from admmkit import IterationRecord

from .kkt import osqp_residuals
from .polish import polish
from .problem import QP
from .residuals import neutral_residuals
from .termination import SOLVED, QPTermination


def active_set(qp: QP, zb: np.ndarray, yb: np.ndarray) -> tuple[bytes, int]:
    """The active set polishing guesses at (zb, yb) (:mod:`admmkit.problems.qp.polish`), as bytes (lower, upper),
    and its number of rows."""
    low = zb - qp.ls < -yb
    upp = ~low & (qp.us - zb < yb)
    return np.packbits(low).tobytes() + np.packbits(upp).tobytes(), int(np.count_nonzero(low) + np.count_nonzero(upp))


class PolishingTermination(QPTermination):
    """:class:`QPTermination`, and at a check near the solution a polished point that passes the same test.

    ``gate`` (>= 1): polish when the test holds at ``gate`` x (eps_abs, eps_rel);
    ``every`` (>= 1): iterations before the next try, multiplied by ``backoff`` (>= 1) after each failed try
    (``backoff = 1``: a try every ``every`` iterations, the rule before issue #50's timing); ``delta``, ``refine``: the
    polishing system's regularisation and refinement steps.  After a stop on a
    polished point, ``polished`` is (x, z, y, info) of the user's problem
    (None otherwise) and ``last`` the residuals of that point.
    """

    def __init__(self, qp: QP, eps_abs: float = 1e-3, eps_rel: float = 1e-3, *, gate: float = 1e3,
                 every: int = 100, backoff: float = 2.0, delta: float = 1e-6, refine: int = 3, **options):
        super().__init__(qp, eps_abs, eps_rel, **options)
        if not (np.isfinite(gate) and gate >= 1):
            raise ValueError(f"gate must be a finite number >= 1, got {gate!r}")
        if isinstance(every, bool) or not isinstance(every, (int, np.integer)) or every < 1:
            raise ValueError(f"every must be an integer >= 1, got {every!r}")
        if isinstance(backoff, bool) or not (isinstance(backoff, (int, float, np.floating)) and np.isfinite(backoff)
                                                    and backoff >= 1):
            raise ValueError(f"backoff must be a finite number >= 1, got {backoff!r}")
        self.backoff = float(backoff)
        self.gate, self.every, self.delta, self.refine = float(gate), int(every), float(delta), int(refine)
        self.name += f"+polish(gate={self.gate:g})"
        self.names[SOLVED] = self.name

    def kernel_test(self, qp: QP) -> tuple | None:
        """:meth:`QPTermination.kernel_test` with the gate and the iteration of the next try (the segment ends where
        a try may come, :func:`admmkit.problems.qp.segment_checks.go_on`); None for a subclass or another QP."""
        if type(self) is not PolishingTermination or self.qp is not qp:
            return None
        return (self.eps_abs, self.eps_rel, self.gap, self.infeasibility, self.eps_prim_inf, self.eps_dual_inf,
                self.gate, int(self.next_try))

    def reset(self) -> None:
        """Forget the last check and the tries (a rule object can serve several runs)."""
        super().reset()
        self.polished = None
        self.tries = 0
        self.next_try = 0
        self.failures = 0                    # failed tries: the next waits every x backoff^failures iterations
        self.failed = None
        self.skipped = 0                     # degenerate tries not made (one failed already)
        self.degenerate_failed = False

    def passes(self, res: dict, factor: float = 1.0) -> bool:
        """OSQP's test (residuals, and the gap if asked) on ``res`` at ``factor`` x the tolerances."""
        a, r = factor * self.eps_abs, factor * self.eps_rel
        return (res["primal"] <= a + r * res["primal_scale"] and res["dual"] <= a + r * res["dual_scale"]
                and (not self.gap or abs(res["gap"]) <= a + r * res["gap_scale"]))

    def confirmed(self, rec: IterationRecord) -> bool:
        """OSQP's test again, on the iterate's (x, z, y) in the user's problem, summed there, and with the neutral
        residuals of (x, y) in place of OSQP's (the test itself sums in the scaled problem: where the objective's
        terms are 1e12, the gaps differ by round-off, and a point must pass where a harness measures it)."""
        qp = self.qp
        x, z, y = qp.unscaled(rec.x, rec.z, rec.lam_z)
        res = osqp_residuals(qp, x, z, y)
        return self.passes(res) and self.passes(res | neutral_residuals(qp, x, y))

    def fired(self, rec: IterationRecord) -> str | None:
        """OSQP's test on the iterate; failing it, near the solution, the same test on the polished iterate."""
        name = super().fired(rec)
        if name is not None and self.outcome == SOLVED and not self.confirmed(rec):
            self.outcome = None                 # the test held in the scaled problem only: go on
            return None
        if name is not None or self.last is None:
            return name
        if rec.k < self.next_try or not self.passes(self.last, self.gate):
            return None
        self.next_try = rec.k + int(self.every * self.backoff ** self.failures)
        qp = self.qp
        yb = rec.lam_z if qp.w is None else qp.w * rec.lam_z
        guess, rows = active_set(qp, rec.z, yb)
        if guess == self.failed:
            return None                         # the active set of the last failed try: the same point again
        degenerate = rows > qp.n                # more active rows than unknowns: A_act has dependent rows
        if degenerate and self.degenerate_failed:
            self.skipped += 1
            return None
        self.tries += 1
        x, y, info = polish(qp, qp.relaxed_x(rec.x), rec.z, yb, delta=self.delta, refine=self.refine,
                            order=getattr(qp._solver, "order", None))
        self.failed = guess
        if x is None:
            self.failures += 1
            self.degenerate_failed |= degenerate
            return None
        y = np.where(np.isinf(qp.u), np.minimum(y, 0.0), y)       # no multiplier pushes against an infinite bound
        y = np.where(np.isinf(qp.l), np.maximum(y, 0.0), y)
        z = np.clip(qp.A @ x, qp.l, qp.u)
        res = osqp_residuals(qp, x, z, y)
        if not self.passes(res):
            self.failures += 1
            self.degenerate_failed |= degenerate
            return None
        self.last, self.polished = res, (x, z, y, info)
        self.outcome, self.certificate = SOLVED, None
        return self.name
