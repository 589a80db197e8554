"""Policy update logic on hand-made records."""
import math

import numpy as np
import pytest

from admmkit import IterationRecord
from admmkit.policies import Fixed, ResidualBalancing, Summable

EMPTY = np.zeros(1)


def record(k=0, rho=1.0, primal=1.0, dual=1.0, lam_change=None, rho_Ax_change=None):
    return IterationRecord(
        k=k, rho=rho, order="zx", primal_residual=primal, dual_residual=dual,
        rho_Ax_change=dual if rho_Ax_change is None else rho_Ax_change,
        lam_change=rho * primal if lam_change is None else lam_change,
        x_change=1.0, x_norm=1.0, z_change=1.0, primal_scale=1.0, dual_scale=1.0,
        primal_unit=1.0, dual_unit=1.0, time=0.0, x=EMPTY, z=EMPTY, lam=EMPTY, Ax=EMPTY,
    )


def test_fixed():
    p = Fixed()
    p.reset(3.0)
    assert p.update(record(rho=3.0, primal=100, dual=1e-9)) == 3.0


def test_residual_balancing():
    p = ResidualBalancing()
    p.reset(1.0)
    assert p.update(record(rho=1.0, primal=11, dual=1)) == 2.0
    assert p.update(record(rho=1.0, primal=1, dual=11)) == 0.5
    assert p.update(record(rho=1.0, primal=10, dual=1)) == 1.0   # boundary: not strictly greater
    assert p.update(record(rho=1.0, primal=0, dual=0)) == 1.0


def test_summable_follows_the_paper():
    p = Summable(tau=2.0, c_max=3)
    p.reset(1.0)
    rho = 1.0
    seq = []
    # w_k = lam_change / rho_Ax_change: always 10 (> 1 + tau) -> rho increases by (1 + s_k)
    for k in range(7):
        rho_next = p.update(record(k=k, rho=rho, lam_change=10.0, rho_Ax_change=1.0))
        seq.append(rho_next / rho)
        rho = rho_next
    # s_k = tau for the first c_max changes, then 1/(c - c_max)^2
    assert seq == pytest.approx([3, 3, 3, 2, 1.25, 1 + 1 / 9, 1 + 1 / 16])
    assert p.changes == 7


def test_summable_band_and_decrease():
    p = Summable()
    p.reset(5.0)
    assert p.update(record(rho=5.0, lam_change=1.0, rho_Ax_change=1.0)) == 5.0      # w = 1
    assert p.update(record(rho=5.0, lam_change=3.0, rho_Ax_change=1.0)) == 5.0      # w = 1 + tau: in band
    assert p.update(record(rho=5.0, lam_change=1.0, rho_Ax_change=3.0)) == 5.0      # w = 1/(1+tau): in band
    assert p.changes == 0
    assert p.update(record(rho=5.0, lam_change=1.0, rho_Ax_change=4.0)) == pytest.approx(5 / 3)
    assert p.changes == 1


def test_summable_edge_cases():
    p = Summable()
    p.reset(1.0)
    assert p.update(record(rho=1.0, lam_change=0.0, rho_Ax_change=0.0)) == 1.0      # w undefined: keep
    assert p.update(record(rho=1.0, lam_change=1.0, rho_Ax_change=0.0)) == 3.0      # w = inf: increase
    p.reset(1.0)
    assert p.changes == 0 and p.s_sum == 0


def test_summable_rho_stays_within_the_bound():
    p = Summable(tau=2.0, c_max=5)
    p.reset(1.0)
    rho, lo, hi = 1.0, 1.0, 1.0
    rng = np.random.default_rng(0)
    for k in range(5000):
        up = rng.random() < 0.5
        rho = p.update(record(k=k, rho=rho, lam_change=10.0 if up else 0.1, rho_Ax_change=1.0))
        lo, hi = min(lo, rho), max(hi, rho)
    assert 1 / p.bound <= lo and hi <= p.bound
    # the s_k used are summable: tau c_max + sum 1/j^2 < tau c_max + pi^2/6
    assert p.s_sum < 2.0 * 5 + math.pi ** 2 / 6
    assert p.bound == pytest.approx(3.0 ** 5 * math.sinh(math.pi) / math.pi)


def test_a_user_policy_in_a_few_lines(vector_problem):
    from admmkit import Policy, solve

    class Halve(Policy):
        def update(self, rec):
            return rec.rho / 2 if rec.k % 10 == 9 else rec.rho

    res = solve(vector_problem, rho=64.0, policy=Halve(), order="zx", max_iter=35)
    assert list(res.history["rho"][[0, 10, 20, 30]]) == [64, 32, 16, 8] or res.converged
