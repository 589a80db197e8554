"""The obstacle plug-in's error estimates and the stop balanced with the discretisation error (#24).

Independent checks: the discrete solution u_h from cvxpy + Clarabel (for the
algebraic error) and the radial obstacle's exact solution (for the
discretisation error).
"""
import numpy as np
import pytest

from admmkit import RelativeChange, solve
from admmkit.cli import main
from admmkit.problems.obstacle import make_problem, radial, solve_with_cvxpy
from admmkit.problems.obstacle.estimate import OBSTACLE_GAMMA, BalancedStop, EnergyGap, zz_estimate, zz_indicators

TIGHT = dict(tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12)


@pytest.fixture(scope="module")
def radial8():
    problem = make_problem(radial(h=1 / 8))
    u_h, _ = solve_with_cvxpy(problem, **TIGHT)
    return problem, u_h


def energy(problem, v):
    return float(np.sqrt(v @ (problem.K @ v)))


@pytest.mark.parametrize("tol", [1e-2, 1e-3, 1e-5, 1e-8])
def test_the_gap_bounds_the_algebraic_error_of_every_iterate(radial8, tol):
    problem, u_h = radial8
    gap = EnergyGap(problem)
    res = solve(problem, rho=1.0, policy="summable", order="zx", stop=RelativeChange(tol), max_iter=5000)
    true = energy(problem, res.z - u_h)
    bound = gap.bound(res.z, res.lam)
    assert true <= bound
    assert bound <= 10 * true + 1e-6                           # and it is sharp: it closes as ADMM converges


def test_the_gap_refuses_an_infeasible_point(radial8):
    problem, u_h = radial8
    below = u_h.copy()
    below[np.argmax(problem.psi)] = problem.psi.max() - 1.0
    assert EnergyGap(problem).bound(below, np.zeros(problem.n)) == np.inf


@pytest.mark.parametrize("h", [1 / 8, 1 / 16])
def test_zz_estimate_tracks_the_true_h1_error_on_the_radial_obstacle(h):
    problem = make_problem(radial(h=h))
    u_h, _ = solve_with_cvxpy(problem, **TIGHT)
    indicators = zz_indicators(problem, u_h)
    assert indicators.shape == (problem.mesh.ne,) and np.all(indicators >= 0)
    effectivity = zz_estimate(problem, u_h) / problem.errors(u_h)["H1_semi"]
    assert 0.8 <= effectivity <= 1.3, effectivity


def test_the_balanced_stop_means_what_it_says(radial8):
    problem, u_h = radial8
    stop = BalancedStop(problem, gamma=0.1)
    res = solve(problem, rho=1.0, policy="summable", order="zx", stop=stop, max_iter=5000)
    assert res.converged and res.stopped_by == stop.name
    assert energy(problem, res.z - u_h) <= stop.algebraic <= 0.1 * stop.discretisation
    assert stop.discretisation == pytest.approx(problem.errors(u_h)["H1_semi"], rel=0.3)


def test_the_obstacle_stops_at_the_top_of_the_band_by_default(radial8, capsys):
    """OBSTACLE_GAMMA = 0.5, tested from iteration 1: the guaranteed bound still holds the true algebraic error below
    half the estimate, and the command line's adaptive path takes the same default."""
    problem, u_h = radial8
    stop = BalancedStop(problem)
    assert stop.gamma == OBSTACLE_GAMMA == 0.5 and stop.first_tests == (1, 2)
    res = solve(problem, rho=1.0, policy="summable", order="zx", stop=stop, max_iter=5000)
    assert res.converged and res.stopped_by == stop.name
    assert energy(problem, res.z - u_h) <= stop.algebraic <= 0.5 * stop.discretisation
    assert main(["solve", "obstacle", "--scene", "radial", "--target-error", "0.1", "--fe-order", "1", "-q"]) == 0
    assert "theta 0.5, gamma 0.5," in capsys.readouterr().out


@pytest.mark.parametrize("kwargs, match", [({"gamma": 0.0}, "gamma = 0.0 is outside the accepted range"),
                                           ({"gamma": 1.5}, "gamma = 1.5 is outside"),
                                           ({"every": 0}, "every = 0 is outside")])
def test_bad_balance_parameters_are_named(radial8, kwargs, match):
    with pytest.raises(ValueError, match=match):
        BalancedStop(radial8[0], **kwargs)


def test_the_documented_default_run_converges_for_a_reason_that_holds(capsys):
    """`admmkit solve obstacle --scene radial` used to end converged_inaccurate (exit 1)."""
    assert main(["solve", "obstacle", "--scene", "radial", "-q"]) == 0
    out = capsys.readouterr().out
    assert "status       converged  (balanced(gamma=0.5)" in out and "balance      algebraic error <=" in out


@pytest.mark.parametrize("argv, message", [(["--balance", "2"], "--balance = 2 is outside the accepted range (0, 1]"),
                                           (["--balance", "0.5", "--tol", "1e-3"], "cannot be combined with --tol")])
def test_cli_bad_balance(capsys, argv, message):
    assert main(["solve", "obstacle", "--scene", "radial", "--h", "1/4", *argv]) == 2
    assert message in capsys.readouterr().err
