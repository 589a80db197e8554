"""A change of rho is one event: ``problem.update_rho`` at the line where rho changes, the accelerator's restart."""
import numpy as np
import pytest
import scipy.sparse as sp

import admmkit
from admmkit.loop.acceleration import Anderson
from admmkit.linalg.linsolve import CachedFactorization

from tests.conftest import Obstacle1D


class Halve(admmkit.Policy):
    """rho / 2 every third iteration."""

    def update(self, rec):
        return rec.rho / 2 if rec.k % 3 == 2 else rec.rho


class Recording(Obstacle1D):
    """Records the events and the rho each x-step sees."""

    def __init__(self, *args):
        super().__init__(*args)
        self.events, self.x_rhos = [], []

    def update_rho(self, rho):
        self.events.append((len(self.x_rhos), rho))

    def x_step(self, z, lam, rho, x):
        self.x_rhos.append(rho)
        return super().x_step(z, lam, rho, x)


def _problem():
    rng = np.random.default_rng(3)
    return Recording(rng.uniform(1, 3, 8), rng.uniform(-2, 4, 8), rng.uniform(0.2, 1, 8), rng.uniform(0.5, 2, 8))


def test_the_loop_raises_one_event_per_change_and_the_next_x_step_sees_its_rho():
    p = _problem()
    res = admmkit.solve(p, rho=64.0, policy=Halve(), max_iter=18, stop=admmkit.ResidualTolerance(1e-300, 0))
    assert res.rho_changes == 6 and res.rho == 1.0
    assert len(p.events) == 5                  # the change at the last iteration (k = 17): no refresh for it
    for at, rho in p.events:
        assert p.x_rhos[at] == rho and p.x_rhos[at - 1] == 2 * rho      # the next x-step is the first at it
    assert res.timings["rho_update"] >= 0


def test_no_event_without_a_change():
    p = _problem()
    admmkit.solve(p, rho=1.0, max_iter=30)
    assert p.events == []


def test_a_plug_in_without_the_hook_runs_as_before():
    from admmkit.loop.steps import RhoEvent
    event = RhoEvent(object())                 # a plug-in of the protocol that lacks update_rho
    assert event.change(2) == 2.0 and event.seconds == 0.0


def test_the_accelerator_restarts_on_the_event(monkeypatch):
    from admmkit.loop.acceleration import Acceleration
    resets = []
    original = Acceleration.reset
    monkeypatch.setattr(Acceleration, "reset", lambda self: (resets.append(1), original(self)))
    p = _problem()
    res = admmkit.solve(p, rho=64.0, policy=Halve(), max_iter=20, acceleration=Anderson(),
                        stop=admmkit.ResidualTolerance(1e-300, 0))
    assert len(resets) == res.rho_changes == 6


def test_a_direct_x_step_factorises_at_the_event_not_at_the_next_solve():
    rng = np.random.default_rng(1)
    A = rng.standard_normal((12, 6))
    xs = admmkit.QuadraticXStep(sp.csr_matrix(A.T @ A), rng.standard_normal(6), solver="direct")
    before = xs.counters()["factorizations_computed"]
    xs.update_rho(3.0)
    assert xs.counters()["factorizations_computed"] == before + 1
    xs(np.zeros(6), np.zeros(6), 3.0, np.zeros(6))
    assert xs.counters()["factorizations_computed"] == before + 1      # the solve found it held


def test_a_factor_cache_is_bounded_and_takes_any_factorisation():
    calls = []

    def dense(matrix):
        calls.append(matrix.shape)
        return lambda b: np.linalg.solve(matrix, b)
    cache = CachedFactorization(lambda rho: np.eye(3) * (1 + rho), factor=dense, max_cached=4)
    for rho in range(1, 10):
        cache.prepare(float(rho))
    assert len(cache) == 4 and cache.factorizations == 9 and cache.backend == "dense"
    assert np.allclose(cache.solve(9.0, np.ones(3)), np.ones(3) / 10)
    cache.clear()
    assert len(cache) == 0
    with pytest.raises(TypeError, match="factor"):
        CachedFactorization(lambda rho: np.eye(2), factor="cholesky")


def test_condensed_contact_holds_at_most_32_factors():
    from admmkit.problems.contact import contact_problem, example1
    from admmkit.problems.contact.model.assembly import assemble
    problem = contact_problem(assemble(example1(h=1 / 10)), mode="condensed")
    for rho in np.geomspace(1, 1e6, 40):
        problem.update_rho(float(rho))
    assert len(problem.factors) == 32 and problem.counters()["factorizations"] == 40
