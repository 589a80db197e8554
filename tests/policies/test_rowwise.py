"""The rule ``rowwise``: OSQP's rho and a penalty per row moved by the row's own residuals (RLQP's shape)."""
import numpy as np
import pytest

import admmkit
from admmkit.policies import OSQPRule
from admmkit.policies.rowwise import RowwiseRule
from admmkit.problems.qp import solve_qp
from admmkit.problems.qp.generate import random_qp

from tests.conftest import Obstacle1D


def _record(r, dz, rho=1.0, w=None, k=49):
    """A hand-made record with A x - z = r and z - z_prev = dz."""
    r, dz = np.asarray(r, float), np.asarray(dz, float)
    z = np.ones_like(r)
    return admmkit.IterationRecord(k=k, rho=rho, order="xz", primal_residual=1.0, dual_residual=1.0,
                                   rho_Ax_change=1.0, lam_change=1.0, x_change=1.0, x_norm=1.0, z_change=1.0,
                                   primal_scale=1.0, dual_scale=1.0, primal_unit=1.0, dual_unit=1.0, time=0.0,
                                   x=np.zeros(2), z=z, lam=np.zeros_like(z), Ax=z + r, z_prev=z - dz,
                                   row_weights=np.ones_like(r) if w is None else np.asarray(w, float))


def test_a_row_with_more_primal_than_dual_residual_gets_a_heavier_penalty():
    rule = RowwiseRule()
    rule.reset(1.0)
    d = rule.row_factors(_record([1.0, 1e-2, 1e-4], [1e-4, 1e-2, 1.0]))
    assert d[0] > d[1] > d[2]
    assert np.exp(np.mean(np.log(d))) == pytest.approx(1.0)            # the level stays the global rho's
    assert d.max() <= 100 and d.min() >= 1 / 100


def test_the_factors_stay_within_the_spread():
    rule = RowwiseRule(spread=3.0)
    rule.reset(1.0)
    d = rule.row_factors(_record([1.0, 1e-8, 1e-8, 1e-8], [1e-8, 1.0, 1.0, 1.0]))
    assert d.max() == pytest.approx(3.0) and d.min() >= 1 / 3


def test_no_residual_of_one_kind_leaves_the_rows_alone():
    rule = RowwiseRule()
    rule.reset(1.0)
    assert rule.row_factors(_record([0.0, 0.0], [1.0, 2.0])) is None


def test_it_answers_row_penalties_only_at_its_interval():
    rule = RowwiseRule()
    rule.reset(1.0)
    assert rule.update(_record([1.0, 1e-4], [1e-4, 1.0], k=10)) == 1.0
    answer = rule.update(_record([1.0, 1e-4], [1e-4, 1.0], w=[1.0, 1e3], k=49))
    assert isinstance(answer, admmkit.RowPenalties) and answer.weights[0] > 1.0 and answer.weights[1] < 1e3


def test_with_spread_1_it_is_osqps_rule_bit_for_bit():
    qp = random_qp(20, 30, seed=7)
    a = solve_qp(qp, policy=OSQPRule(), eps_abs=1e-8, eps_rel=0.0, max_iter=3000)
    b = solve_qp(qp, policy=RowwiseRule(spread=1.0), eps_abs=1e-8, eps_rel=0.0, max_iter=3000)
    assert a.iterations == b.iterations and a.rho_changes == b.rho_changes and not b.history.row_weights
    for name in ("x", "z", "lam"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_on_a_qp_it_moves_the_rows_and_ends_at_the_solution():
    qp = random_qp(20, 30, seed=7)
    ref = solve_qp(qp, eps_abs=1e-9, eps_rel=0.0, max_iter=20000)
    runs = [solve_qp(qp, policy=RowwiseRule(), eps_abs=1e-9, eps_rel=0.0, max_iter=20000) for _ in range(2)]
    res = runs[0]
    assert res.solved and res.history.row_weights
    assert res.counters["factorizations"] == 1 + res.rho_changes      # the setup's, then one per event
    assert np.allclose(res.x, ref.x, atol=1e-6) and np.allclose(res.y, ref.y, atol=1e-5)
    assert np.array_equal(runs[0].x, runs[1].x) and runs[0].iterations == runs[1].iterations   # deterministic


def test_a_problem_with_one_rho_refuses_it():
    p = Obstacle1D(np.ones(3), np.ones(3), np.ones(3), np.ones(3))
    with pytest.raises(ValueError, match="RowwiseRule.*per row.*Obstacle1D does not take"):
        admmkit.solve(p, policy=RowwiseRule(), max_iter=5)


@pytest.mark.parametrize("params, name", [({"spread": 0.5}, "spread"), ({"floor": 0.0}, "floor"),
                                          ({"floor": 1.0}, "floor"), ({"interval": 0}, "interval")])
def test_bad_parameters_name_themselves(params, name):
    with pytest.raises(ValueError, match=name):
        RowwiseRule(**params)


def test_solve_qp_runs_it_by_name_on_osqps_normalisation():
    from admmkit.problems.qp.solve import qp_for
    from admmkit.problems.qp.settings import osqp_settings
    from admmkit.problems.qp.termination import osqp_relative_residuals
    qp = random_qp(20, 30, seed=7)
    settings = osqp_settings(eps_abs=1e-8, eps_rel=0.0, max_iter=3000)
    run_qp = qp_for(qp, settings)

    def rule(**changes):
        return RowwiseRule(rho_min=1e-6, rho_max=1e6, residuals=osqp_relative_residuals(run_qp), **changes)
    named = solve_qp(qp, settings, policy="rowwise")
    given = solve_qp(run_qp, settings, policy=rule())
    assert named.history.row_weights and named.iterations == given.iterations
    assert np.array_equal(named.x, given.x) and np.array_equal(named.y, given.y)
    osqp = solve_qp(qp, settings)                                       # OSQP's rule as solve_qp runs it
    still = solve_qp(run_qp, settings, policy=rule(spread=1.0))
    assert osqp.iterations == still.iterations and np.array_equal(osqp.x, still.x) and np.array_equal(osqp.y, still.y)
