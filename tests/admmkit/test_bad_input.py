"""Every public entry point refuses bad input with an error that names the parameter."""
import numpy as np
import pytest

from admmkit import policies
from admmkit import Policy, RelativeChange, ResidualTolerance, make_policy, solve


@pytest.mark.parametrize("rho", [0, -1, np.nan, np.inf])
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


def test_a_plug_in_whose_start_is_not_finite_is_named(vector_problem, monkeypatch):
    n = vector_problem.n
    monkeypatch.setattr(type(vector_problem), "initial_point",
                        lambda self: (np.zeros(n), np.full(n, np.inf), np.zeros(n)))
    with pytest.raises(ValueError, match=r"Obstacle1D.initial_point\(\) gave a non-finite z0"):
        solve(vector_problem)
    assert solve(vector_problem, z0=np.zeros(n), max_iter=3).iterations == 3      # a given start replaces it


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


# ---------------------------------------------------------------- issue #16: wrong types name the parameter
def _no_n_problem():
    from admmkit import Problem

    class NoN(Problem):
        def x_step(self, z, lam, rho, x): return z
        def z_step(self, Ax, lam, rho, z): return Ax
        def apply_A(self, x): return np.asarray(x, dtype=float)
    return NoN()


@pytest.mark.parametrize("call, error, needle", [
    (lambda p: RelativeChange("x"), ValueError, "tol must be a finite number > 0, got 'x'"),
    (lambda p: ResidualTolerance("a", 1e-3), ValueError, "eps_abs must be a finite number >= 0, got 'a'"),
    (lambda p: ResidualTolerance(1e-3, "b"), ValueError, "eps_rel must be a finite number >= 0, got 'b'"),
    (lambda p: solve(p, order="zx", time_limit="5"), TypeError, "time_limit must be a number"),
    (lambda p: solve(p, order="zx", x0="abc"), ValueError, "x0 must be an array of numbers"),
    (lambda p: solve(p, order="zx", x0=np.ones(1) * 1j), ValueError, "x0 must be real"),
    (lambda p: solve(p, order="zx", rho=1e-300), ValueError, r"rho must be in \[1e-30, 1e\+30\]"),
    (lambda p: solve(p, order="zx", rho="1"), TypeError, "rho must be a number"),
    (lambda p: make_policy(None), TypeError, "policy name must be a string"),
    (lambda p: solve(_no_n_problem(), order="zx"), TypeError, "must set the attribute n"),
])
def test_wrong_types_name_the_parameter(scalar_problem, call, error, needle):
    with pytest.raises(error, match=needle):
        call(scalar_problem)


@pytest.mark.parametrize("returned, error, needle", [
    (lambda x: None, TypeError, r"x_step\(\) returned NoneType"),
    (lambda x: list(x), TypeError, r"x_step\(\) returned list"),
    (lambda x: np.zeros(x.size + 1), ValueError, r"x_step\(\) returned an array of shape \(4,\); it must have shape \(3,\)"),
])
def test_a_step_of_the_wrong_shape_is_stopped_at_once(returned, error, needle):
    from admmkit import Problem

    class Bad(Problem):
        n = 3
        def x_step(self, z, lam, rho, x): return returned(x)
        def z_step(self, Ax, lam, rho, z): return Ax
        def apply_A(self, x): return np.asarray(x, dtype=float)
    with pytest.raises(error, match=needle):
        solve(Bad(), order="zx")


@pytest.mark.parametrize("bad_rho", [1e-300, 1e300])
def test_a_policy_outside_the_rho_range_ends_the_run_as_diverged(bad_rho):
    from admmkit import Problem

    class Obstacle1D(Problem):
        n = 5
        d, b, g = np.full(5, 2.0), np.arange(5.0), np.ones(5)
        def x_step(self, z, lam, rho, x): return (self.b - lam + rho * z) / (self.d + rho)
        def z_step(self, Ax, lam, rho, z): return np.minimum(self.g, Ax + lam / rho)
        def apply_A(self, x): return x.copy()

    class Wild(Policy):
        def update(self, rec): return bad_rho
    r = solve(Obstacle1D(), order="zx", policy=Wild(), stop=RelativeChange(1e-8))
    assert r.status.value == "diverged" and "outside admmkit's rho range" in r.message


def test_an_exception_in_the_loop_restores_the_blas_threads():
    from threadpoolctl import threadpool_info

    from admmkit import Problem

    class Boom(Problem):
        n = 2
        def x_step(self, z, lam, rho, x): raise KeyboardInterrupt
        def z_step(self, Ax, lam, rho, z): return Ax
        def apply_A(self, x): return np.asarray(x, dtype=float)
    before = [i["num_threads"] for i in threadpool_info()]
    with pytest.raises(KeyboardInterrupt):
        solve(Boom(), order="zx", blas_threads=1)
    assert [i["num_threads"] for i in threadpool_info()] == before
