"""Building blocks (issue #14): prox operators and the quadratic x-step against cvxpy, LinearMap, counters."""
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

import admmkit
from admmkit import LinearMap, QuadraticXStep, ResidualTolerance, SplitProblem, prox

cp = pytest.importorskip("cvxpy")
TIGHT = dict(solver="CLARABEL", tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12)
PROX_TOL = dict(solver="CLARABEL", tol_gap_abs=1e-10, tol_gap_rel=1e-10, tol_feas=1e-10)
rng = np.random.default_rng(7)
P_SIZE = 12
V = rng.standard_normal(P_SIZE) * 2
M_DIAG = rng.uniform(0.5, 2.0, P_SIZE)
GROUPS = [np.arange(0, 4), np.arange(4, 9), np.arange(9, 12)]
M_GROUPED = np.concatenate([np.full(len(g), w) for g, w in zip(GROUPS, (0.7, 1.3, 2.0))])


def cvx_prox(g_expr, v, t, m, constraints=lambda z: []):
    z = cp.Variable(v.size)
    w = np.ones_like(v) if m is None else m
    cp.Problem(cp.Minimize(g_expr(z) + cp.sum(cp.multiply(w, cp.square(z - v))) / (2 * t)), constraints(z)).solve(**PROX_TOL)
    return z.value


LOWER, UPPER = -np.linspace(0.1, 1, P_SIZE), np.linspace(0.2, 1.5, P_SIZE)
CASES = {
    "zero": (prox.Zero(), lambda z: 0, lambda z: []),
    "box": (prox.Box(LOWER, UPPER), lambda z: 0, lambda z: [z >= LOWER, z <= UPPER]),
    "nonnegative": (prox.NonNegative(), lambda z: 0, lambda z: [z >= 0]),
    "upper_bound": (prox.UpperBound(UPPER), lambda z: 0, lambda z: [z <= UPPER]),
    "l1": (prox.L1(0.8), lambda z: 0.8 * cp.norm1(z), lambda z: []),
    "l1_weighted": (prox.L1(np.linspace(0, 2, P_SIZE)), lambda z: cp.sum(cp.multiply(np.linspace(0, 2, P_SIZE), cp.abs(z))),
                    lambda z: []),
    "l2_ball_M": (prox.L2Ball(1.5, in_M_norm=True), lambda z: 0,
                  lambda z: [cp.sum(cp.multiply(M_DIAG, cp.square(z))) <= 1.5 ** 2]),
}


@pytest.mark.parametrize("metric", ["identity", "diagonal"])
@pytest.mark.parametrize("name", list(CASES))
def test_prox_matches_cvxpy(name, metric):
    op, g_expr, cons = CASES[name]
    m = None if metric == "identity" else M_DIAG
    for t in (0.3, 2.0):
        ref = cvx_prox(g_expr, V, t, m, cons)
        if name == "l2_ball_M" and m is None:
            ref = cvx_prox(g_expr, V, t, None, lambda z: [cp.sum_squares(z) <= 1.5 ** 2])
        assert np.allclose(op.prox(V, t, m), ref, atol=1e-7), (name, metric, t)


@pytest.mark.parametrize("metric", [None, "grouped"])
def test_group_l1_and_euclidean_ball_match_cvxpy(metric):
    m = None if metric is None else M_GROUPED
    op = prox.GroupL1(GROUPS, 0.9)
    g = lambda z: 0.9 * sum(cp.norm(z[idx]) for idx in GROUPS)
    assert np.allclose(op.prox(V, 0.7, m), cvx_prox(g, V, 0.7, m), atol=1e-7)
    ball = prox.L2Ball(1.2, center=0.1)
    uniform = None if m is None else np.full(P_SIZE, 1.7)
    ref = cvx_prox(lambda z: 0, V, 0.5, uniform, lambda z: [cp.norm(z - 0.1) <= 1.2])
    assert np.allclose(ball.prox(V, 0.5, uniform), ref, atol=1e-7)


def test_consensus_is_the_weighted_average():
    op = prox.Consensus(3)
    v, m = rng.standard_normal(12), rng.uniform(0.5, 2, 12)
    z = cp.Variable(12)
    blocks = [z[0:4], z[4:8], z[8:12]]
    cp.Problem(cp.Minimize(cp.sum(cp.multiply(m, cp.square(z - v)))), [blocks[0] == blocks[1], blocks[1] == blocks[2]]).solve(**PROX_TOL)
    assert np.allclose(op.prox(v, 1.0, m), z.value, atol=1e-7)


def test_non_exact_weighted_forms_are_refused():
    with pytest.raises(ValueError, match="non-uniform metric"):
        prox.L2Ball(1.0).check(M_DIAG)
    with pytest.raises(ValueError, match="non-uniform metric"):
        prox.GroupL1(GROUPS, 1.0).check(M_DIAG)


def test_pyproximal_adapter():
    pyproximal = pytest.importorskip("pyproximal")
    op = prox.PyProximal(pyproximal.L1(sigma=0.8))
    assert np.allclose(op.prox(V, 0.3, np.full(P_SIZE, 2.0)), prox.L1(0.8).prox(V, 0.3, np.full(P_SIZE, 2.0)))
    assert op.value(V) == pytest.approx(0.8 * np.abs(V).sum())
    with pytest.raises(ValueError, match="non-uniform metric"):
        op.check(M_DIAG)
    ball = prox.PyProximal(pyproximal.proximal.EuclideanBall(np.zeros(P_SIZE), 1.0))
    assert np.allclose(ball.prox(V, 1.0), prox.L2Ball(1.0).prox(V, 1.0))


def test_linear_map_adjoint_norm_and_gram():
    A = rng.standard_normal((P_SIZE, 5))
    for given in (A, sp.csr_matrix(A), spla.aslinearoperator(A)):
        L = LinearMap(given, M=M_DIAG)
        y = rng.standard_normal(P_SIZE)
        assert L.adjoint_norm(y) == pytest.approx(np.linalg.norm(A.T @ (M_DIAG * y)))
        assert L.norm(y) == pytest.approx(np.sqrt(y @ (M_DIAG * y)))
        if L.is_matrix():
            assert np.allclose(L.gram().toarray(), A.T @ np.diag(M_DIAG) @ A)
    W = rng.uniform(1, 3, 5)
    Lw = LinearMap(A, x_weights=W)
    v = A.T @ y
    assert Lw.adjoint_norm(y) == pytest.approx(np.sqrt(v @ (v / W)))     # the dual norm of ||x||_W
    with pytest.raises(ValueError, match="M must be"):
        LinearMap(A, M=-np.ones(P_SIZE))


def x_step_reference(P, q, A, m, sigma, z, lam, rho, x, c):
    H = P + sigma * np.eye(P.shape[0]) + rho * A.T @ np.diag(m) @ A
    return np.linalg.solve(H, -q + sigma * x + A.T @ (m * (rho * (z + c) - lam)))


@pytest.mark.parametrize("solver", ["direct", "cg", "amg"])
def test_quadratic_x_step_is_the_minimiser(solver):
    n, p = 30, 45
    B = rng.standard_normal((n, n))
    P, q, A = B @ B.T / n + np.eye(n), rng.standard_normal(n), rng.standard_normal((p, n))
    m, z, lam, x = rng.uniform(0.5, 2, p), rng.standard_normal(p), rng.standard_normal(p), rng.standard_normal(n)
    given = (spla.aslinearoperator(P), spla.aslinearoperator(A)) if solver == "cg" else (sp.csr_matrix(P), sp.csr_matrix(A))
    step = QuadraticXStep(given[0], q, given[1], M=m, sigma=1e-3, solver=solver)
    for rho in (0.1, 10.0, 0.1):
        got = step(z, lam, rho, x, 0.3)
        ref = x_step_reference(P, q, A, m, 1e-3, z, lam, rho, x, 0.3)
        tol = 1e-6 if solver == "amg" else 1e-9
        assert np.allclose(got, ref, atol=tol * np.abs(ref).max()), solver


def test_cg_with_a_jacobi_preconditioner_per_rho():
    n, p = 40, 60
    B = rng.standard_normal((n, n))
    P, A = B @ B.T / n + np.eye(n), rng.standard_normal((p, n))
    q, z, lam, x = rng.standard_normal(n), rng.standard_normal(p), rng.standard_normal(p), np.zeros(n)
    diag = lambda rho: np.diag(P) + rho * (A * A).sum(axis=0)                 # noqa: E731
    jacobi = lambda rho: spla.LinearOperator((n, n), matvec=lambda v: np.ravel(v) / diag(rho))  # noqa: E731
    plain = QuadraticXStep(spla.aslinearoperator(P), q, spla.aslinearoperator(A), solver="cg")
    pre = QuadraticXStep(spla.aslinearoperator(P), q, spla.aslinearoperator(A), solver="cg", cg_preconditioner=jacobi)
    ref = x_step_reference(P, q, A, np.ones(p), 0.0, z, lam, 5.0, x, 0.0)
    for step in (plain, pre):
        assert np.allclose(step(z, lam, 5.0, x), ref, atol=1e-9 * np.abs(ref).max())
    assert pre.cg_iterations <= plain.cg_iterations


def test_diagonal_x_step_is_chosen_for_a_diagonal_problem():
    d = rng.uniform(1, 2, 8)
    step = QuadraticXStep(sp.diags(d), -np.ones(8), None, M=np.full(8, 2.0))
    assert step.solver == "diagonal"
    z, lam = rng.standard_normal(8), rng.standard_normal(8)
    ref = x_step_reference(np.diag(d), -np.ones(8), np.eye(8), np.full(8, 2.0), 0.0, z, lam, 3.0, z, 0.0)
    assert np.allclose(step(z, lam, 3.0, z), ref)


def lasso(seed=0, m=30, n=20, mu=0.5):
    r = np.random.default_rng(seed)
    D, b = r.standard_normal((m, n)), r.standard_normal(m)
    x = cp.Variable(n)
    cp.Problem(cp.Minimize(0.5 * cp.sum_squares(D @ x - b) + mu * cp.norm1(x))).solve(**TIGHT)
    return SplitProblem(QuadraticXStep(D.T @ D, -D.T @ b), prox.L1(mu)), x.value


@pytest.mark.parametrize("order", ["xz", "zx"])
def test_split_problem_lasso_matches_cvxpy(order):
    problem, x_ref = lasso()
    res = admmkit.solve(problem, policy="summable", order=order, stop=ResidualTolerance(1e-12, 1e-12), max_iter=5000)
    assert res.status is admmkit.Status.CONVERGED
    assert np.linalg.norm(res.x - x_ref) <= 1e-8 * np.linalg.norm(x_ref)
    assert max(res.kkt.values()) < 1e-10


def test_counters_count_this_run_whatever_the_cache_holds():
    problem, _ = lasso()
    runs = [admmkit.solve(problem, rho=1.0, policy="residual_balancing", order="xz", max_iter=300,
                          stop=ResidualTolerance(1e-10, 1e-10)) for _ in range(2)]
    a, b = runs
    assert a.counters["factorizations"] == b.counters["factorizations"] == len(set(a.history["rho"]))
    assert a.counters["factorizations_computed"] == a.counters["factorizations"]
    assert b.counters["factorizations_computed"] == 0           # the second run found them all in the cache
    assert a.counters["solves"] == b.counters["solves"] == a.iterations


def test_default_stop_flags_an_inaccurate_stop():
    # rho_0 = 1e-3 with fixed rho: the relative-change rule fires early, far from the solution
    problem, x_ref = lasso()
    res = admmkit.solve(problem, rho=1e-3, stop=admmkit.RelativeChange(1e-5), max_iter=5000)
    err = np.linalg.norm(res.x - x_ref) / np.linalg.norm(x_ref)
    assert res.stopped_by is not None
    assert (res.status is admmkit.Status.CONVERGED_INACCURATE) == (max(res.accuracy.values()) > 1e-4)
    if err > 1e-3:
        assert res.status is admmkit.Status.CONVERGED_INACCURATE
