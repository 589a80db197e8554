"""Residual balancing (He, Yang & Wang 2000; Boyd et al. 2011, section 3.4.1).

    rho_{k+1} = tau_incr rho_k   if ||r^{k+1}|| > mu ||s^{k+1}||
              = rho_k / tau_decr if ||s^{k+1}|| > mu ||r^{k+1}||
              = rho_k            otherwise

with r the primal and s Boyd's dual residual, both in the problem's norms
(Boyd et al. 2011, eq. (3.13); defaults mu = 10, tau_incr = tau_decr = 2).
"""
from __future__ import annotations

from admmkit import IterationRecord, Policy

from ._checks import check_number


class ResidualBalancing(Policy):
    """Boyd's residual balancing: keep ||r|| and ||s|| within a factor mu of each other."""

    requires = ("dual_residual",)

    def __init__(self, mu: float = 10.0, tau_incr: float = 2.0, tau_decr: float = 2.0):
        self.mu = check_number("mu", mu, low=1.0)
        self.tau_incr = check_number("tau_incr", tau_incr, low=1.0)
        self.tau_decr = check_number("tau_decr", tau_decr, low=1.0)

    def update(self, rec: IterationRecord) -> float:
        """Boyd et al. (2011) eq. (3.13)."""
        r, s = rec.primal_residual, rec.dual_residual
        if r > self.mu * s:
            return rec.rho * self.tau_incr
        if s > self.mu * r:
            return rec.rho / self.tau_decr
        return rec.rho
