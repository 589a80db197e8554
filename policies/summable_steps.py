"""Make any rule summable: clip each change of rho to [1/(1+s_j), 1+s_j] with sum s_j < inf.

The paper's convergence theorem (Yuan & Zhang 2023, section 3; the condition
of He, Yang & Wang 2000) needs only that the relative changes of rho are
summable: rho_{k+1}/rho_k in [1/(1+s_k), 1+s_k] with sum_k s_k < inf.  The
paper meets it with its own rule; this wrapper meets it for any rule:

    rho' = inner.update(record)                        (the wrapped rule's wish)
    if rho' != rho_k:  c <- c + 1  (the change counter, as in the paper)
        s = tau                 if c <= c_max
          = 1/(c - c_max)^2     if c >  c_max
        rho_{k+1} = rho_k * clip(rho'/rho_k, 1/(1+s), 1+s)
    else: rho_{k+1} = rho_k

so sum s <= tau c_max + pi^2/6 and rho_k stays in [rho_0/C, C rho_0] with
C = (1+tau)^c_max sinh(pi)/pi, the paper's bound, whatever the wrapped rule
does.  The defaults tau = 2, c_max = 100 are the paper's (eq. (17)).
Caveat (docs/framework.md, docs/policies.md): with these defaults C is about
1e48, so the bound does not keep rho moderate; a wrapped rule that keeps
asking for larger rho can still run away for c_max changes.  Smaller c_max
(or tau) tightens it.
"""
from __future__ import annotations

import math

from admmkit import IterationRecord, Policy

from ._checks import check_int, check_number
from ._wrap import as_policy


class SummableSteps(Policy):
    """Clip the changes of a wrapped rule (default: Wohlberg's) so that they are summable."""

    def __init__(self, inner: Policy | str = "wohlberg", tau: float = 2.0, c_max: int = 100):
        self.inner = as_policy(inner)
        self.tau = check_number("tau", tau, low=0.0)
        self.c_max = check_int("c_max", c_max, low=0)
        self.requires = tuple(self.inner.requires)

    def reset(self, rho0: float) -> None:
        """Reset the wrapped rule and the change counter."""
        super().reset(rho0)
        self.inner.reset(rho0)
        self.changes = 0      # c: how many times rho changed
        self.s_sum = 0.0      # sum of the s used so far
        self.clipped = 0      # how many wished changes were clipped

    @property
    def bound(self) -> float:
        """C >= prod (1 + s_j): rho_k stays in [rho_0/C, C rho_0]."""
        return (1.0 + self.tau) ** self.c_max * math.sinh(math.pi) / math.pi

    def step(self, changes: int) -> float:
        """s_c for the c-th change: tau for c <= c_max, then 1/(c - c_max)^2."""
        return self.tau if changes <= self.c_max else 1.0 / (changes - self.c_max) ** 2

    def update(self, rec: IterationRecord) -> float:
        """The wrapped rule's rho, its ratio to rho_k clipped to [1/(1+s), 1+s]."""
        wish = self.inner.update(rec)
        if not (isinstance(wish, (int, float)) and math.isfinite(wish) and wish > 0):
            return wish                   # let the loop report the wrapped rule's bad value
        if wish == rec.rho:
            return rec.rho
        self.changes += 1
        s = self.step(self.changes)
        self.s_sum += s
        ratio = min(max(wish / rec.rho, 1.0 / (1.0 + s)), 1.0 + s)
        if ratio != wish / rec.rho:
            self.clipped += 1
        return rec.rho * ratio
