"""OSQP 1.x's rho update triggered by the KKT error (``adaptive_rho = 3``, OSQP_ADAPTIVE_RHO_UPDATE_KKT_ERROR).

OSQP 1.x can decide *when* to update rho by progress instead of by the
iteration count: rho is re-estimated once the relative KKT error

    e_k = max(r_rel, s_rel)   (the normalised primal and dual residuals of the iterate)

has fallen to ``fraction`` times its value at the last update (OSQP's
``adaptive_rho_fraction``, default 0.4), and the estimate is the one of
:class:`admmkit.policies.OSQPRule` (Stellato et al. 2020, eq. (34)):

    rho_est = rho_k sqrt(r_rel / s_rel),  adopted if it differs from rho_k by more than ``tolerance``.

The error is read every ``interval`` iterations (OSQP reads it where it checks
termination); so the rule changes rho (and the x-step matrix is factorised)
only after the iterate made progress, where the rule of every 50 iterations
can refactorise on a plateau.  ``residuals``: a function record -> (r_rel,
s_rel), as in OSQPRule (the QP plug-in passes OSQP's normalisation).
"""
from __future__ import annotations

import math

from admmkit import IterationRecord

from ._checks import check_number
from .osqp_rule import OSQPRule


class OSQPKKTRule(OSQPRule):
    """OSQP's estimate, adopted once the KKT error max(r_rel, s_rel) fell to ``fraction`` x its value at the last update."""

    def __init__(self, interval: int = 25, tolerance: float = 5.0, fraction: float = 0.4, rho_min: float = 0.0,
                 rho_max: float = math.inf, residuals=None):
        super().__init__(interval=interval, tolerance=tolerance, rho_min=rho_min, rho_max=rho_max,
                         residuals=residuals)
        self.fraction = check_number("fraction", fraction, low=0.0, high=1.0)
        self.reference = math.inf

    def reset(self, rho0: float) -> None:
        """Start a new run: no update yet, so the first read error is the reference."""
        super().reset(rho0)
        self.reference = math.inf

    def update(self, rec: IterationRecord) -> float:
        """At iterations interval, 2 interval, ...: the estimate, if the KKT error fell below ``fraction`` x the reference."""
        if (rec.k + 1) % self.interval:
            return rec.rho
        r, s = self.relative_residuals(rec)
        error = max(r, s)
        if not math.isfinite(error):
            return rec.rho
        if math.isinf(self.reference):
            self.reference = error                     # the first reading: progress is measured from here
            return rec.rho
        if error > self.fraction * self.reference:
            return rec.rho
        self.reference = error
        return self.adopted(rec, self.clamped_estimate(rec))
