"""Residual balancing on normalised residuals with an adaptive factor (Wohlberg 2017).

B. Wohlberg, "ADMM penalty parameter selection by residual balancing",
arXiv:1704.06209 (2017), sections 3-4; the same rule is SPORCO's
``AutoRho`` with ``AutoScaling`` (``sporco.admm.admm.ADMM.update_rho``).

With the relative residuals (Wohlberg's eq. (15)-(16), Boyd's normalisation)

    r = ||r^{k+1}|| / max(||A x||, ||z||, ||c||)      (``primal_residual_rel``)
    s = ||s^{k+1}|| / ||A^T M lam||  (order "xz"),  ||s^{k+1}|| / ||lam||_M  ("zx")
                                                      (``dual_residual_rel``)

the factor adapts to the imbalance, capped at tau_max:

    tau_k = sqrt(r / (xi s))   if r > xi s
          = sqrt(xi s / r)     otherwise,
    tau_k = min(tau_k, tau_max);   tau_k = tau_max if r = 0 or s = 0

    rho_{k+1} = tau_k rho_k    if r > xi mu s
              = rho_k / tau_k  if s > (mu / xi) r
              = rho_k          otherwise.

xi is the target ratio r/s (1 balances them), mu the tolerated imbalance.
Literature defaults: xi = 1, mu = 10, tau_max = 100 (Wohlberg's section 5;
SPORCO calls them RsdlTarget, RsdlRatio and Scaling).  ``period`` applies the
rule every period-th iteration (SPORCO's ``Period``; 1 = every iteration).
The multiplier is unscaled in admmkit, so SPORCO's rescaling U <- U / tau_k
has no counterpart here.
"""
from __future__ import annotations

import math

from admmkit import IterationRecord, Policy

from ._checks import check_int, check_number


class Wohlberg(Policy):
    """Residual balancing on relative residuals with the adaptive factor tau_k <= tau_max."""

    requires = ("dual_residual",)

    def __init__(self, xi: float = 1.0, mu: float = 10.0, tau_max: float = 100.0, period: int = 1):
        self.xi = check_number("xi", xi, low=0.0)
        self.mu = check_number("mu", mu, low=1.0, low_open=False)
        self.tau_max = check_number("tau_max", tau_max, low=1.0)
        self.period = check_int("period", period, low=1)

    def factor(self, r: float, s: float) -> float:
        """tau_k: sqrt of the (target-corrected) residual ratio, capped at tau_max."""
        if r == 0 or s == 0 or math.isinf(r) or math.isinf(s):
            return self.tau_max
        ratio = r / (self.xi * s)
        return min(math.sqrt(ratio if ratio > 1 else 1.0 / ratio), self.tau_max)

    def update(self, rec: IterationRecord) -> float:
        """rho_{k+1} from the relative residuals of iteration k."""
        if (rec.k + 1) % self.period:
            return rec.rho
        r, s = rec.primal_residual_rel, rec.dual_residual_rel
        if math.isnan(r) or math.isnan(s):
            return rec.rho
        if r > self.xi * self.mu * s:
            return rec.rho * self.factor(r, s)
        if s > (self.mu / self.xi) * r:
            return rec.rho / self.factor(r, s)
        return rec.rho
