"""OSQP's rule with each change of rho priced by the factorisation it costs.

A change of rho refactorises the x-step matrix; OSQP's rule
(:class:`admmkit.policies.OSQPRule`) adopts its estimate whenever it differs
from rho_k by more than the factor ``tolerance``, however recently rho last
changed.  Here a change must also pay for its factorisation, ``price``
iterations' worth of work (a deterministic number the caller sets: the
factorisation's cost over one iteration's, e.g. from the factor's entries):
the estimate is adopted when

    |log(rho_est / rho_k)|  >  log(tolerance) * max(1, price / j)

with j the iterations since the last change.  A change that comes long after
the last (j >= price) is judged as OSQP judges it; one that comes soon after
needs a larger disagreement, in proportion to the work not yet amortised.
``price = 0`` is OSQP's rule.
"""
from __future__ import annotations

import math

from admmkit import IterationRecord

from ._checks import check_number
from .osqp_rule import OSQPRule


class OSQPPricedRule(OSQPRule):
    """OSQP's estimate, adopted when its log-distance to rho exceeds log(tolerance) x max(1, price / iterations since
    the last change)."""

    def __init__(self, interval: int = 50, tolerance: float = 5.0, price: float = 100.0, rho_min: float = 0.0,
                 rho_max: float = math.inf, residuals=None):
        super().__init__(interval=interval, tolerance=tolerance, rho_min=rho_min, rho_max=rho_max,
                         residuals=residuals)
        self.price = check_number("price", price, low=0.0, low_open=False)
        self.last_change = -1

    def reset(self, rho0: float) -> None:
        """Start a new run: the setup's factorisation counts as the last change (at iteration -1)."""
        super().reset(rho0)
        self.last_change = -1

    def update(self, rec: IterationRecord) -> float:
        """At iterations interval, 2 interval, ...: the estimate, if it disagrees with rho by more than its price."""
        if (rec.k + 1) % self.interval:
            return rec.rho
        est = self.clamped_estimate(rec)
        if math.isnan(est):
            return rec.rho
        since = rec.k - self.last_change
        threshold = math.log(self.tolerance) * max(1.0, self.price / since)
        if est <= 0 or abs(math.log(est / rec.rho)) <= threshold:
            return rec.rho
        self.last_change = rec.k
        return est
