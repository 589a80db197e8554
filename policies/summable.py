"""The paper's self-adaptive rule (Yuan & Zhang 2023, section 3; SADMM = Algorithm 2).

After iteration k, with the norms of the constraint space (the lumped boundary
mass on Gamma_C for contact):

    w_k = ||lam^{k+1} - lam^k|| / (rho_k ||A x^{k+1} - A x^k||)
    c_0 = 0,  c_{k+1} = c_k       if 1/(1+tau) <= w_k <= 1+tau
                      = c_k + 1   otherwise                     (how often rho changed)
    s_k = tau                      if c_{k+1} > c_k and c_{k+1} <= c_max
        = 1/(c_{k+1} - c_max)^2    if c_{k+1} > c_k and c_{k+1} >  c_max
        = 0                        otherwise
    rho_{k+1} = rho_k / (1 + s_k)  if w_k < 1/(1+tau)
              = (1 + s_k) rho_k    if w_k > 1+tau
              = rho_k              otherwise                    eq. (17)

Since sum s_k < inf, rho_k stays in [rho_0/C_s, C_s rho_0] with
C_s = prod (1 + s_k) <= (1+tau)^c_max * prod_{j>=1} (1 + 1/j^2)
    = (1+tau)^c_max * sinh(pi)/pi,
and the method converges for any rho_0 > 0 (the paper's Theorems 1 and 2).
In the paper x is the displacement u, A x = u_n on Gamma_C and tau = 2,
c_max = 100.  Edge cases: w_k = +inf when A x did not move but lam did
(rho increases); when neither moved, w_k is undefined and rho is kept.
"""
from __future__ import annotations

import math

from admmkit import IterationRecord, Policy

from ._checks import check_int, check_number


class Summable(Policy):
    """SADMM's rule: residual balancing on w_k with summable changes s_k."""

    def __init__(self, tau: float = 2.0, c_max: int = 100):
        self.tau = check_number("tau", tau, low=0.0)
        self.c_max = check_int("c_max", c_max, low=0)

    def reset(self, rho0: float) -> None:
        """Start a run: the change counter c_0 = 0."""
        super().reset(rho0)
        self.changes = 0  # c_k
        self.s_sum = 0.0  # sum of the s_k used so far

    @property
    def bound(self) -> float:
        """C_s: an upper bound of prod (1 + s_k), so rho_k in [rho_0/C_s, C_s rho_0]."""
        return (1.0 + self.tau) ** self.c_max * math.sinh(math.pi) / math.pi

    def w(self, rec: IterationRecord) -> float:
        """w_k = ||lam^{k+1} - lam^k|| / (rho_k ||A x^{k+1} - A x^k||)."""
        num, den = rec.lam_change, rec.rho_Ax_change
        if den > 0:
            return num / den
        return math.inf if num > 0 else math.nan

    def update(self, rec: IterationRecord) -> float:
        """Return rho_{k+1} by eq. (17) with the paper's s_k."""
        w = self.w(rec)
        band_low, band_high = 1.0 / (1.0 + self.tau), 1.0 + self.tau
        if math.isnan(w) or band_low <= w <= band_high:
            return rec.rho                        # c_{k+1} = c_k, s_k = 0
        self.changes += 1                         # c_{k+1} = c_k + 1
        if self.changes <= self.c_max:
            s = self.tau
        else:
            s = 1.0 / (self.changes - self.c_max) ** 2
        self.s_sum += s
        return rec.rho * (1.0 + s) if w > band_high else rec.rho / (1.0 + s)
