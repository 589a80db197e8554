"""Every public entry point refuses bad input with an error that names the parameter."""
import numpy as np
import pytest

import policies
from admmkit import Policy, RelativeChange, ResidualTolerance, make_policy, solve


@pytest.mark.parametrize("rho", [0, -1, np.nan, np.inf, "abc"])
def test_rho(scalar_problem, rho):
    with pytest.raises(ValueError, match="rho must be a finite number > 0"):
        solve(scalar_problem, rho=rho)


@pytest.mark.parametrize("tol", [0, -1e-5, np.nan, np.inf])
def test_tol(tol):
    with pytest.raises(ValueError, match="tol must be a finite number > 0"):
        RelativeChange(tol)


def test_residual_tolerances():
    with pytest.raises(ValueError, match="eps_abs must be"):
        ResidualTolerance(-1, 1e-3)
    with pytest.raises(ValueError, match="cannot both be 0"):
        ResidualTolerance(0, 0)


@pytest.mark.parametrize("max_iter", [0, -3, 2.5, True])
def test_max_iter(scalar_problem, max_iter):
    with pytest.raises(ValueError, match="max_iter must be an integer >= 1"):
        solve(scalar_problem, max_iter=max_iter)


def test_order(scalar_problem):
    with pytest.raises(ValueError, match="order must be 'xz'"):
        solve(scalar_problem, order="yx")


def test_policy_name(scalar_problem):
    with pytest.raises(ValueError, match="unknown policy 'sumable'; known policies: .*fixed"):
        solve(scalar_problem, policy="sumable")
    with pytest.raises(TypeError, match="policy must be a Policy"):
        solve(scalar_problem, policy=3)


def test_stop_and_callback_types(scalar_problem):
    with pytest.raises(TypeError, match="stop must be a StoppingRule"):
        solve(scalar_problem, stop=1e-5)
    with pytest.raises(TypeError, match="callback must be callable"):
        solve(scalar_problem, callback=5)


def test_starting_point_shape(vector_problem):
    with pytest.raises(ValueError, match="x0 must have shape"):
        solve(vector_problem, x0=np.zeros(3))
    with pytest.raises(ValueError, match="lam0 must be finite"):
        solve(vector_problem, lam0=np.full(vector_problem.n, np.nan))


def test_not_a_problem():
    with pytest.raises(TypeError, match="must implement x_step"):
        solve(object())


def test_policy_needing_dual_residual_without_adjoint():
    from admmkit import Problem

    class NoAdjoint(Problem):
        n = 1
        def x_step(self, z, lam, rho, x): return z
        def z_step(self, Ax, lam, rho, z): return Ax
        def apply_A(self, x): return x

    with pytest.raises(ValueError, match="needs Boyd's dual residual"):
        solve(NoAdjoint(), policy="residual_balancing", order="xz")
    solve(NoAdjoint(), policy="residual_balancing", order="zx", max_iter=3)


@pytest.mark.parametrize("kwargs, match", [
    (dict(tau=0), "tau must be"), (dict(tau=np.nan), "tau must be"), (dict(c_max=-1), "c_max must be an integer"),
    (dict(c_max=2.5), "c_max must be an integer"),
])
def test_summable_parameters(kwargs, match):
    with pytest.raises(ValueError, match=match):
        make_policy("summable", **kwargs)


@pytest.mark.parametrize("kwargs, match", [(dict(mu=0.5), "mu must be"), (dict(tau_incr=1.0), "tau_incr must be")])
def test_residual_balancing_parameters(kwargs, match):
    with pytest.raises(ValueError, match=match):
        make_policy("residual_balancing", **kwargs)
