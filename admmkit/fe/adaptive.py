"""The pieces every adaptive finite element loop reuses: Dörfler marking, the warm levels' rule, the checks,
the result.

Dörfler (1996): given error indicators eta_T, mark the smallest set M of
cells with sum_{T in M} eta_T^2 >= theta sum_T eta_T^2 (the cells of the
largest indicators first).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from ..policy import Policy, make_policy


@dataclass
class AdaptiveResult:
    """How an adaptive loop ended, its levels, and the last level's model, ADMM result and indicators.

    ``status``: ``target_reached``; ``level_cap`` or ``unknowns_cap`` (the target
    was not reached; ``levels`` say what was); ``admm_failed`` (a level's ADMM
    run did not converge).  ``model`` is the plug-in's discrete problem of the
    last level (its operators).
    """

    status: str
    message: str
    levels: list = field(default_factory=list)
    model: Any = None
    result: Any = None
    indicators: np.ndarray | None = None

    @property
    def reached(self) -> bool:
        """True when the estimated relative energy error is at most the target."""
        return self.status == "target_reached"

    def record(self, level, model, result, indicators) -> None:
        """Keep a finished level (with a ``relative_estimate``) and its model, ADMM result and indicators."""
        self.levels.append(level)
        self.model, self.result, self.indicators = model, result, indicators

    def ends(self, target: float) -> bool:
        """True (status and message set) when the loop ends at the last level: its ADMM run failed, or the target
        is reached."""
        relative = self.levels[-1].relative_estimate
        if not self.result.converged:
            self.status = "admm_failed"
            self.message = f"level {len(self.levels)}: ADMM ended {self.result.status.value}"
        elif relative <= target:
            self.status = "target_reached"
            self.message = f"estimated relative energy error {relative:.3e} <= target {target:g}"
        else:
            return False
        return True

    def capped(self, max_levels: int, target: float) -> "AdaptiveResult":
        """The loop ran out of levels: status ``level_cap`` with what was reached."""
        self.status = "level_cap"
        self.message = (f"max_levels = {max_levels} reached with an estimated relative energy error "
                        f"{self.levels[-1].relative_estimate:.3e}; target {target:g} not reached"
                        + needed_unknowns(self.levels, target))
        return self


def needed_unknowns(levels, target: float) -> str:
    """What the levels' own convergence says the target needs: "; at the observed rate N^-p (last levels) the
    target needs about K unknowns", or "" when there are too few levels to tell (or no decrease)."""
    if len(levels) < 3:
        return ""
    last = levels[-3:]
    n = np.log([lvl.unknowns for lvl in last])
    e = np.log([lvl.relative_estimate for lvl in last])
    slope = float(np.polyfit(n, e, 1)[0])
    if not slope < -1e-3:
        return ""
    need = math.exp(n[-1] + (math.log(target) - e[-1]) / slope)
    return f"; at the rate of the last levels (estimate ~ N^{slope:.2f}) it needs about {need:.1e} unknowns"


def dorfler_mark(indicators, theta: float) -> np.ndarray:
    """The smallest set of cells whose eta_T^2 sum to at least theta x the total (a boolean mask)."""
    eta2 = np.asarray(indicators, dtype=float) ** 2
    order = np.argsort(-eta2, kind="stable")
    count = int(np.searchsorted(np.cumsum(eta2[order]), theta * eta2.sum())) + 1
    mask = np.zeros(eta2.size, dtype=bool)
    mask[order[:min(count, eta2.size)]] = True
    return mask


def check_adaptive(target, theta, gamma, max_levels, max_unknowns) -> None:
    """Refuse parameters of an adaptive loop outside their ranges, naming the parameter and the range."""
    for name, value, ok, accepted in [("target", target, lambda v: 0 < v < 1, "(0, 1)"),
                                      ("theta", theta, lambda v: 0 < v < 1, "(0, 1)"),
                                      ("gamma", gamma, lambda v: 0 < v <= 1, "(0, 1]")]:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or not ok(value):
            raise ValueError(f"{name} = {value!r} is outside the accepted range {accepted}")
    for name, value in [("max_levels", max_levels), ("max_unknowns", max_unknowns)]:
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"{name} = {value!r} is outside the accepted range: an integer >= 1")


class HeldRho(Policy):
    """The penalty rule of a warm level: rho held for the first ``hold`` iterations, then the wrapped rule.

    A warm level starts from the previous level's solution and rho, which
    that level's rule has already tuned; a move of rho costs the x-step a new
    factorisation (or a new preconditioner), dear on a fine mesh.  Most warm
    levels stop at their first test of the balanced stop (``hold`` = the
    stop's interval), with one x-step matrix; one that does not gets the rule
    (started afresh) from iteration ``hold`` on.  ``inner``: a Policy or a
    registered name.

    ``keep``: None, or a callable read after ``hold``: while it returns True,
    rho stays held.  The adaptive loops pass the balanced stop's
    ``converging`` (its last test predicted the stop within its interval):
    on a P2 obstacle level (26,237 unknowns) a rule that took over at
    iteration 10, with the bound at 1.1x its threshold, moved rho 9x in two
    iterations, the bound rose 7x and the level took 181 iterations.  The
    prediction reads iteration counts and bounds only, so the schedule of rho
    stays deterministic.
    """

    def __init__(self, inner: Policy | str, hold: int = 10, keep: Callable[[], bool] | None = None):
        self.inner = inner if isinstance(inner, Policy) else make_policy(inner)
        if isinstance(hold, bool) or not isinstance(hold, int) or hold < 0:
            raise ValueError(f"hold = {hold!r} is outside the accepted range: an integer >= 0")
        if keep is not None and not callable(keep):
            raise ValueError(f"keep = {keep!r} is outside the accepted range: None or a callable")
        self.hold, self.keep = hold, keep
        self.requires = tuple(self.inner.requires)

    def reset(self, rho0: float) -> None:
        """Start a run: the wrapped rule too."""
        super().reset(rho0)
        self.inner.reset(rho0)

    def update(self, rec) -> float:
        """rho_k for k < hold and while ``keep()``, else the wrapped rule's rho_{k+1}."""
        if rec.k < self.hold or (self.keep is not None and self.keep()):
            return rec.rho
        return self.inner.update(rec)

    def unchanged_until(self, k: int) -> int:
        """Iteration ``hold`` at the earliest, then the wrapped rule's (holding longer never moves rho)."""
        return self.inner.unchanged_until(max(k, self.hold))
