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


# ---------------------------------------------------------------- #46 item 4, #47 item 9
@pytest.mark.parametrize("atom, cone", [(lambda x: cp.norm(x, 2), "SOC"), (lambda x: cp.sum(cp.exp(x)), "ExpCone")])
def test_a_cone_the_plug_in_lacks_is_named(atom, cone):
    x = cp.Variable(3)
    with pytest.raises(cp.error.SolverError, match=f"ADMMKIT cannot solve this problem: it needs the cone\\(s\\) {cone}"):
        cp.Problem(cp.Minimize(atom(x)), [x >= 1]).solve(solver=ADMMKIT())


def test_a_rule_returning_nan_is_named_in_the_error():
    from admmkit import Policy

    class NaNRule(Policy):
        name = "nan_rule"

        def reset(self, rho0):
            pass

        def update(self, rec):
            return float("nan")

    x = cp.Variable(3)
    problem = cp.Problem(cp.Minimize(cp.sum_squares(x)), [x >= 1])
    with pytest.raises((cp.error.SolverError, ValueError), match="NaNRule.*nan"):
        problem.solve(solver=ADMMKIT(policy=NaNRule()))


def test_the_defaults_are_those_of_cvxpys_osqp_interface():
    """Swapping solver=cp.OSQP for solver=ADMMKIT() keeps the accuracy asked (eps 1e-5, polishing): with OSQP's
    native defaults (1e-3, no polish) this projection's value was 8.32935."""
    from admmkit.problems.qp.cvxpy_interface import CVXPY_DEFAULTS
    assert CVXPY_DEFAULTS == {"eps_abs": 1e-5, "eps_rel": 1e-5, "max_iter": 10_000, "polish": True}
    x = cp.Variable(3)
    problem = cp.Problem(cp.Minimize(cp.sum_squares(x)), [cp.sum(x) == 5, x >= 0])
    problem.solve(solver=ADMMKIT())
    assert problem.value == pytest.approx(25 / 3, rel=1e-9)
    stats = problem.solver_stats.extra_stats
    assert (stats.settings.eps_abs, stats.settings.max_iter, stats.settings.polish) == (1e-5, 10_000, True)
    problem.solve(solver=ADMMKIT(), polishing=False, eps_abs=1e-3, eps_rel=1e-3)      # OSQP 1.x's name is taken
    assert problem.solver_stats.extra_stats.settings.polish is False


def test_without_cvxpy_the_import_error_names_the_pip_command():
    import subprocess
    import sys
    code = ("import sys; sys.modules['cvxpy'] = None\n"
            "try:\n    import admmkit.problems.qp.cvxpy_interface\n"
            "except ImportError as e:\n    print(type(e).__name__, '|', e)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == "ImportError | admmkit.problems.qp.cvxpy_interface needs cvxpy: pip install cvxpy"
