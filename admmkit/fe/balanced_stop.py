"""The stop balanced with the discretisation error (Ern & Vohralik's adaptive inexact stopping).

Iterating once the algebraic error is far below the discretisation error buys
nothing.  A plug-in with error estimates subclasses :class:`BalancedStop` and
gives the two measures of an iterate, in the same (energy) norm:
:meth:`BalancedStop.algebraic_error_bound` (a guaranteed bound of the algebraic
error, inf where it cannot tell) and :meth:`BalancedStop.discretisation_estimate`.
The rule fires when

    bound <= gamma x estimate.

**gamma.**  The default ``GAMMA = 0.3`` aims the stop at the middle, on a log
scale, of the band [0.05, 0.5] of the discretisation error that issue #24
asks the algebraic error at the stop to lie in: the bound is guaranteed, so
the algebraic error is at most 0.3 of the estimate, and the error of the
returned iterate is at most 1.3 times the discretisation error by the
triangle inequality (about 1.04 times where the two are orthogonal).  A test
every iteration at 0.1 would need the error to fall by less than 2x an
iteration to stay above 0.05; the measured fall is up to 4.5x (contact,
warm-started levels).

**When it is tested.**  A test costs the bound (the obstacle: two solves with
K; contact: O(n_c^2) on the boundary), so it is not taken at every
iteration.  The first two tests are at iterations 1 and 2 (a warm-started
level may be done there; a plug-in may set ``first_tests`` later); after
them the bound's decrease per iteration between the last two tests, q,
predicts in how many iterations it crosses gamma x the estimate, ``log(bound / (gamma eta)) / log(1 / q)``, and the next
test is then, rounded down, at least 1 and at most ``every`` iterations later.
Where the bound did not fall (it may rise for a few iterations while the
iterate's contact set moves, as on the obstacle's warm P2 levels) there is
nothing to predict from, and the interval doubles: 1, 2, 4, ... up to
``every``, rather than jumping to ``every`` at once (on an obstacle level
of 4,165 unknowns the next test came at iteration 18, though the bound had
been below gamma x the estimate from iteration 9).  Within ``NEAR`` (8) times
gamma x the estimate the bound is tested at every iteration, whatever it
predicts: one iteration may cross the threshold after a plateau (a cold
radial P2 level's bound stayed at 3.3-4 times the estimate for four
iterations, then fell to 0.6 of it in one as rho rose; the schedule's next
test came ten iterations later, when the error was 0.02 of the estimate).
So the stop comes near the crossing, not up to ``every`` iterations past it.  ``converging`` says whether
the last test predicted the crossing within ``every`` iterations: a penalty
rule may leave rho alone while it does (:class:`admmkit.fe.adaptive.HeldRho`).  The schedule reads
iteration counts and bounds only, never the clock: the iterates do not depend
on the machine.  An iterate at which x, z and lam stopped changing (ADMM's
fixed point, the discrete solution: a warm level can start on it) is tested
at once, whatever the schedule, rather than left to end ``stalled``.

**The estimate**, often the dearer of the two, is computed afresh only where
the bound is within twice gamma x the last estimate (it moves little from one
iterate to the next), and there only where the last estimate would let the
rule fire or is ``REFRESH`` iterations old; the rule fires only on a fresh one.
"""
from __future__ import annotations

import math

from ..loop.record import IterationRecord
from ..loop.stopping import StoppingRule
from ..loop.termination import stalled

#: the default gamma; the algebraic error at the stop is at most this times the estimated discretisation error
GAMMA = 0.3
#: a balanced stop refreshes an estimate that would not let it fire after this many iterations (near firing)
REFRESH = 10
#: the tests at these iterations come before any prediction (a warm-started level may be done at once)
FIRST_TESTS = (1, 2)
#: within this factor of gamma x the estimate the bound is tested at every iteration (one iteration may cross it)
NEAR = 8.0


class BalancedStop(StoppingRule):
    """Stop when a bound of the algebraic error is below ``gamma`` x the estimated discretisation error.

    ``every``: the most iterations between two tests (the tests are scheduled by
    the bound's observed decrease: module docstring).  ``algebraic`` and
    ``discretisation`` hold the last values computed, ``tests`` the iterations
    tested, ``converging`` whether the last test predicted the crossing within
    ``every`` iterations.  ``tolerance`` is None: the rule's own test is the accuracy check,
    so ``converged`` means "the algebraic error is below gamma x the estimated
    discretisation error".
    """

    requires = ()
    tolerance = None
    #: the first two tests (a plug-in whose bound is dear and never fires at the first iteration tests later)
    first_tests = FIRST_TESTS
    #: within this factor of gamma x the estimate, a test at every iteration (``NEAR``)
    near = NEAR

    def __init__(self, gamma: float = GAMMA, every: int = 10):
        if isinstance(gamma, bool) or not isinstance(gamma, (int, float)) or not 0 < gamma <= 1:
            raise ValueError(f"gamma = {gamma!r} is outside the accepted range (0, 1]")
        if isinstance(every, bool) or not isinstance(every, int) or every < 1:
            raise ValueError(f"every = {every!r} is outside the accepted range: an integer >= 1")
        self.gamma, self.every = float(gamma), every
        self.algebraic = self.discretisation = math.nan
        self.tests: list[int] = []
        self._seen = 0                                 # the last iteration this rule was asked about
        self._restart()
        self.name = f"balanced(gamma={self.gamma:g}): algebraic error bound <= gamma x ZZ discretisation estimate"

    def algebraic_error_bound(self, rec: IterationRecord) -> float:
        """A guaranteed bound of the algebraic error of the iterate the run returns (inf: none here)."""
        raise NotImplementedError

    def discretisation_estimate(self, rec: IterationRecord) -> float:
        """An estimate of the discretisation error of that iterate."""
        raise NotImplementedError

    def _restart(self) -> None:
        """The schedule of a new run (the last estimate is kept: the next run is on the same mesh)."""
        self._estimated_at = -REFRESH                  # the iteration of the last estimate
        self._next = self.first_tests[0]               # the iteration (counted from 1) of the next test
        self._last: tuple[int, float] | None = None    # (iteration, bound) of the last finite test
        self.converging = False                        # the last test predicted the crossing within ``every``

    def fired(self, rec: IterationRecord) -> str | None:
        """The rule's name when the bound is at most gamma x the estimate at this record, else None."""
        n = rec.k + 1
        if n <= self._seen:                            # a new run with the same rule (a Coulomb fixed point's)
            self._restart()
        self._seen = n
        if n < self._next and not stalled(rec, rec.computed()):   # ADMM's fixed point: tested at once
            return None
        self.tests.append(n)
        self.algebraic = bound = self.algebraic_error_bound(rec)
        if not math.isfinite(bound):
            self._next, self.converging = n + self.every, False
            return None
        if not self._near_firing(rec.k, bound):
            self._schedule(n, bound)
            return None
        self.discretisation = self.discretisation_estimate(rec)     # fresh at every iterate that may fire
        self._estimated_at = rec.k
        if bound <= self.gamma * self.discretisation:
            return self.name
        self._schedule(n, bound)
        return None

    def _near_firing(self, k: int, bound: float) -> bool:
        """Whether this test needs a fresh estimate: none yet, or the bound within 2 gamma x the last one and
        either at most gamma x it or the last one REFRESH iterations old."""
        target = self.gamma * self.discretisation
        if not math.isfinite(target):
            return True
        return bound <= target or (bound <= 2.0 * target and k - self._estimated_at >= REFRESH)

    def _schedule(self, n: int, bound: float) -> None:
        """The next test: ``first_tests``, then where the bound's decrease per iteration since the last test
        predicts it crosses gamma x the estimate (at least 1, at most ``every`` iterations on); where it predicts
        nothing (the bound did not fall), twice the last interval, at most ``every``."""
        last, self._last = self._last, (n, bound)
        later = [t for t in self.first_tests if t > n]
        if later:
            self._next = later[0]
            return
        # without a prediction below: twice the last interval, up to ``every``
        steps = self.every if last is None else min(self.every, 2 * (n - last[0]))
        self.converging = False
        if last is not None and 0.0 < bound < last[1]:
            q = (bound / last[1]) ** (1.0 / (n - last[0]))                  # decrease per iteration, < 1
            ratio = bound / (self.gamma * self.discretisation)                  # > 1: it did not fire
            if 1.0 < ratio < math.inf and q < 1.0:                              # q rounds to 1: no prediction
                predicted = math.log(ratio) / -math.log(q)
                steps, self.converging = min(self.every, max(1, int(predicted))), predicted <= self.every
        if bound <= self.near * self.gamma * self.discretisation:
            steps = 1
        self._next = n + steps


__all__ = ["GAMMA", "REFRESH", "FIRST_TESTS", "NEAR", "BalancedStop"]
