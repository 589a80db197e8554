"""A status never lies: no run ends as a plain ``converged`` far from the solution, whatever rho_0, rule or stop.

Every registered rule in both orders, from rho_0 = 1e-12 to 1e12, with the
paper's relative-change stop and with the default residual stop, on contact
Example 1 and the radial obstacle.  A run the stopping rule ended is
``converged`` only if its relative KKT measures are within 10x the rule's
tolerance (``admmkit.loop.solver.INACCURATE_FACTOR``); this checks that no such run
is more than 1e-3 away from an independent solve (Clarabel) of the same
discrete problem.
"""
import numpy as np
import pytest

import admmkit
from admmkit import RelativeChange, ResidualTolerance, Status
from admmkit.benchmarks.fixtures.methods import admm_methods, make

RHOS = [10.0 ** e for e in range(-12, 13, 3)]
STOPS = {"paper": lambda: RelativeChange(1e-5), "default": lambda: None}
FALSE = 1e-3


def audit(make_problem, error, stop):
    outcomes, false = {}, []
    for label in admm_methods():
        for rho in RHOS:
            policy, order = make(label)
            r = admmkit.solve(make_problem(), rho=rho, policy=policy, order=order, stop=STOPS[stop](), max_iter=3000)
            outcomes[r.status.value] = outcomes.get(r.status.value, 0) + 1
            if r.status is Status.CONVERGED and error(r) > FALSE:
                false.append((label, rho, r.iterations, error(r), r.accuracy))
    return outcomes, false


@pytest.fixture(scope="module")
def contact():
    from admmkit.problems.contact import assemble, example1
    from admmkit.problems.contact.validation.reference import errors_against, reference_solution
    ops = assemble(example1(h=1 / 20))
    ref = reference_solution(ops)
    return ops, lambda r: errors_against(ops, ref, r.x, r.lam)["err_u_energy"]


@pytest.mark.parametrize("stop", STOPS)
def test_contact_never_reports_converged_far_from_the_solution(contact, stop):
    from admmkit.problems.contact.solvers.problem import contact_problem
    ops, error = contact
    outcomes, false = audit(lambda: contact_problem(ops), error, stop)
    assert false == []
    assert outcomes.get("converged", 0) > 20          # the audit is not vacuous: many runs do converge
    if stop == "paper":                                # the paper's rule fires early from extreme rho_0
        assert outcomes.get("converged_inaccurate", 0) > 20


@pytest.mark.parametrize("stop", STOPS)
def test_obstacle_never_reports_converged_far_from_the_solution(stop):
    from admmkit.problems.obstacle import make_problem
    from admmkit.problems.obstacle.problem import solve_with_cvxpy
    from admmkit.problems.obstacle.scene import scene
    sc = scene("radial", h=1 / 8)
    u_ref, _ = solve_with_cvxpy(make_problem(sc), tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12)
    error = lambda r: float(np.linalg.norm(r.x - u_ref) / np.linalg.norm(u_ref))  # noqa: E731
    outcomes, false = audit(lambda: make_problem(sc), error, stop)
    assert false == []
    assert outcomes.get("converged", 0) > 20
