"""The QP from cvxpy (#26 item 4): problem.solve(solver=ADMMKIT(...)) against Clarabel."""
import numpy as np
import pytest

cp = pytest.importorskip("cvxpy")
from admmkit.problems.qp.cvxpy_interface import ADMMKIT  # noqa: E402

KINDS = ("equality", "inequality", "box")


def random_problem(kind: str, seed: int):
    """A random convex QP written in cvxpy: equality, inequality or box constraints (feasible, bounded)."""
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(5, 25)), int(rng.integers(2, 10))
    x = cp.Variable(n)
    G = rng.standard_normal((n + 2, n))
    c = rng.standard_normal(n)
    x0 = rng.uniform(-0.5, 0.5, n)                                 # a feasible point
    A = rng.standard_normal((min(m, n - 1), n))
    cons = {"equality": [A @ x == A @ x0],
            "inequality": [A @ x <= A @ x0 + rng.uniform(0, 1, A.shape[0])],
            "box": [x >= -1, x <= 1, A @ x <= A @ x0 + 1]}[kind]
    return cp.Problem(cp.Minimize(0.5 * cp.sum_squares(G @ x) + c @ x), cons)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("seed", range(17))
def test_random_cvxpy_qps_match_clarabel(kind, seed):
    prob = random_problem(kind, seed)
    prob.solve(solver=ADMMKIT(policy="osqp"), eps_abs=1e-7, eps_rel=0.0, max_iter=20_000)
    assert prob.status == cp.OPTIMAL
    value, duals = prob.value, [np.copy(c.dual_value) for c in prob.constraints]
    prob.solve(solver=cp.CLARABEL)
    assert abs(value - prob.value) <= 1e-4 * max(1.0, abs(prob.value))
    for mine, ref in zip(duals, (c.dual_value for c in prob.constraints)):
        assert np.allclose(mine, ref, atol=1e-3 * max(1.0, np.abs(ref).max()))


@pytest.mark.parametrize("policy", ["summable", "aadmm"])
def test_any_rule_solves_from_cvxpy(policy):
    prob = random_problem("box", 3)
    prob.solve(solver=ADMMKIT(policy=policy, order="zx"), eps_abs=1e-7, eps_rel=0.0, max_iter=20_000)
    value = prob.value
    prob.solve(solver=cp.CLARABEL)
    assert abs(value - prob.value) <= 1e-4 * max(1.0, abs(prob.value))


def test_infeasible_and_unbounded_get_cvxpy_statuses():
    x = cp.Variable(4)
    infeasible = cp.Problem(cp.Minimize(cp.sum_squares(x)), [x >= 1, cp.sum(x) <= 2])
    infeasible.solve(solver=ADMMKIT())
    assert infeasible.status == cp.INFEASIBLE
    unbounded = cp.Problem(cp.Minimize(cp.sum_squares(x[:2]) - x[3]), [x[:3] <= 1])
    unbounded.solve(solver=ADMMKIT())
    assert unbounded.status == cp.UNBOUNDED


def test_a_capped_run_is_a_user_limit_not_optimal():
    prob = random_problem("inequality", 0)
    prob.solve(solver=ADMMKIT(), eps_abs=1e-12, eps_rel=0.0, max_iter=5)
    assert prob.status == cp.USER_LIMIT
