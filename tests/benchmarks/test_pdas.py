"""The primal-dual active set baseline against cvxpy + Clarabel, its KKT residuals and its bad input."""
import numpy as np
import pytest
import scipy.sparse as sp

from admmkit.benchmarks.fixtures.pdas import pdas
from admmkit.problems.contact import assemble, contact_problem, example1, example2


def clarabel(K, f, B, g):
    import cvxpy as cp

    u = cp.Variable(K.shape[0])
    con = B @ u <= g
    prob = cp.Problem(cp.Minimize(0.5 * cp.quad_form(u, cp.psd_wrap(sp.csc_matrix(K))) - f @ u), [con])
    prob.solve(solver="CLARABEL", tol_gap_abs=1e-11, tol_gap_rel=1e-11, tol_feas=1e-11)
    assert prob.status == "optimal"
    return np.asarray(u.value), np.asarray(con.dual_value)


def random_problem(n=60, m=25, seed=0):
    """SPD K, a dense random B (no selection structure), g chosen so that some constraints bind."""
    rng = np.random.default_rng(seed)
    G = rng.standard_normal((n, n))
    K = sp.csr_matrix(G @ G.T + n * np.eye(n))
    f = rng.standard_normal(n) * 10
    B = sp.csr_matrix(rng.standard_normal((m, n)))
    u_free = np.linalg.solve(K.toarray(), f)
    g = B @ u_free - rng.uniform(-1.0, 1.0, m)          # about half of the rows are violated at u_free
    return K, f, B, g


@pytest.mark.parametrize("method", ["schur", "kkt"])
def test_general_constraints_match_clarabel(method):
    K, f, B, g = random_problem()
    u_ref, mu_ref = clarabel(K, f, B, g)
    res = pdas(K, f, B, g, method=method)
    assert res.converged and res.method == method
    assert np.linalg.norm(res.u - u_ref) <= 1e-7 * np.linalg.norm(u_ref)
    assert np.linalg.norm(res.mu - mu_ref) <= 1e-6 * np.linalg.norm(mu_ref)
    assert 0 < res.active.sum() < g.size
    assert max(res.kkt.values()) < 1e-9


@pytest.mark.parametrize("example, order, expected", [(example1, 1, "bounds"), (example2, 1, "bounds"),
                                                      (example1, 2, "schur")])
def test_contact_matches_clarabel(example, order, expected):
    ops = assemble(example(h=1 / 10, order=order))
    u_ref, mu_ref = clarabel(ops.K, ops.f, ops.B, ops.g)
    res = pdas(ops.K, ops.f, ops.B, ops.g, weights=ops.mc)
    assert res.converged and res.method == expected
    assert np.sqrt((res.u - u_ref) @ ops.K @ (res.u - u_ref)) <= 1e-7 * np.sqrt(u_ref @ ops.K @ u_ref)
    assert np.allclose(res.lam, mu_ref / ops.mc, rtol=0, atol=1e-6 * np.abs(mu_ref / ops.mc).max())
    assert res.kkt["infeasibility"] < 1e-12 and res.kkt["stationarity"] < 1e-10


def test_compliance_of_the_condensed_contact_mode_gives_the_same_solution():
    ops = assemble(example2(h=1 / 10))
    problem = contact_problem(ops, "condensed")
    given = pdas(ops.K, ops.f, ops.B, ops.g, weights=ops.mc,
                 compliance=(problem.C, problem.d0, lambda mu: problem.schur.solve(ops.f - ops.B.T @ mu)))
    own = pdas(ops.K, ops.f, ops.B, ops.g, weights=ops.mc, method="kkt")
    assert given.method == "schur" and given.converged and own.converged
    assert np.array_equal(given.active, own.active)
    assert np.abs(given.u - own.u).max() <= 1e-9 * np.abs(own.u).max()


def test_obstacle_lower_bound_matches_cvxpy():
    from admmkit.problems.obstacle import make_problem, radial, solve_with_cvxpy

    p = make_problem(radial(h=1 / 4))
    res = pdas(p.K, p.F, -sp.identity(p.n), -p.psi, weights=p.m, keep_iterates=True)
    u_ref, lam_ref = solve_with_cvxpy(p, tol_gap_abs=1e-11, tol_gap_rel=1e-11, tol_feas=1e-11)
    assert res.converged and res.method == "bounds"
    assert np.linalg.norm(res.u - u_ref) <= 1e-8 * np.linalg.norm(u_ref)
    assert np.allclose(-res.lam, lam_ref, atol=1e-6 * np.abs(lam_ref).max())   # u >= psi: lam = -mu/m
    assert len(res.iterates) == res.iterations == len(res.multipliers) == len(res.history)
    assert np.array_equal(res.iterates[-1], res.u)
    # every step's iterate is feasible on its active set and the times grow
    times = [h["time"] for h in res.history]
    assert times == sorted(times) and res.time >= times[-1]


def test_max_iter_stops_before_the_active_set_settles():
    ops = assemble(example2(h=1 / 10))
    full = pdas(ops.K, ops.f, ops.B, ops.g)
    assert full.converged and full.iterations >= 3
    capped = pdas(ops.K, ops.f, ops.B, ops.g, max_iter=1)
    assert capped.status == "max_iter" and capped.iterations == 1 and not capped.converged


def test_bad_input_names_the_parameter():
    K, f, B, g = random_problem(8, 3)
    with pytest.raises(ValueError, match="method must be one of"):
        pdas(K, f, B, g, method="newton")
    with pytest.raises(ValueError, match="g must have length m = 3"):
        pdas(K, f, B, g[:2])
    with pytest.raises(ValueError, match="f must have length n = 8"):
        pdas(K, f[:5], B, g)
    with pytest.raises(ValueError, match="weights must be 3 finite numbers > 0"):
        pdas(K, f, B, g, weights=[1.0, 0.0, 1.0])
    with pytest.raises(ValueError, match="max_iter must be an integer >= 1"):
        pdas(K, f, B, g, max_iter=0)
    with pytest.raises(ValueError, match="c must be a finite number > 0"):
        pdas(K, f, B, g, c=-1.0)
    with pytest.raises(ValueError, match="method='bounds' needs"):
        pdas(K, f, B, g, method="bounds")
    with pytest.raises(ValueError, match="compliance: C must be 3x3"):
        pdas(K, f, B, g, compliance=(np.eye(2), np.zeros(3), lambda mu: mu))
