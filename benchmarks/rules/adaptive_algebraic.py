"""The algebraic error at the balanced stop, against the exact discrete solution of the same level.

Issue #24's target: on every adaptive level the algebraic error of the
returned solution is within [0.05, 0.5] of the discretisation error (the
balanced stop fires at gamma = 0.1 of the estimate, so a sharp bound puts it
near 0.1, a loose one lower).  The exact discrete solution u_h* of a level:

* contact: the condensed mode's SADMM run to Boyd's residuals 1e-10 (the
  boundary problem is small: O(n_c^2) an iteration);
* obstacle: the primal-dual active set method (``pdas``, method "bounds":
  exact sparse solves, finite termination), or, where it cycles (P2's K is
  not an M-matrix), ADMM to residuals 1e-10 from the level's result.

Both return ||u - u_h*||_a, the energy norm of the difference, which
:func:`admmkit.benchmarks.rules.adaptive_levels.level_row` divides by the
level's (absolute) estimate eta.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp

import admmkit

TIGHT = admmkit.ResidualTolerance(1e-10, 1e-10)


def contact_algebraic_error(ops, u: np.ndarray) -> float:
    """||u - u_h*||_K on a contact level (``ops``: its ContactOperators; ``u``: the level's displacement)."""
    from admmkit.problems.contact.solvers.methods import solve_scene
    from admmkit.problems.contact.validation.reference import energy_norm
    tight = solve_scene(ops, "sadmm", 1e3, mode="condensed", stop=TIGHT, max_iter=50_000)
    if not tight.result.converged:
        return math.nan
    return energy_norm(ops, u - tight.result.x)


def obstacle_algebraic_error(problem, result) -> float:
    """||z - u_h*||_K on an obstacle level (``problem``: the level's ObstacleProblem; ``result``: its run)."""
    from admmkit.benchmarks.rules.pdas import pdas
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
