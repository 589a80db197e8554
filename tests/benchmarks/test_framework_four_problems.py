"""A subset of benchmarks/framework/four_problems.py: the issue #14 problems, written with the building blocks, against cvxpy."""
import numpy as np
import pytest

import admmkit

pytest.importorskip("cvxpy")
from admmkit.benchmarks.framework.four_problems import PROBLEMS, build  # noqa: E402

CASES = [("summable", "zx", 1e3), ("residual_balancing", "xz", 1e-3), ("aadmm", "xz", 1.0), ("osqp", "zx", 1e-3)]


@pytest.fixture(scope="module")
def built():
    return {name: build(name) for name in PROBLEMS}


@pytest.mark.parametrize("name", list(PROBLEMS))
def test_adaptive_rules_solve_to_1e_8(built, name):
    problem, ref = built[name]
    for rule, order, rho0 in CASES:
        res = admmkit.solve(problem, rho=rho0, policy=rule, order=order,
                            stop=admmkit.ResidualTolerance(1e-12, 1e-12), max_iter=20_000)
        err = np.linalg.norm(res.x - ref) / np.linalg.norm(ref)
        assert res.status is admmkit.Status.CONVERGED and err <= 1e-8, (name, rule, order, rho0, err)


@pytest.mark.study
@pytest.mark.parametrize("name", list(PROBLEMS))
def test_default_stop_never_lies(built, name):
    problem, ref = built[name]
    for rule in ("fixed", "summable"):
        for rho0 in (1e-3, 1e3):
            res = admmkit.solve(problem, rho=rho0, policy=rule, order="zx", max_iter=10_000)
            err = np.linalg.norm(res.x - ref) / np.linalg.norm(ref)
            if res.status is admmkit.Status.CONVERGED:
                assert err <= 1e-3, (name, rule, rho0, err)
