"""A penalty per row through the rule protocol: ``admmkit.RowPenalties`` from a rule with ``per_row = True`` is one
event (one refresh of the x-step, one row of the history), keeps the multiplier M lam, and a problem without per-row
weights refuses such a rule before the first iteration."""
import numpy as np
import pytest

import admmkit
from admmkit import RowPenalties
from admmkit.problems.qp import solve_qp
from admmkit.problems.qp.generate import random_qp

from tests.conftest import Obstacle1D


class Reweigh(admmkit.Policy):
    """At the iterations of ``plan`` ({k: (rho factor, row factors)}) the weights and rho it says; else rho_k."""

    per_row = True

    def __init__(self, plan):
        self.plan = plan

    def unchanged_until(self, k):
        return min((j for j in self.plan if j >= k), default=10 ** 9)

    def update(self, rec):
        if rec.k not in self.plan:
            return rec.rho
        rho_factor, factors = self.plan[rec.k]
        return RowPenalties(rec.rho * rho_factor, rec.row_weights * factors)


class RowsObstacle(Obstacle1D):
    """The diagonal obstacle with M = diag(m) open to a penalty per row; counts the refreshes."""

    def __init__(self, *args):
        super().__init__(*args)
        self.refreshes = []

    def inner_weights(self):
        return self.m

    def update_row_weights(self, rho, w):
        self.refreshes.append(rho)
        self.m = np.array(w, dtype=float)


def _obstacle(cls=RowsObstacle):
    rng = np.random.default_rng(3)
    return cls(rng.uniform(1, 3, 8), rng.uniform(-2, 4, 8), rng.uniform(0.2, 1, 8), rng.uniform(0.5, 2, 8))


def _qp(xstep="kkt", seed=4):
    return random_qp(12, 18, seed=seed, row_weights="osqp", xstep=xstep)


STOP = admmkit.ResidualTolerance(1e-300, 0)


@pytest.mark.parametrize("xstep", ["kkt", "reduced"])
def test_each_change_of_the_rows_is_one_factorisation_and_one_row_of_the_history(xstep):
    qp = _qp(xstep)
    m = qp.m
    factors = np.linspace(0.5, 3.0, m)
    plan = {9: (1.0, factors), 19: (2.0, 1 / factors), 29: (1.0, np.ones(m))}      # the last: the rows as they are
    qp.setup(0.1)
    before = qp.counters()["factorizations"]
    res = admmkit.solve(qp, rho=0.1, policy=Reweigh(plan), max_iter=40, stop=STOP)
    assert res.rho_changes == 2 and res.rho == pytest.approx(0.2)
    assert qp.counters()["factorizations"] - before == 2             # one per event, none at the next x-steps
    assert sorted(res.history.row_weights) == [9, 19]
    assert np.flatnonzero(res.history["rho_changed"]).tolist() == [9, 19]
    free = np.isinf(qp.ls) & np.isinf(qp.us)
    want = res.history.row_weights[19]
    assert np.array_equal(qp.w[~free], want[~free])


def test_the_multiplier_M_lam_is_kept_and_the_run_ends_at_the_solution():
    p = _obstacle()
    x_star, lam_star = p.solution()
    y_star = p.m * lam_star                                          # M lam, what the weights must not change
    factors = np.geomspace(0.1, 10.0, 8)
    res = admmkit.solve(p, rho=1.0, policy=Reweigh({5: (1.0, factors), 12: (3.0, factors[::-1])}),
                        max_iter=3000, stop=admmkit.ResidualTolerance(1e-12, 1e-12))
    assert len(p.refreshes) == 2 and res.status is admmkit.Status.CONVERGED
    assert np.allclose(res.x, x_star, atol=1e-9)
    assert np.allclose(p.m * res.lam, y_star, atol=1e-9)             # lam itself is in the new M


def test_the_event_rescales_lam_by_the_old_over_the_new_weights():
    from admmkit.loop.steps import RhoEvent
    p = _obstacle()
    w_old = p.m.copy()
    w_new = w_old * np.arange(1, 9)
    lam = np.linspace(-1, 1, 8)
    rho, lam_new = RhoEvent(p).change_rows(RowPenalties(2.0, w_new), lam)
    assert rho == 2.0 and np.allclose(w_new * lam_new, w_old * lam) and p.refreshes == [2.0]
    rho, same = RhoEvent(p).change_rows(RowPenalties(3.0, w_old), lam, follows=False)   # after the last iteration
    assert same is lam and p.refreshes == [2.0]


def test_a_problem_without_per_row_weights_refuses_a_per_row_rule_at_the_start():
    p = _obstacle(Obstacle1D)
    with pytest.raises(ValueError, match=r"Reweigh.*per row.*Obstacle1D does not take.*update_row_weights"):
        admmkit.solve(p, rho=1.0, policy=Reweigh({}), max_iter=5)


def test_row_penalties_from_a_rule_that_does_not_declare_them_is_its_error():
    class Undeclared(Reweigh):
        per_row = False
    with pytest.raises(TypeError, match="Undeclared.*RowPenalties.*per_row = True"):
        admmkit.solve(_obstacle(), rho=1.0, policy=Undeclared({2: (1.0, 2.0)}), max_iter=5)


class Returns(admmkit.Policy):
    """RowPenalties(rho_k, ``weights``) at iteration 2."""

    per_row = True

    def __init__(self, weights):
        self.weights = weights

    def update(self, rec):
        return RowPenalties(rec.rho, self.weights) if rec.k == 2 else rec.rho


@pytest.mark.parametrize("weights, error, match", [(np.ones(3), ValueError, "shape"),
                                                   (-np.ones(8), ValueError, r"\(0, inf\)"),
                                                   (np.full(8, np.nan), ValueError, r"\(0, inf\)"),
                                                   ("heavy", TypeError, "array of numbers")])
def test_bad_row_weights_are_the_rules_error(weights, error, match):
    with pytest.raises(error, match=f"Returns.*{match}"):
        admmkit.solve(_obstacle(), rho=1.0, policy=Returns(weights), max_iter=5)


def test_a_row_change_runs_the_same_compiled_and_in_python():
    from admmkit.kernels import AVAILABLE
    if not AVAILABLE:
        pytest.skip("numba is not installed")
    m = _qp().m
    plan = {49: (1.0, np.linspace(0.2, 5, m)), 99: (0.5, np.linspace(5, 0.2, m))}
    runs = [solve_qp(_qp(), policy=Reweigh(plan), eps_abs=1e-14, eps_rel=0.0, max_iter=160, compiled=c)
            for c in (True, False)]
    assert runs[0].rho_changes == runs[1].rho_changes == 2
    assert runs[0].counters.get("compiled_iterations", 0) > 0
    for name in ("x", "z", "lam"):
        assert np.array_equal(getattr(runs[0], name), getattr(runs[1], name)), name


def test_the_next_run_on_the_same_qp_starts_from_its_own_weights():
    from admmkit.policies import OSQPRule
    fresh = admmkit.solve(_qp(), rho=0.1, policy=OSQPRule(), max_iter=200, stop=STOP)
    qp = _qp()
    w_own = qp.w.copy()
    admmkit.solve(qp, rho=0.1, policy=Reweigh({9: (1.0, np.linspace(0.5, 3.0, qp.m))}), max_iter=20, stop=STOP)
    assert not np.array_equal(qp.w, w_own)
    again = admmkit.solve(qp, rho=0.1, policy=OSQPRule(), max_iter=200, stop=STOP)
    assert np.array_equal(qp.w, w_own)
    for name in ("x", "z", "lam"):
        assert np.array_equal(getattr(again, name), getattr(fresh, name)), name


def test_a_hand_made_record_carries_the_given_row_weights():
    rec = admmkit.IterationRecord(k=0, rho=1.0, order="xz", primal_residual=1, dual_residual=1, rho_Ax_change=1,
                                  lam_change=1, x_change=1, x_norm=1, z_change=1, primal_scale=1, dual_scale=1,
                                  primal_unit=1, dual_unit=1, time=0, x=np.zeros(2), z=np.zeros(3),
                                  lam=np.zeros(3), Ax=np.zeros(3), row_weights=np.array([1.0, 2.0, 3.0]))
    assert rec.row_weights.tolist() == [1.0, 2.0, 3.0]
