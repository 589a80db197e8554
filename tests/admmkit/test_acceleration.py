"""Acceleration as a loop option: Anderson (safeguarded, type II) and restarted fast ADMM."""
import math

import numpy as np
import pytest

import admmkit
from admmkit.loop.acceleration import Anderson, FastADMM, make_accelerator, w_inner
from tests.conftest import anderson_inner


def lasso(seed=0, m=40, n=90):
    """A small LASSO from the building blocks (the tutorial's kind) and its solution to 1e-12."""
    rng = np.random.default_rng(seed)
    truth = np.zeros(n)
    truth[rng.choice(n, 5, replace=False)] = rng.choice([-2.0, 2.0], 5)
    D = rng.standard_normal((m, n)) / np.sqrt(m)
    b = D @ truth + 0.05 * rng.standard_normal(m)
    mu = 0.1 * np.abs(D.T @ b).max()
    return admmkit.SplitProblem(admmkit.QuadraticXStep(D.T @ D, -D.T @ b), admmkit.blocks.prox.L1(mu))


TIGHT = admmkit.ResidualTolerance(1e-10, 1e-10)


@pytest.fixture(scope="module")
def reference():
    problem = lasso()
    res = admmkit.solve(problem, rho=1.0, policy="summable", order="zx", stop=TIGHT, max_iter=50_000)
    assert res.converged
    return res


@pytest.mark.parametrize("acceleration", ["anderson", "fast"])
@pytest.mark.parametrize("order", ["xz", "zx"])
@pytest.mark.parametrize("policy", [None, "summable", "osqp"])
def test_accelerated_runs_reach_the_plain_solution(acceleration, order, policy, reference):
    res = admmkit.solve(lasso(), rho=1e2, policy=policy, order=order, acceleration=acceleration,
                        stop=admmkit.ResidualTolerance(1e-9, 1e-9), max_iter=20_000)
    assert res.status is admmkit.Status.CONVERGED
    assert np.linalg.norm(res.z - reference.z) <= 1e-6 * np.linalg.norm(reference.z)
    assert res.acceleration["accelerator"].startswith(("Anderson", "FastADMM"))


@pytest.mark.parametrize("acceleration", [Anderson(m=5), FastADMM()])
@pytest.mark.parametrize("order", ["xz", "zx"])
def test_a_fixed_point_of_admm_is_a_fixed_point_of_the_accelerated_map(acceleration, order, reference):
    """Started at the solution, the accelerated iterates stay there (to round-off)."""
    res = admmkit.solve(lasso(), rho=reference.rho, order=order, acceleration=acceleration,
                        x0=reference.x_iterate, z0=reference.z, lam0=reference.lam,
                        stop=admmkit.ResidualTolerance(1e-300, 0.0), max_iter=30)
    assert np.linalg.norm(res.z - reference.z) <= 1e-8 * np.linalg.norm(reference.z)
    assert np.linalg.norm(res.lam - reference.lam) <= 1e-8 * np.linalg.norm(reference.lam)


class LoggedAnderson(Anderson):
    """Anderson that notes, at every call, the residual at the state it is given and what it returned."""

    def start(self):
        super().start()
        self.log = []          # (||g||_W at s, whether s was an extrapolation, rejected here)

    def propose(self, s, f, rho, inner):
        g = (f[0] - s[0], f[1] - s[1])
        extrapolated_before = self._fallback is not None
        rejected_before = self.stats["rejected"]
        out = super().propose(s, f, rho, inner)
        self.log.append((math.sqrt(w_inner(g, g, rho, inner)), extrapolated_before,
                         self.stats["rejected"] > rejected_before))
        return out


@pytest.mark.parametrize("order", ["xz", "zx"])
def test_the_safeguard_never_lets_the_residual_grow(order):
    """Every extrapolated state the run goes on from has a residual <= the one before it (safeguard 1)."""
    accel = LoggedAnderson(m=8, safeguard=1.0)
    admmkit.solve(lasso(seed=3), rho=1e-2, order=order, acceleration=accel, stop=TIGHT, max_iter=3000)
    kept = [(g, prev) for (g, extrapolated, rejected), (prev, _, _) in zip(accel.log[1:], accel.log)
            if extrapolated and not rejected]
    assert kept and all(g <= prev for g, prev in kept)
    rejected = [g > prev for (g, extrapolated, rejected), (prev, _, _) in zip(accel.log[1:], accel.log) if rejected]
    assert all(rejected)            # a state is rejected only when its residual grew


def test_anderson_cuts_the_iterations_at_a_poor_fixed_rho():
    plain = admmkit.solve(lasso(), rho=1e-2, order="zx", stop=TIGHT, max_iter=50_000)
    fast = admmkit.solve(lasso(), rho=1e-2, order="zx", stop=TIGHT, max_iter=50_000, acceleration="anderson")
    assert plain.converged and fast.converged
    assert fast.iterations < plain.iterations / 3


def test_off_is_plain_admm_bit_for_bit():
    a = admmkit.solve(lasso(), rho=3.0, policy="summable", order="zx", max_iter=200)
    b = admmkit.solve(lasso(), rho=3.0, policy="summable", order="zx", max_iter=200, acceleration=None)
    assert a.iterations == b.iterations and np.array_equal(a.x, b.x) and np.array_equal(a.lam, b.lam)
    assert a.acceleration is None


def test_a_change_of_rho_resets_the_accelerator():
    class Halve(admmkit.Policy):
        def update(self, rec):
            return rec.rho / 2 if rec.k == 10 else rec.rho

    accel = Anderson(m=5)
    resets = []
    original = accel.reset
    accel.reset = lambda: (resets.append(True), original())[1]
    admmkit.solve(lasso(), rho=8.0, policy=Halve(), acceleration=accel, max_iter=30)
    # the start of the run, the change at iteration 10 and every rejection of the safeguard
    assert len(resets) == 2 + accel.stats["rejected"]


@pytest.mark.parametrize("bad,match", [("nesterov", "acceleration"), (3, "acceleration")])
def test_bad_acceleration_is_named(bad, match):
    with pytest.raises(ValueError, match=match):
        admmkit.solve(lasso(), acceleration=bad, max_iter=5)


@pytest.mark.parametrize("make,match", [(lambda: Anderson(m=0), "m"), (lambda: Anderson(safeguard=0.5), "safeguard"),
                                        (lambda: FastADMM(eta=1.0), "eta")])
def test_bad_accelerator_parameters_are_named(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_names_make_accelerators():
    assert isinstance(make_accelerator("Anderson"), Anderson)
    assert isinstance(make_accelerator("fast"), FastADMM)
    assert make_accelerator(None) is None


def test_anderson_backs_off_after_rejections():
    """After a rejection the next b proposals are plain, b doubling with each rejection (issue #50's safeguard); a
    step after every iteration (interval 1), so that every call is a proposal."""
    a = Anderson(m=2, interval=1)
    a.start()
    inner = lambda u, v: float(np.dot(u, v))
    one = np.ones(3)
    a.propose((0 * one, 0 * one), (one, one), 1.0, inner)
    a._skip, a._backoff = 0, 4
    a._fallback = ((one, one), 0.0)                   # pretend s was extrapolated with a residual of 0 before it
    plain = a.propose((one, one), (2 * one, 2 * one), 1.0, inner)
    assert a.stats["rejected"] == 1 and plain[0] is one
    assert a._skip == 4 and a._backoff == 8
    for k in range(5):        # memory gathers (none at the first), but the four that could extrapolate are plain
        s = (k * one, k * one)
        f = ((k + 1) * one, (k + 1) * one + k * k)
        assert a.propose(s, f, 1.0, inner) is f
    assert a._skip == 0 and a.stats["extrapolated"] == 0
    f = (6 * one, 7 * one + 30)
    assert a.propose((5 * one, 5 * one + 16), f, 1.0, inner) is not f      # then it extrapolates again
    assert a.stats["extrapolated"] == 1


@pytest.mark.parametrize("compiled", [False, True])
def test_the_fused_gram_pass_is_the_weighted_inner_product_bit_for_bit(compiled):
    """_gram_row_and_rhs advances the 4 count sums side by side (over the contiguous rows of dG, stored (n, mem)); each
    must be the loop of its own sum, bit for bit (so the compiled segment's Anderson steps stay the Python path's)."""
    from admmkit.kernels import AVAILABLE, compiled_code
    from admmkit.loop.anderson_kernel import _gram_row_and_rhs
    if compiled and not AVAILABLE:
        pytest.skip("numba not installed")
    rng = np.random.default_rng(7)
    m, mem, rho = 37, 6, 0.37
    w, dG, g = rng.uniform(0.1, 3, m), rng.standard_normal((2 * m, mem)), rng.standard_normal(2 * m)

    def inner(a, b):
        return anderson_inner(w, rho, a, b)

    for p, count, extrapolate in ((2, 5, True), (0, 1, True), (4, 6, False), (-1, 3, True)):
        gram, rhs, acc = np.full((mem, mem), np.nan), np.full(mem, np.nan), np.zeros((4, mem))
        with compiled_code(compiled):
            _gram_row_and_rhs(w, rho, dG, g, p, count, extrapolate, gram, rhs, acc)
        for q in range(count):
            if p >= 0:
                assert gram[p, q] == gram[q, p] == inner(dG[:, p], dG[:, q])
            assert (rhs[q] == inner(dG[:, q], g)) if extrapolate else np.isnan(rhs[q])
        assert np.isnan(gram[:, count:]).all() and (p >= 0 or np.isnan(gram).all())


def test_fast_admm_keeps_its_momentum_where_it_pays():
    """LASSO at a poor fixed rho: momentum phases of 5-13 extrapolations fail the patience of 16 (12 back-offs) but
    cut the iterations 7-fold; the global fallback (A7) counts only short failed phases (fewer than 4
    extrapolations), so it keeps them (counting every failed phase in a row, it gave up: 5116 iterations)."""
    plain = admmkit.solve(lasso(), rho=100.0, order="zx", stop=TIGHT, max_iter=50_000)
    fast = admmkit.solve(lasso(), rho=100.0, order="zx", stop=TIGHT, max_iter=50_000, acceleration=FastADMM())
    assert plain.converged and fast.converged and fast.acceleration["rejected"] > 4
    assert fast.iterations < plain.iterations / 5            # 717 against 5211
