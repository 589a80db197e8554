"""The contact plug-in's error estimates and its balanced stop (#24).

Independent checks: the discrete solution u_h from the plug-in's reference
solve (cvxpy + Clarabel, problems/contact/validation/reference.py) for the algebraic error, and the energy
of a much finer mesh for the discretisation error (for the contact problem
J(u_h) - J(u) >= ||u_h - u||_a^2 / 2, so sqrt(2 (J(u_h) - J_fine)) estimates it).
"""
import numpy as np
import pytest

import admmkit
from admmkit.cli import main
from admmkit.problems.contact import assemble, contact_problem, example1, example2, solve_scene
from admmkit.problems.contact.solvers.estimate import BalancedStop, CondensedGap, zz_estimate, zz_indicators
from admmkit.problems.contact.validation.reference import energy, energy_norm, reference_solution


@pytest.fixture(scope="module")
def ex1():
    ops = assemble(example1(h=1 / 10))
    return ops, contact_problem(ops, mode="condensed"), reference_solution(ops).u


@pytest.mark.parametrize("tol", [1e-2, 1e-3, 1e-5, 1e-8])
def test_the_bound_is_above_the_true_algebraic_error_and_sharp(ex1, tol):
    ops, problem, u_h = ex1
    seen = []

    def watch(rec):
        seen.append((rec.x.copy(), rec.z.copy(), rec.lam.copy()))
    res = admmkit.solve(problem, rho=ops.scene.E, policy="summable", order="zx", stop=admmkit.RelativeChange(tol),
                        callback=watch)
    x, z, lam = seen[-1]
    true = energy_norm(ops, res.x - u_h)
    bound = CondensedGap(problem).bound(x[1:], z, lam)
    assert true <= bound <= 20 * true + 1e-7


@pytest.mark.parametrize("make, order", [(example1, 1), (example2, 2)])
def test_the_bound_is_the_true_error_once_the_contact_set_is_found(make, order, contact_tight):
    """The active-set candidate (A) makes (B) exact when the iterate's contact set is the solution's."""
    ops = assemble(make(h=1 / 10, order=order))
    problem = contact_problem(ops, mode="condensed")
    u_h = contact_tight(ops).x
    stop = BalancedStop(problem, 0.1)
    res = admmkit.solve(problem, rho=1e3, policy="summable", order="zx", stop=stop, max_iter=5_000)
    true = energy_norm(ops, res.x - u_h)
    assert res.converged and true <= stop.algebraic * (1 + 1e-6) <= 1.01 * true + 1e-9
    gap = stop.gap
    touching = ops.B @ u_h >= problem.g - 1e-9 * max(1.0, np.abs(problem.g).max())
    exact = gap.active_set_multiplier(touching)
    assert exact.any() and gap.active_set_multiplier(touching.copy()) is exact      # kept while the set holds


@pytest.mark.parametrize("make, order", [(example1, 1), (example2, 2)])
def test_the_active_set_steps_correct_a_wrong_touched_set(make, order, contact_tight):
    """(A') drops the nodes whose multiplier (A) gives a negative force and adds those d0 - C mu puts through
    the obstacle: from the solution's contact set with the two nearest free nodes added, or with its weakest
    node taken away (an iterate's touched set near the end of a run), the steps end on the solution's set,
    with its multiplier."""
    ops = assemble(make(h=1 / 10, order=order))
    problem = contact_problem(ops, mode="condensed")
    u_h = contact_tight(ops).x
    gap = CondensedGap(problem)
    touching = ops.B @ u_h >= problem.g - 1e-9 * max(1.0, np.abs(problem.g).max())
    assert 0 < touching.sum() < touching.size
    exact = gap._restricted_multiplier(touching)
    assert np.all(exact[touching] > 0)
    free = np.flatnonzero(~touching)
    added = touching.copy()
    added[free[np.argsort((problem.g - ops.B @ u_h)[free])[:2]]] = True
    removed = touching.copy()
    removed[np.flatnonzero(touching)[np.argmin(exact[touching])]] = False
    for start in (added, removed):
        assert not np.array_equal(start, touching)
        assert np.allclose(CondensedGap(problem).active_set_multiplier(start), exact, rtol=1e-9, atol=0)


def test_energy_exceeds_the_minimum_by_half_the_squared_energy_norm_at_a_feasible_point(ex1):
    """J(v) - J(u_h) >= ||v - u_h||_a^2 / 2 for a feasible v (the studies' true error rests on it)."""
    ops, _, u_h = ex1
    v = 0.5 * u_h                                      # B u_h <= g and B 0 = 0 <= g: feasible, g >= 0 here
    assert np.all(ops.B @ v <= ops.g + 1e-12)
    assert energy(ops, u_h) == pytest.approx(0.5 * u_h @ (ops.K @ u_h) - ops.f @ u_h, rel=1e-14)
    assert energy(ops, v) - energy(ops, u_h) >= 0.5 * energy_norm(ops, v - u_h) ** 2 * (1 - 1e-8)


@pytest.mark.parametrize("make, order", [(example1, 1), (example1, 2), (example2, 1), (example2, 2)])
def test_zz_tracks_the_discretisation_error(make, order, contact_tight):
    fine = assemble(make(h=1 / 80, order=order))
    J_fine = energy(fine, contact_tight(fine).x)
    ops = assemble(make(h=1 / 10, order=order))
    u = contact_tight(ops).x
    error = np.sqrt(2 * max(energy(ops, u) - J_fine, 0.0))
    indicators = zz_indicators(ops, u)
    assert indicators.shape == (ops.mesh.ne,) and np.all(indicators >= 0)
    assert 0.5 <= zz_estimate(ops, u) / error <= 1.3


def test_the_balanced_stop_means_what_it_says(ex1):
    ops, problem, u_h = ex1
    stop = BalancedStop(problem, gamma=0.1)
    res = admmkit.solve(problem, rho=ops.scene.E, policy="summable", order="zx", stop=stop)
    assert res.converged and res.stopped_by == stop.name
    assert energy_norm(ops, res.x - u_h) <= stop.algebraic <= 0.1 * stop.discretisation


def test_refusals_name_what_is_wrong():
    ops = assemble(example1(h=1 / 10))
    with pytest.raises(ValueError, match="mode 'condensed'"):
        BalancedStop(contact_problem(ops, mode="full"))
    with pytest.raises(ValueError, match=r"gamma = 0 is outside the accepted range \(0, 1\]"):
        BalancedStop(contact_problem(ops, mode="condensed"), gamma=0)
    with pytest.raises(ValueError, match="give one"):
        solve_scene(ops, "sadmm", mode="condensed", stop=admmkit.RelativeChange(1e-5), balance=0.1)


def test_cli_balance(capsys):
    assert main(["solve", "contact", "--scene", "ex2", "--h", "1/10", "--balance", "0.1", "-q"]) == 0
    out = capsys.readouterr().out
    assert "balanced(gamma=0.1)" in out and "balance      algebraic error <=" in out
    assert main(["solve", "contact", "--h", "1/10", "--balance", "0.1", "--mode", "full"]) == 2
    assert "--balance needs --mode condensed" in capsys.readouterr().err
    assert main(["solve", "contact", "--scene", "ex1_tresca", "--h", "1/10", "--balance", "0.1", "-q"]) == 0
    assert "balance      algebraic error <=" in capsys.readouterr().out    # Tresca: the bound (B_t)
    assert main(["solve", "contact", "--scene", "ex1_tresca", "--h", "1/10", "--balance", "0.1",
                 "--estimator", "residual"]) == 2
    assert "frictionless residual estimator" in capsys.readouterr().err
