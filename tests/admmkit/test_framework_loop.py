"""The lean loop against the eager one, over-relaxation, check_every, callback, warm start (issue #14)."""
import math

import numpy as np
import pytest

import admmkit
from admmkit import RelativeChange, ResidualTolerance, Status, solve


def eager_reference(problem, rho, policy, order, stop, max_iter):
    """The loop as it was before issue #14 (every norm of every iteration), alpha = 1.

    Returns the iterates and the history columns it computed, row by row.
    """
    x, z, lam = (np.array(v, dtype=float) for v in problem.initial_point())
    Ax, c = problem.apply_A(x), problem.c
    policy = admmkit.make_policy(policy)
    policy.reset(rho)
    primal_unit = problem.norm(np.ones_like(z))
    dual_unit = math.sqrt(problem.n) if order == "xz" else primal_unit
    c_norm = problem.norm(np.broadcast_to(np.asarray(c, dtype=float), z.shape))
    iterates, rows = [], []
    for k in range(max_iter):
        if order == "xz":
            x_new = problem.x_step(z, lam, rho, x)
            Ax_new = problem.apply_A(x_new)
            z_new = problem.z_step(Ax_new, lam, rho, z)
        else:
            z_new = problem.z_step(Ax, lam, rho, z)
            x_new = problem.x_step(z_new, lam, rho, x)
            Ax_new = problem.apply_A(x_new)
        r = Ax_new - z_new - c
        lam_new = lam + rho * r
        primal_residual = problem.norm(r)
        rho_Ax_change = rho * problem.norm(Ax_new - Ax)
        if order == "xz":
            dual_residual = rho * problem.adjoint_norm(z_new - z)
            dual_scale = problem.adjoint_norm(lam_new)
        else:
            dual_residual, dual_scale = rho_Ax_change, problem.norm(lam_new)
        row = dict(k=k, rho=rho, primal_residual=primal_residual, dual_residual=dual_residual,
                   rho_Ax_change=rho_Ax_change, lam_change=rho * primal_residual,
                   x_change=problem.x_distance(x_new, x), x_norm=problem.x_norm(x_new),
                   z_change=problem.norm(z_new - z),
                   primal_scale=max(problem.norm(Ax_new), problem.norm(z_new), c_norm), dual_scale=dual_scale,
                   primal_unit=primal_unit, dual_unit=dual_unit)
        rec = admmkit.IterationRecord(order=order, time=0.0, x=x_new, z=z_new, lam=lam_new, Ax=Ax_new, z_prev=z,
                                      Ax_prev=Ax, inner=problem.inner, **row)
        x, z, lam, Ax = x_new, z_new, lam_new, Ax_new
        iterates.append((x, z, lam))
        if stop.fired(rec):
            row["rho_next"] = rho
            rows.append(row)
            break
        rho_next = policy.update(rec)
        row["rho_next"] = rho_next
        rows.append(row)
        rho = float(rho_next)
    return iterates, rows


CASES = [("fixed", "xz"), ("fixed", "zx"), ("summable", "zx"), ("residual_balancing", "xz"),
         ("aadmm", "xz"), ("aadmm", "zx"), ("osqp", "zx"), ("wohlberg", "xz")]


@pytest.mark.parametrize("history", ["lean", "full"])
@pytest.mark.parametrize("policy,order", CASES)
def test_lazy_loop_is_bitwise_the_eager_loop(vector_problem, policy, order, history):
    stop = RelativeChange(1e-9)
    ref_iterates, ref_rows = eager_reference(vector_problem, 0.3, policy, order, stop, 400)
    seen = []
    res = solve(vector_problem, rho=0.3, policy=policy, order=order, stop=stop, max_iter=400, history=history,
                callback=lambda rec: seen.append((rec.x, rec.z, rec.lam)))
    assert res.iterations == len(ref_rows) > 5
    for (x, z, lam), (rx, rz, rlam) in zip(seen, ref_iterates):
        assert np.array_equal(x, rx) and np.array_equal(z, rz) and np.array_equal(lam, rlam)
    h = res.history.as_dict()
    for name in ref_rows[0]:
        expected = np.array([row[name] for row in ref_rows])
        got = h[name]
        if history == "full":
            assert np.array_equal(got, expected), name               # bitwise, every row
        else:
            known = ~np.isnan(got)
            assert np.array_equal(got[known], expected[known]), name  # bitwise where computed
            assert known[-1], f"the last row of a lean history is complete ({name})"


def test_lean_history_computes_only_what_is_read(vector_problem):
    res = solve(vector_problem, rho=0.3, policy="summable", order="zx", stop=RelativeChange(1e-9), max_iter=50,
                history="lean")
    h = res.history
    assert not np.isnan(h["lam_change"]).any() and not np.isnan(h["rho_Ax_change"]).any()   # SADMM reads these
    assert not np.isnan(h["x_change"]).any()                                                 # the stop reads these
    assert np.isnan(h["dual_scale"][:-1]).all() and np.isnan(h["z_change"][:-1]).all()      # nobody did


@pytest.mark.parametrize("order", ["xz", "zx"])
def test_alpha_one_gives_todays_iterates(vector_problem, order):
    runs = [solve(vector_problem, rho=0.5, policy="summable", order=order, stop=RelativeChange(1e-10),
                  history="full", **kw) for kw in ({}, {"alpha": 1.0})]
    a, b = runs
    assert a.iterations == b.iterations
    assert np.array_equal(a.x, b.x) and np.array_equal(a.z, b.z) and np.array_equal(a.lam, b.lam)
    for name in ("primal_residual", "dual_residual", "lam_change", "rho"):
        assert np.array_equal(a.history[name], b.history[name])


@pytest.mark.parametrize("order", ["xz", "zx"])
@pytest.mark.parametrize("alpha", [0.6, 1.6, 1.9])
def test_over_relaxation_converges_to_the_solution(vector_problem, order, alpha):
    x_star, lam_star = vector_problem.solution()
    res = solve(vector_problem, rho=1.0, order=order, alpha=alpha, stop=ResidualTolerance(1e-12, 1e-12))
    assert res.status is Status.CONVERGED and res.alpha == alpha
    assert np.allclose(res.x, x_star, atol=1e-9) and np.allclose(res.lam, lam_star, atol=1e-8)


@pytest.mark.parametrize("order", ["xz", "zx"])
def test_over_relaxation_hand_computed(scalar_problem, order):
    # a = 2, b = 4, g = 1, m = 1, rho = 1, start x = z = lam = 0; alpha = 1.5
    seen = []
    solve(scalar_problem, rho=1.0, order=order, alpha=1.5, max_iter=1, stop=ResidualTolerance(1e-300, 1e-300),
          callback=lambda rec: seen.append(rec))
    rec = seen[0]
    if order == "xz":      # x1 = 4/3, Ax_hat = 1.5*4/3 = 2, z1 = min(1, 2) = 1, lam1 = 0 + (2 - 1) = 1
        assert rec.x[0] == pytest.approx(4 / 3) and rec.z[0] == 1 and rec.lam[0] == pytest.approx(1.0)
    else:                  # z1 = min(1, 0) = 0, z_hat = 0, x1 = 4/3, lam1 = 4/3
        assert rec.z[0] == 0 and rec.x[0] == pytest.approx(4 / 3) and rec.lam[0] == pytest.approx(4 / 3)
    # lam_change is ||lam^{k+1} - lam^k|| (not rho ||r|| when alpha != 1)
    assert rec.lam_change == pytest.approx(abs(rec.lam[0]))


@pytest.mark.parametrize("order", ["xz", "zx"])
def test_relaxed_multipliers_make_both_conditions_exact(vector_problem, order):
    p = vector_problem
    recs = []
    solve(p, rho=0.7, order=order, alpha=1.6, max_iter=6, stop=ResidualTolerance(1e-300, 1e-300), callback=recs.append)
    for rec in recs:
        # x-optimality of f = 1/2 x'Dx - b'x with A = I: D x - b + M lam_x = 0
        assert np.allclose(p.d * rec.x - p.b + p.m * rec.lam_x, 0, atol=1e-12)
        # z-optimality of g = indicator(z <= g): M lam_z in the normal cone: lam_z >= 0, = 0 where z < g
        assert np.all(rec.lam_z >= -1e-12) and np.allclose(rec.lam_z[rec.z < p.g - 1e-12], 0, atol=1e-12)
        # the dual residual is the norm of the first block's defect
        defect = rec.lam_x - rec.lam if order == "xz" else rec.lam_z - rec.lam
        expected = np.linalg.norm(p.m * defect) if order == "xz" else math.sqrt(np.sum(p.m * defect ** 2))
        assert rec.dual_residual == pytest.approx(expected, rel=1e-12, abs=1e-14)


@pytest.mark.parametrize("check_every", [1, 7, 25])
def test_check_every_leaves_the_iterates_alone(vector_problem, check_every):
    ref = solve(vector_problem, rho=0.3, policy="summable", order="zx", stop=ResidualTolerance(1e-10, 1e-10))
    res = solve(vector_problem, rho=0.3, policy="summable", order="zx", stop=ResidualTolerance(1e-10, 1e-10),
                check_every=check_every)
    assert res.converged and res.iterations % check_every == 0
    assert ref.iterations <= res.iterations < ref.iterations + check_every
    same = solve(vector_problem, rho=0.3, policy="summable", order="zx", stop=ResidualTolerance(1e-300, 1e-300),
                 max_iter=ref.iterations)
    assert np.array_equal(same.x, ref.x) and np.array_equal(same.lam, ref.lam)


def test_callback_sees_the_last_record(vector_problem):
    ks = []
    res = solve(vector_problem, rho=1.0, callback=lambda rec: ks.append(rec.k))
    assert res.converged and ks == list(range(res.iterations))


def test_warm_start_from_a_result(vector_problem):
    first = solve(vector_problem, rho=1.0, max_iter=5, stop=ResidualTolerance(1e-12, 1e-12))
    assert first.status is Status.MAX_ITER and np.array_equal(first.x_iterate, first.x)
    again = solve(vector_problem, warm_start=first, max_iter=5, stop=ResidualTolerance(1e-12, 1e-12))
    straight = solve(vector_problem, rho=1.0, max_iter=10, stop=ResidualTolerance(1e-12, 1e-12))
    assert np.array_equal(again.x, straight.x) and np.array_equal(again.lam, straight.lam)
    with pytest.raises(TypeError, match="warm_start must be an admmkit.Result"):
        solve(vector_problem, warm_start=first.x)


@pytest.mark.parametrize("bad,match", [({"alpha": 2.0}, "alpha must be a number in"), ({"alpha": 0}, "alpha"),
                                       ({"check_every": 0}, "check_every must be an integer"),
                                       ({"history": "some"}, "history must be 'lean' or 'full'")])
def test_bad_arguments(vector_problem, bad, match):
    with pytest.raises(ValueError, match=match):
        solve(vector_problem, **bad)


def test_records_are_read_only(vector_problem):
    recs = []
    solve(vector_problem, max_iter=2, callback=recs.append, stop=RelativeChange(1e-300))
    with pytest.raises(AttributeError, match="read-only"):
        recs[0].rho = 3.0
    with pytest.raises(ValueError):
        recs[0].x[0] = 1.0


class Euclidean(admmkit.Problem):
    """The conftest's problem with M = I and no inner/norm override: the loop's fast Euclidean norms apply."""

    def __init__(self, seed=5, n=15):
        r = np.random.default_rng(seed)
        self.d, self.b, self.g, self.n = r.uniform(1, 3, n), r.uniform(-2, 4, n), r.uniform(0.2, 1, n), n

    def x_step(self, z, lam, rho, x):
        return (self.b - lam + rho * z) / (self.d + rho)

    def z_step(self, Ax, lam, rho, z):
        return np.minimum(self.g, Ax + lam / rho)

    def apply_A(self, x):
        return x.copy()

    def adjoint_norm(self, y):
        return float(np.linalg.norm(y))


@pytest.mark.parametrize("order", ["xz", "zx"])
def test_fast_euclidean_norms_are_bitwise_the_problems(order):
    p = Euclidean()
    stop = RelativeChange(1e-9)
    _, ref_rows = eager_reference(p, 0.3, "summable", order, stop, 400)
    res = solve(p, rho=0.3, policy="summable", order=order, stop=stop, max_iter=400, history="full")
    h = res.history.as_dict()
    for name in ref_rows[0]:
        assert np.array_equal(h[name], np.array([row[name] for row in ref_rows])), name


class Shifted(Euclidean):
    """A x - z = c with c != 0 (an array): r = A x - z - c."""

    def __init__(self):
        super().__init__(seed=8, n=10)
        self.c = np.linspace(-0.2, 0.3, self.n)

    def z_step(self, Ax, lam, rho, z):
        return np.minimum(self.g, Ax - self.c + lam / rho)


@pytest.mark.parametrize("problem", [Euclidean, Shifted, "vector"])
@pytest.mark.parametrize("policy,order", [("fixed", "zx"), ("fixed", "xz"), ("summable", "zx"), ("osqp", "zx")])
def test_residual_read_now_and_then_is_bitwise_the_eager_one(vector_problem, problem, policy, order):
    # the loop keeps r = Ax - z - c only while something reads ||r||: a callback that reads it at
    # irregular iterations (and a stop tested every 4) gets the eager loop's numbers, iterates unchanged
    p = vector_problem if problem == "vector" else problem()
    stop = ResidualTolerance(1e-300, 1e-300)
    ref_iterates, ref_rows = eager_reference(p, 0.3, policy, order, stop, 60)
    got = {}

    def read_sometimes(rec):
        if rec.k % 3 == 0 or rec.k in (10, 11, 12, 30):
            got[rec.k] = (rec.primal_residual, rec.lam_change)
            assert rec.primal_residual == p.norm(rec.Ax - rec.z - p.c)
    res = solve(p, rho=0.3, policy=policy, order=order, stop=stop, max_iter=60, check_every=4, callback=read_sometimes)
    assert res.iterations == 60 and len(got) > 20
    x, z, lam = ref_iterates[-1]
    assert np.array_equal(res.x_iterate, x) and np.array_equal(res.z, z) and np.array_equal(res.lam, lam)
    for k, (primal, lam_change) in got.items():
        assert primal == ref_rows[k]["primal_residual"] and lam_change == ref_rows[k]["lam_change"]
    h = res.history
    assert h["primal_residual"][-1] == ref_rows[-1]["primal_residual"]


def test_a_norm_the_loop_took_counts_only_when_read(vector_problem):
    # the callback reads ||r|| in iterations 0-4 only: the loop takes it with the dual update of iteration 5 too
    # (it expects a read), but a lean history shows a number only where something read it
    res = solve(vector_problem, rho=0.3, stop=RelativeChange(1e-300), max_iter=12,
                callback=lambda rec: rec.k < 5 and rec.primal_residual and None)
    h = res.history["primal_residual"]
    assert not np.isnan(h[:5]).any() and np.isnan(h[5:-1]).all() and not np.isnan(h[-1])


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("c", [0.0, 0.25])
def test_dual_update_and_residual_is_the_plain_update(dtype, c):
    from admmkit.loop.steps import dual_update, dual_update_and_residual
    rng = np.random.default_rng(2)
    lam, Ax, z = (rng.standard_normal(50).astype(dtype) for _ in range(3))
    before = [a.copy() for a in (lam, Ax, z)]
    lam_new, r_norm = dual_update_and_residual(lam, 0.7, Ax, z, c, c == 0.0, lambda r: float(np.linalg.norm(r)))
    assert np.array_equal(lam_new, dual_update(lam, 0.7, Ax, z, c, c == 0.0))
    assert np.array_equal(lam_new, lam + 0.7 * (Ax - z - c)) and lam_new.dtype == (lam + 0.7 * (Ax - z)).dtype
    assert r_norm == float(np.linalg.norm(Ax - z - c))
    assert all(np.array_equal(a, b) for a, b in zip((lam, Ax, z), before))    # the inputs are left alone
