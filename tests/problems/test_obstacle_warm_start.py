"""The warm level's active-set step (problems/obstacle/warm_start.py), checked against the exact discrete solution."""
import math

import numpy as np
import pytest
import scipy.sparse as sp

from admmkit.benchmarks.fixtures.pdas import pdas
from admmkit.problems.obstacle import ObstacleProblem, radial
from admmkit.problems.obstacle.adaptive import solve_adaptive
from admmkit.problems.obstacle.warm_start import FreeProblem, active_set_multiplier, active_set_start, warm_start


def _exact(problem):
    """The exact discrete solution by the primal-dual active set method (finite termination)."""
    s = problem.sign
    out = pdas(problem.K, problem.F, -s * sp.identity(problem.n, format="csr"), -s * problem.psi,
               method="bounds", max_iter=200)
    assert out.status == "converged"
    return out.u


def _energy(problem, v):
    return math.sqrt(float(v @ (problem.K @ v)))


@pytest.fixture(scope="module")
def level():
    problem = ObstacleProblem(radial(h=1 / 8), backend="jacobi")
    return problem, _exact(problem)


def test_one_step_from_the_right_contact_set_gives_the_exact_discrete_solution(level):
    """Where the start puts exactly the solution's contact nodes on the obstacle, one active-set step returns the
    solution (to CG's tolerance), however far off the start is elsewhere, and the multiplier that closes
    K u - F + M lam = 0."""
    problem, exact = level
    slack = problem.sign * (exact - problem.psi)
    on = slack <= 1e-12
    assert 10 < on.sum() < problem.n - 10
    x, y = problem.nodes[problem.free].T
    smooth = 0.3 * np.cos(x) * np.cos(y)                          # a smooth error, kept off the contact set
    start = np.where(on, problem.psi, exact + problem.sign * (np.abs(smooth) + 1e-3))
    out = active_set_start(problem, start)
    assert _energy(problem, out["x0"] - exact) <= 1e-6 * _energy(problem, exact)
    assert _energy(problem, start - exact) > 1e-2 * _energy(problem, exact)
    residual = problem.K @ out["x0"] - problem.F + problem.m * out["lam0"]
    assert np.max(np.abs(residual)) <= 1e-6 * np.max(np.abs(problem.F))
    assert np.all(out["lam0"][~on] == 0.0)
    assert np.all(problem.sign * (out["z0"] - problem.psi) >= 0.0)           # z0 feasible


def test_the_step_keeps_the_starts_contact_nodes_on_the_obstacle(level):
    """A start with the wrong contact set (half the solution's contact nodes lifted off): its contact nodes stay
    on the obstacle, the other nodes solve K u = F, and lam is zero there."""
    problem, exact = level
    x = problem.nodes[problem.free][:, 0]
    lifted = (problem.sign * (exact - problem.psi) <= 1e-12) & (x > 0)
    assert lifted.sum() > 5
    start = np.where(lifted, exact + problem.sign * 0.01, exact)
    on = problem.sign * (start - problem.psi) <= 0.0
    out = active_set_start(problem, start)
    assert np.array_equal(out["x0"][on], problem.psi[on])
    r = (problem.K @ out["x0"] - problem.F)[~on]
    assert np.linalg.norm(r) <= 1e-6 * np.linalg.norm(problem.F)
    assert np.all(out["lam0"][~on] == 0.0)


def test_warm_start_keeps_the_start_of_lower_energy(level):
    """For a feasible z, J(z) - J(u_h) >= ||z - u_h||_K^2 / 2: warm_start keeps the step where its projected start
    has the lower energy (the solution's contact set, a smooth error elsewhere: the step returns the solution)
    and the prolongated start with its lam where the step's is higher (a start just off the obstacle everywhere:
    the step solves K u = F without a contact node and goes through the obstacle)."""
    problem, exact = level
    J = lambda v: 0.5 * v @ (problem.K @ v) - problem.F @ v          # noqa: E731
    lam = np.full(problem.n, 0.25)
    on = problem.sign * (exact - problem.psi) <= 1e-12
    x, y = problem.nodes[problem.free].T
    smooth = np.where(on, problem.psi, exact + problem.sign * (0.3 * np.abs(np.cos(x) * np.cos(y)) + 1e-3))
    off = exact + problem.sign * 1e-3
    for start, stepped in ((smooth, True), (off, False)):
        out, step = warm_start(problem, start, lam), active_set_start(problem, start)
        plain_z0 = problem.z_step(start, np.zeros(problem.n), 1.0, None)
        assert (J(step["z0"]) <= J(plain_z0)) == stepped
        kept = step if stepped else {"x0": start, "z0": plain_z0, "lam0": lam}
        assert all(np.array_equal(out[k], kept[k]) for k in ("x0", "z0", "lam0"))
    plain = warm_start(problem, smooth, lam, step=False)
    assert plain["x0"] is smooth and plain["lam0"] is lam and "z0" in plain


def test_p1_warm_levels_start_closer_with_the_step(monkeypatch):
    """On the radial P1 levels the step's start is closer to the level's solution than the prolongated one, and
    both paths end at the target; False keeps the prolongated start."""
    import admmkit.problems.obstacle.adaptive as adaptive
    plain, starts = adaptive.solve, {}

    def solve(problem, **kw):
        res = plain(problem, **kw)
        if "x0" in kw:
            starts.setdefault(kw_key, []).append(_energy(problem, kw["x0"] - res.z) / _energy(problem, res.z))
        return res
    monkeypatch.setattr(adaptive, "solve", solve)
    for kw_key in (True, False):
        assert solve_adaptive(radial(h=1 / 2), 2e-2, active_set_step=kw_key).reached
    assert len(starts[True]) >= 4
    assert np.median(starts[True]) < 0.5 * np.median(starts[False])


def test_the_free_problem_keeps_its_solver_while_the_set_stays(level):
    """FreeProblem sets up K_II once per active set: the same set again reuses it (the same u), a new set sets up
    anew; the multiplier from the solution's own contact set is the solution's contact force."""
    problem, u = level
    free = FreeProblem(problem)
    mu = active_set_multiplier(problem, u, free=free)
    on = problem.sign * (u - problem.psi) <= 0.0
    force = np.where(on, np.maximum(problem.sign * (problem.K @ u - problem.F), 0.0), 0.0)
    assert np.max(np.abs(mu - force)) <= 1e-6 * np.max(np.abs(force))
    assert np.array_equal(active_set_multiplier(problem, u, free=free), mu) and free.setups == 1
    shifted = np.where(on, u, u + 0.5 * (u - problem.psi))     # the same touched set
    active_set_multiplier(problem, shifted, free=free)
    assert free.setups == 1
    assert np.all(active_set_multiplier(problem, u + 1.0, free=free) == 0.0)     # no node on the obstacle
    assert free.setups == 2                                                     # a new set, set up anew
    assert np.array_equal(active_set_multiplier(problem, u, free=free), mu) and free.setups == 3
    with pytest.raises(ValueError, match=f"on must be a boolean mask of {problem.n} values"):
        free.solution(on.astype(float), u)
    with pytest.raises(ValueError, match=f"on must be a boolean mask of {problem.n} values"):
        free.solution(on[:-1], u)
    with pytest.raises(ValueError, match="x must hold .* with a NaN or inf"):
        free.solution(on, np.full(problem.n, np.nan))


def test_active_set_multiplier_refuses_an_iterate_of_the_wrong_shape_or_with_a_nan(level):
    problem, u = level
    with pytest.raises(ValueError, match=f"z must hold {problem.n} finite values"):
        active_set_multiplier(problem, u[:-1])
    with pytest.raises(ValueError, match="with a NaN or inf"):
        active_set_multiplier(problem, np.where(np.arange(problem.n) == 0, np.nan, u))


def test_warm_p2_levels_and_only_they_try_the_active_set_multiplier(monkeypatch):
    """solve_adaptive's balanced stop tries the active-set multiplier on warm levels by ACTIVE_SET_BOUND: P2 yes,
    P1 no, never on the cold first level."""
    import admmkit.problems.obstacle.adaptive as adaptive
    made = []

    class Spy(adaptive.BalancedStop):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            made.append((getattr(self.problem, "order", 1), self.gap.active_set))
    monkeypatch.setattr(adaptive, "BalancedStop", Spy)
    for order in (1, 2):
        solve_adaptive(radial(h=1 / 2), 0.1, fe_order=order, max_levels=3)
    assert [a for o, a in made if o == 1] == [False, False, False]
    p2 = [a for o, a in made if o == 2]
    assert len(p2) >= 2 and p2[0] is False and all(p2[1:])


def test_a_run_started_on_the_discrete_solution_ends_converged_not_stalled(level):
    """ADMM from its fixed point ends converged at once.  (Where the x-step left x exactly unchanged, as Jacobi-CG
    written for x itself did, the balanced stop tests that iterate at once, before its schedule's first test at
    iteration 2: tests/admmkit/test_balanced_stop.py.)"""
    import admmkit
    from admmkit.problems.obstacle.estimate import BalancedStop
    problem, exact = level
    start = active_set_start(problem, exact)
    res = admmkit.solve(problem, rho=problem.rho_scale(), policy="summable", stop=BalancedStop(problem), **start)
    assert res.status.value == "converged" and res.iterations <= 2


@pytest.mark.parametrize("value", ["yes", 1, None, float("nan")])
def test_bad_active_set_step_is_named(value):
    with pytest.raises(ValueError, match="active_set_step"):
        solve_adaptive(radial(h=1 / 4), 5e-2, active_set_step=value)


def test_active_set_start_refuses_a_start_of_the_wrong_shape_or_with_a_nan(level):
    problem, exact = level
    with pytest.raises(ValueError, match=f"x0 must hold {problem.n} finite values.*shape \\({problem.n - 1},\\)"):
        active_set_start(problem, exact[:-1])
    bad = exact.copy()
    bad[3] = np.nan
    with pytest.raises(ValueError, match="x0 must hold .* with a NaN or inf"):
        active_set_start(problem, bad)


@pytest.mark.parametrize("step", [True, False])
def test_warm_start_refuses_a_start_of_the_wrong_shape_or_with_a_nan(level, step):
    problem, exact = level
    with pytest.raises(ValueError, match=f"x0 must hold {problem.n} finite values.*shape \\({problem.n - 1},\\)"):
        warm_start(problem, exact[:-1], step=step)
    bad = exact.copy()
    bad[3] = np.nan
    with pytest.raises(ValueError, match="x0 must hold .* with a NaN or inf"):
        warm_start(problem, bad, step=step)
    with pytest.raises(ValueError, match="lam0 must hold .* with a NaN or inf"):
        warm_start(problem, exact, bad, step=step)
