"""The LASSO plug-in admmkit.problems.lasso: against cvxpy, x = 0 above lam_max, the refusals, the KKT measure."""
import numpy as np
import pytest

import admmkit
from admmkit.problems.lasso import Lasso, lam_max, solve_with_cvxpy

pytest.importorskip("cvxpy")
TIGHT = admmkit.ResidualTolerance(1e-12, 1e-12)


def data(m=60, n=40, seed=0):
    """A, b with standard normal entries (m > n: A has full column rank)."""
    r = np.random.default_rng(seed)
    return r.standard_normal((m, n)), r.standard_normal(m)


@pytest.mark.parametrize("shape", [(60, 40), (30, 80)])
@pytest.mark.parametrize("order", ["xz", "zx"])
def test_matches_cvxpy_to_1e_6(shape, order):
    A, b = data(*shape)
    lam = 0.1 * lam_max(A, b)
    problem, x_star = Lasso(A, b, lam), solve_with_cvxpy(A, b, lam)
    res = admmkit.solve(problem, order=order, stop=TIGHT, max_iter=20_000)
    assert res.status is admmkit.Status.CONVERGED
    assert np.linalg.norm(res.x - x_star) <= 1e-6 * np.linalg.norm(x_star)
    assert abs(res.objective - problem.objective(x_star)) <= 1e-6 * problem.objective(x_star)
    assert res.objective == pytest.approx(0.5 * np.sum((A @ res.x - b) ** 2) + lam * np.abs(res.x).sum())


def test_default_solve_is_converged_and_sparse():
    A, b = data()
    lam = 0.3 * lam_max(A, b)
    res = admmkit.solve(Lasso(A, b, lam))
    x_star = solve_with_cvxpy(A, b, lam)
    assert res.status is admmkit.Status.CONVERGED
    assert np.linalg.norm(res.x - x_star) <= 1e-3 * np.linalg.norm(x_star)
    assert np.array_equal(np.flatnonzero(res.z), np.flatnonzero(np.abs(x_star) > 1e-8))   # z's zeros are exact


@pytest.mark.parametrize("factor", [1.0, 1.5])
def test_x_is_zero_from_lam_max_on(factor):
    A, b = data(30, 80, seed=2)
    res = admmkit.solve(Lasso(A, b, factor * lam_max(A, b)))
    assert res.status is admmkit.Status.CONVERGED                       # a relative ||x - z|| would be 1 here
    assert not np.any(res.z) and np.linalg.norm(res.x) <= 2 * np.sqrt(80) * 1e-6
    assert np.linalg.norm(solve_with_cvxpy(A, b, factor * lam_max(A, b))) < 1e-6   # the reference agrees
    below = admmkit.solve(Lasso(A, b, 0.99 * lam_max(A, b)), stop=TIGHT, max_iter=20_000)
    assert np.count_nonzero(below.z) == 1                               # just below: one entry leaves 0


def test_lam_max_is_the_largest_entry_of_A_transpose_b():
    A, b = data()
    assert lam_max(A, b) == np.abs(A.T @ b).max()


@pytest.mark.parametrize("args, parameter", [
    ((np.ones(3), np.ones(3), 1.0), "A must be a 2-D array"),
    ((np.ones((3, 0)), np.ones(3), 1.0), "A must be a 2-D array"),
    ((np.array([[1.0, np.nan]]), np.ones(1), 1.0), "A must have finite entries"),
    ((np.ones((3, 2)), np.ones(2), 1.0), r"b must be a vector of 3 entries \(one per row of A\), got shape \(2,\)"),
    ((np.ones((3, 2)), np.ones((3, 1)), 1.0), "b must be a vector of 3 entries"),
    ((np.ones((3, 2)), np.array([1.0, np.inf, 0.0]), 1.0), "b must have finite entries"),
    ((np.ones((3, 2)), np.ones(3), -0.1), "lam must be a finite number >= 0, got -0.1"),
    ((np.ones((3, 2)), np.ones(3), np.inf), "lam must be a finite number >= 0"),
    ((np.ones((3, 2)), np.ones(3), np.nan), "lam must be a finite number >= 0"),
    ((np.ones((3, 2)), np.ones(3), "1"), "lam must be a finite number >= 0"),
])
def test_constructor_refuses_bad_input_naming_the_parameter(args, parameter):
    with pytest.raises(ValueError, match=parameter):
        Lasso(*args)
    with pytest.raises(ValueError, match=parameter):
        solve_with_cvxpy(*args)
    if not parameter.startswith("lam"):
        with pytest.raises(ValueError, match=parameter):
            lam_max(*args[:2])


def test_a_sparse_A_gives_the_dense_solution():
    import scipy.sparse as sp
    A, b = data()
    lam = 0.1 * lam_max(A, b)
    dense = admmkit.solve(Lasso(A, b, lam), stop=TIGHT, max_iter=20_000)
    sparse = admmkit.solve(Lasso(sp.csr_matrix(A), b, lam), stop=TIGHT, max_iter=20_000)
    assert np.allclose(sparse.x, dense.x, atol=1e-10)


def test_kkt_measure_is_below_the_tolerance_at_converged():
    # the data of tutorial 6 (A scaled by 1/sqrt(m), a sparse truth): the default stop's run
    rng = np.random.default_rng(0)
    m, n = 80, 200
    truth = np.zeros(n)
    truth[rng.choice(n, 8, replace=False)] = rng.choice([-2.0, 2.0], 8)
    A = rng.standard_normal((m, n)) / np.sqrt(m)
    b = A @ truth + 0.05 * rng.standard_normal(m)
    res = admmkit.solve(Lasso(A, b, 0.1 * lam_max(A, b)), policy="summable", order="zx")
    assert res.status is admmkit.Status.CONVERGED
    assert set(res.accuracy) == {"primal", "subgradient"} and max(res.accuracy.values()) < 1e-5


@pytest.mark.parametrize("tol", [1e-5, 1e-8, 1e-10])
def test_kkt_measure_tracks_the_error(tol):
    # A of full column rank: the measure is within a factor 2 of the relative error of x, at every tolerance,
    # so `converged` (measure <= 10 x tol) means an error of at most 20 x tol
    A, b = data()
    lam = 0.1 * lam_max(A, b)
    x_star = solve_with_cvxpy(A, b, lam)
    for rule in ("summable", "residual_balancing", "fixed"):
        res = admmkit.solve(Lasso(A, b, lam), policy=rule, stop=admmkit.ResidualTolerance(tol, tol), max_iter=20_000)
        error = np.linalg.norm(res.x - x_star) / np.linalg.norm(x_star)
        measure = max(res.accuracy.values())
        assert res.status in (admmkit.Status.CONVERGED, admmkit.Status.CONVERGED_INACCURATE)
        assert measure / 2 <= error <= 2 * measure, (rule, error, res.accuracy)
        assert (res.status is admmkit.Status.CONVERGED) == (measure <= 10 * max(tol, 1e-9))


def test_kkt_measure_sees_a_wrong_point():
    A, b = data()
    problem = Lasso(A, b, 0.1 * lam_max(A, b))
    zero = np.zeros(40)
    assert problem.kkt_relative(zero, zero, zero)["subgradient"] > 0.5      # x = 0 is far from optimal here
    assert problem.kkt(zero, zero, zero) == problem.kkt_relative(zero, zero, zero)


@pytest.mark.parametrize("options", [dict(policy="residual_balancing"), dict(acceleration="anderson"),
                                     dict(policy="residual_balancing", acceleration="anderson", order="xz")])
def test_works_with_residual_balancing_and_anderson(options):
    # (residual balancing from rho_0 = 1 on data(30, 80, seed=1) cycles: max_iter at 2% error, with the
    # building blocks' SplitProblem as well; a property of the rule, which has no convergence guarantee)
    A, b = data()
    lam = 0.1 * lam_max(A, b)
    x_star = solve_with_cvxpy(A, b, lam)
    res = admmkit.solve(Lasso(A, b, lam), stop=TIGHT, max_iter=20_000, **options)
    assert res.status is admmkit.Status.CONVERGED
    assert np.linalg.norm(res.x - x_star) <= 1e-6 * np.linalg.norm(x_star)
    assert max(res.accuracy.values()) <= 1e-8
