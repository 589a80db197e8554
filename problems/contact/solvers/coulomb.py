"""Coulomb friction by the fixed point on the slip bound: each outer step a Tresca problem.

Coulomb's law |sigma_t| <= mu |sigma_n| is Tresca's with the slip bound
s = mu p_n, where p_n = lam_n is the (unknown) contact pressure.  The usual
fixed point (Panagiotopoulos 1975; Haslinger, Hlavacek and Necas 1996,
section 4) solves

    s^0 = 0 (frictionless),  s^{j+1} = mu max(p_n(s^j), 0),

each step a Tresca problem solved by ADMM, warm-started from the previous
step's (u, z, lam) and final rho.  It converges for small enough mu (the
Tresca-to-pressure map is then a contraction); the outer iteration stops when
the M_c-weighted relative change of s is at most ``tol``, and its record
(inner iterations and change of every outer step) is returned so that the
convergence can be reported.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from admmkit import Status


@dataclass
class CoulombReport:
    """The outer iteration of a Coulomb solve.

    ``inner_iterations[j]`` ADMM iterations of outer step j, ``changes[j]``
    = ||s^{j+1} - s^j||_M / ||s^{j+1}||_M after it, ``converged`` whether the
    last change is at most ``tol``; ``last`` the admmkit Result of the last
    Tresca solve (the detail behind the whole solve's totals).
    """

    tol: float
    inner_iterations: list[int] = field(default_factory=list)
    changes: list[float] = field(default_factory=list)
    converged: bool = False
    last: Any = None
    settled: bool = False       # ended by the caller's ``settled`` rule (not by the change of s)

    @property
    def outer_iterations(self) -> int:
        """Number of Tresca solves."""
        return len(self.inner_iterations)

    @property
    def total_iterations(self) -> int:
        """ADMM iterations over all outer steps."""
        return int(sum(self.inner_iterations))

    def summary(self) -> str:
        """One line: outer steps, ADMM iterations, the last change of s."""
        change = self.changes[-1] if self.changes else float("nan")
        state = ("converged" + (" (settled: the displacement's step balanced)" if self.settled else "")
                 if self.converged else "NOT converged")
        line = (f"Coulomb fixed point {state}: {self.outer_iterations} Tresca solves, "
                f"{self.total_iterations} ADMM iterations, last change of s {change:.2e} (tol {self.tol:g})")
        if self.last is not None:
            r = self.last
            line += (f"; last Tresca solve: {r.status.value}, {r.iterations} iterations, "
                     f"{r.factorizations or 0} factorizations, {r.timings['total']:.4f} s")
        return line


def whole_solve(results: list, report: CoulombReport):
    """One admmkit Result for the whole fixed point: the last Tresca solve's iterate, with the totals of
    iterations, rho changes, work and time over every Tresca solve, and a status that is ``converged``
    only if the last solve and the fixed point both converged."""
    last = results[-1]
    timings = {k: sum(r.timings.get(k, 0.0) for r in results) for k in last.timings}
    counters = {k: sum(r.counters.get(k, 0) for r in results) for k in last.counters}
    status, message = last.status, f"last Tresca solve: {last.message}"
    if last.status is Status.CONVERGED and not report.converged:
        status = Status.MAX_ITER
        message = (f"the Coulomb fixed point stopped after {report.outer_iterations} Tresca solves with the change of "
                   f"s at {report.changes[-1]:.2e} > tol {report.tol:g}; {message}")
    else:
        message = f"Coulomb fixed point {'converged' if report.converged else 'NOT converged'} in " \
                  f"{report.outer_iterations} Tresca solves; {message}"
    return dataclasses.replace(last, iterations=report.total_iterations, timings=timings, counters=counters,
                               rho_changes=sum(r.rho_changes for r in results), status=status, message=message)


def _ended_by_a_rule(result) -> bool:
    """The Tresca solve ended because its stopping rule fired (converged, or converged but less accurate
    than the rule's tolerance in the KKT measures); not at max_iter, diverged or stalled."""
    return str(result.status) in ("converged", "converged_inaccurate")


def warm_z0(problem, warm):
    """z^0 of the next Tresca solve, warm-started from ``warm`` (the last one's Result): a z-step with the new slip
    bound.  In order "xz" the first x-step would otherwise not see the new s, change u little, and let a
    relative-change stop fire at once (measured: the fixed point then "converged" after 2 steps with an error of
    0.2)."""
    return problem.z_step(problem.apply_A(warm.x_iterate), warm.lam, warm.rho, warm.z)


def coulomb_fixed_point(problem, run: Callable, mu: float, tol: float = 1e-4, max_outer: int = 30,
                        s0: np.ndarray | None = None, settled: Callable | None = None):
    """Iterate s^{j+1} = mu max(p_n^j, 0) on ``problem`` (a contact plug-in with Coulomb friction).

    ``run(warm)`` solves the current Tresca problem (``warm`` = the previous
    admmkit Result or None) and returns its Result; ``problem.friction.s`` is
    the slip bound it reads.  ``s0``: the first slip bound (default 0, the
    frictionless problem; an adaptive level starts from mu p_n of the level
    before).  ``settled(previous, last)`` (two Results of consecutive Tresca
    solves): a second way to end, when it says True (the adaptive loop's
    balanced outer stop).  Returns (the whole solve's Result, CoulombReport):
    see :func:`whole_solve`; the last Tresca solve's own Result is ``report.last``.
    """
    if not (isinstance(tol, (int, float)) and 0 < tol < 1):
        raise ValueError(f"coulomb tol = {tol!r}; accepted: 0 < tol < 1")
    if not (isinstance(max_outer, int) and max_outer >= 1):
        raise ValueError(f"coulomb max_outer = {max_outer!r}; accepted: an integer >= 1")
    n_c, mc = problem.ops.n_c, problem.ops.mc
    report = CoulombReport(tol=tol)
    problem.friction.s = np.zeros(n_c) if s0 is None else np.maximum(np.asarray(s0, dtype=float), 0.0)
    result, results = None, []
    for _ in range(max_outer):
        result = run(result)
        results.append(result)
        report.inner_iterations.append(int(result.iterations))
        s_new = mu * np.maximum(result.lam[:n_c], 0.0)
        ds = s_new - problem.friction.s
        norm = np.sqrt(mc @ (s_new * s_new))
        change = float(np.sqrt(mc @ (ds * ds)) / norm) if norm > 0 else float(np.sqrt(mc @ (ds * ds)) > 0)
        report.changes.append(change)
        problem.friction.s = s_new
        report.settled = bool(settled is not None and len(results) > 1 and settled(results[-2], result))
        if change <= tol or report.settled or not _ended_by_a_rule(result):
            break
    report.converged = bool((report.changes[-1] <= tol or report.settled) and _ended_by_a_rule(result))
    report.last = result
    return whole_solve(results, report), report
