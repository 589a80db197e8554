"""The obstacle plug-in's residual estimator (#24) against the radial scene's exact solution, and --estimator.

The discrete solutions come from cvxpy + Clarabel (independent of ADMM); the
true error is NGSolve's integral of grad(u_h - u) against the exact solution.
"""
import math

import numpy as np
import pytest

from admmkit import solve
from admmkit.cli import main
from admmkit.problems.obstacle import make_problem, radial, solve_with_cvxpy
from admmkit.problems.obstacle.adaptive import solve_adaptive
from admmkit.problems.obstacle.estimate import BalancedStop, estimator_of, zz_estimate
from admmkit.problems.obstacle.estimate_residual import (check_estimator, residual_estimate, residual_estimator,
                                                         residual_indicators)

TIGHT = dict(tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12)


@pytest.fixture(scope="module")
def ladder():
    """(h, true H1-seminorm error, residual estimate, ZZ estimate) for h = 1/8, 1/16, 1/32."""
    rows = []
    for N in (32, 64, 128):
        problem = make_problem(radial(h=4 / N))
        u_h, _ = solve_with_cvxpy(problem, **TIGHT)
        rows.append((4 / N, problem.errors(u_h)["H1_semi"], residual_estimate(problem, u_h), zz_estimate(problem, u_h)))
    return rows


def test_the_effectivity_is_bounded_and_the_estimate_is_above_the_error(ladder):
    effectivity = [eta / err for _, err, eta, _ in ladder]
    assert all(1.0 <= e <= 6.0 for e in effectivity), effectivity        # reliable, and not far above
    assert max(effectivity) / min(effectivity) <= 1.5, effectivity         # the same constant on every mesh


def test_the_estimate_converges_at_the_rate_of_the_error(ladder):
    for (h0, e0, eta0, _), (h1, e1, eta1, _) in zip(ladder, ladder[1:]):
        rate_error = math.log(e0 / e1) / math.log(h0 / h1)
        rate_estimate = math.log(eta0 / eta1) / math.log(h0 / h1)
        assert rate_error == pytest.approx(1.0, abs=0.1)                     # P1: O(h) in H1
        assert abs(rate_estimate - rate_error) <= 0.2, (rate_estimate, rate_error)


def test_indicators_are_one_non_negative_value_per_triangle():
    problem = make_problem(radial(h=1 / 4))
    u_h, _ = solve_with_cvxpy(problem, **TIGHT)
    terms = residual_estimator(problem).terms(u_h)
    assert set(terms) == {"residual", "jump", "complementarity", "obstacle"}
    for values in terms.values():
        assert values.shape == (problem.mesh.ne,) and np.all(values >= 0)
    eta_T = residual_indicators(problem, u_h)
    assert eta_T.shape == (problem.mesh.ne,) and np.all(eta_T >= 0)
    assert np.allclose(eta_T ** 2, sum(terms.values()))
    assert terms["residual"].sum() > 0 and terms["complementarity"].sum() > 0     # the contact force is seen
    assert np.array_equal(estimator_of(problem, "residual")(u_h), eta_T)


def test_the_balanced_stop_with_the_residual_estimate_means_what_it_says():
    problem = make_problem(radial(h=1 / 8))
    u_h, _ = solve_with_cvxpy(problem, **TIGHT)
    stop = BalancedStop(problem, gamma=0.1, estimator="residual")
    res = solve(problem, rho=1.0, policy="summable", order="zx", stop=stop, max_iter=5000)
    assert res.converged and "residual discretisation estimate" in res.stopped_by
    assert float(np.sqrt((res.z - u_h) @ (problem.K @ (res.z - u_h)))) <= stop.algebraic <= 0.1 * stop.discretisation


def test_adaptive_marking_by_the_residual_estimator_reaches_the_target():
    out = solve_adaptive(radial(h=1 / 4), 0.15, estimator="residual")
    assert out.reached and out.levels[-1].relative_estimate <= 0.15
    assert all(lvl.estimate >= lvl.errors["H1_semi"] for lvl in out.levels)      # it stays above the true error


def test_bad_estimator_names_are_refused():
    with pytest.raises(ValueError, match=r"estimator = 'foo' is unknown; accepted: zz, residual"):
        check_estimator("foo")
    with pytest.raises(ValueError, match="estimator = 'ZZ' is unknown"):
        solve_adaptive(radial(h=1 / 4), 0.1, estimator="ZZ")
    with pytest.raises(ValueError, match="estimator = 'foo' is unknown"):
        BalancedStop(make_problem(radial(h=1 / 4)), estimator="foo")


def test_cli_estimator(capsys):
    assert main(["solve", "obstacle", "--h", "1/4", "--estimator", "residual", "-q"]) == 0
    assert "(residual estimate)" in capsys.readouterr().out
    assert main(["solve", "obstacle", "--h", "1/4", "--target-error", "0.2", "--estimator", "residual"]) == 0
    assert "residual estimator" in capsys.readouterr().out
    assert main(["solve", "obstacle", "--h", "1/4", "--estimator", "zz2"]) == 2
    err = capsys.readouterr().err
    assert err.strip() == "admmkit: error: --estimator = 'zz2' is unknown; accepted: zz, residual"


def test_the_estimators_study_writes_its_table_and_figure(tmp_path):
    from admmkit.benchmarks.adaptive.estimators import run
    paths = run(tmp_path, "admmkit bench estimators --quick", quick=True)
    assert [p.name for p in paths] == ["estimators.csv", "estimators.md", "estimators.png"]
    text = (tmp_path / "estimators.md").read_text()
    assert "radial obstacle" in text and "contact Example 1" in text and "residual effectivity" in text
    assert (tmp_path / "estimators.png").stat().st_size > 10_000
