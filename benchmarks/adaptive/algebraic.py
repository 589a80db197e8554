"""The algebraic error at the balanced stop, against the exact discrete solution of the same level.

Issue #24's target: on every adaptive level the algebraic error of the
returned solution is within [0.05, 0.5] of the discretisation error (the
balanced stop fires at gamma = 0.3 of the estimate, so a sharp bound puts it
near 0.3 or, where one iteration cuts the error several times, lower; a loose
bound lower still).  The exact discrete solution u_h* of a level:

* contact: the condensed mode's SADMM continued from the level's result to a
  relative change of 1e-13 (the boundary problem is small: O(n_c^2) an
  iteration); the study also measures the level's true (discretisation)
  error on it, since the energy of an x-iterate that penetrates a little
  misreads its error (J(u) - J(u_h) is then not >= ||u - u_h||_a^2 / 2);
* obstacle: the primal-dual active set method (``pdas``, method "bounds":
  exact sparse solves, finite termination), or, where it cycles (P2's K is
  not an M-matrix), ADMM to residuals 1e-10 from the level's result.

Both return ||u - u_h*||_a, the energy norm of the difference, which
:func:`admmkit.benchmarks.adaptive.levels.level_row` divides by the
level's (absolute) estimate eta.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp

import admmkit

TIGHT = admmkit.ResidualTolerance(1e-10, 1e-10)     # the obstacle's ADMM fallback


def contact_exact(ops, result):
    """The level's exact discrete solution u_h*: the condensed mode's SADMM from the level's ``result`` (its
    iterate, multiplier and rho) to a relative change of 1e-13 (where Boyd's residuals stall at round-off on
    Hertz's curved obstacle); a Result (``x`` the displacement), or None if it did not get there."""
    from admmkit.problems.contact.solvers.methods import method
    from admmkit.problems.contact.solvers.problem import contact_problem
    order, policy = method("sadmm")
    tight = admmkit.solve(contact_problem(ops, mode="condensed"), policy=policy, order=order,
                          stop=admmkit.RelativeChange(1e-13), max_iter=50_000, warm_start=result)
    return tight if tight.status.value in ("converged", "converged_inaccurate") else None


def contact_algebraic_error(ops, u: np.ndarray, exact) -> float:
    """||u - u_h*||_K on a contact level (``ops``: its ContactOperators; ``u``: the level's displacement; ``exact``:
    :func:`contact_exact`'s result, or None: NaN)."""
    from admmkit.problems.contact.validation.reference import energy_norm
    return math.nan if exact is None else energy_norm(ops, u - exact.x)


def obstacle_algebraic_error(problem, result) -> float:
    """||z - u_h*||_K on an obstacle level (``problem``: the level's ObstacleProblem; ``result``: its run)."""
    from admmkit.benchmarks.fixtures.pdas import pdas
    s = problem.sign                                  # s (u - psi) >= 0  <=>  -s u <= -s psi
    exact = pdas(problem.K, problem.F, -s * sp.identity(problem.n, format="csr"), -s * problem.psi,
                 method="bounds", max_iter=200)
    if exact.status == "converged":
        u = exact.u
    else:
        tight = admmkit.solve(problem, policy="summable", order="zx", stop=TIGHT, max_iter=50_000,
                              warm_start=result)
        if not tight.converged:
            return math.nan
        u = tight.z
    d = result.z - u
    return math.sqrt(max(float(d @ (problem.K @ d)), 0.0))
