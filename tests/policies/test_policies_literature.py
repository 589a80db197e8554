"""Rules from the literature (Wohlberg, OSQP, AADMM) and the wrappers (summable steps, quantised rho).

Each rule's update logic is checked on hand-made records, including the edge
cases: zero residuals, the first iteration, a long run past the freeze point.
Then every registered rule is run on small problems with known solutions.
"""
import math

import numpy as np
import pytest

import admmkit
from admmkit import policies
from admmkit import IterationRecord, Policy, ResidualTolerance, solve
from admmkit.policies import AADMM, OSQPRule, Quantized, SummableSteps, Wohlberg
from admmkit.policies.aadmm import curvature, hybrid_step

ONE = np.zeros(1)


def record(k=0, rho=1.0, r=1.0, s=1.0, primal_scale=1.0, dual_scale=1.0, order="xz", **vectors):
    """A record with given residuals (absolute, and the scales that normalise them)."""
    v = {"x": ONE, "z": ONE, "lam": ONE, "Ax": ONE}
    v.update(vectors)
    return IterationRecord(
        k=k, rho=rho, order=order, primal_residual=r, dual_residual=s, rho_Ax_change=s, lam_change=rho * r,
        x_change=1.0, x_norm=1.0, z_change=1.0, primal_scale=primal_scale, dual_scale=dual_scale,
        primal_unit=1.0, dual_unit=1.0, time=0.0, **v)


class Wish(Policy):
    """Test double: returns a given sequence of factors times rho_k (or absolute values)."""

    def __init__(self, factors=(), values=()):
        self.factors, self.values = list(factors), list(values)

    def update(self, rec):
        if self.values:
            return self.values.pop(0)
        return rec.rho * self.factors.pop(0) if self.factors else rec.rho


# ---------------------------------------------------------------- Wohlberg
def test_wohlberg_adaptive_factor():
    p = Wohlberg()
    p.reset(1.0)
    assert p.update(record(rho=2.0, r=1.0, s=0.01)) == pytest.approx(20.0)      # tau = sqrt(100)
    assert p.update(record(rho=2.0, r=0.04, s=1.0)) == pytest.approx(0.4)       # tau = sqrt(25)
    assert p.update(record(rho=2.0, r=5.0, s=1.0)) == 2.0                       # within mu = 10
    assert p.update(record(rho=2.0, r=1.0, s=1e-6)) == pytest.approx(200.0)     # sqrt(1e6) capped at 100


def test_wohlberg_uses_the_relative_residuals():
    p = Wohlberg()
    p.reset(1.0)
    # the same absolute residuals, balanced once normalised: no change
    assert p.update(record(r=100.0, s=1.0, primal_scale=100.0, dual_scale=1.0)) == 1.0
    assert p.update(record(r=100.0, s=1.0, primal_scale=1.0, dual_scale=1.0)) == pytest.approx(10.0)


def test_wohlberg_target_ratio_and_period():
    p = Wohlberg(xi=4.0)
    p.reset(1.0)
    assert p.update(record(r=50.0, s=1.0)) == pytest.approx(math.sqrt(50 / 4))  # r > xi mu s = 40
    assert p.update(record(r=30.0, s=1.0)) == 1.0                                # 30 < 40 and s < (mu/xi) r
    assert p.update(record(r=1.0, s=3.0)) == pytest.approx(1 / math.sqrt(12))   # s > (mu/xi) r = 2.5
    q = Wohlberg(period=3)
    q.reset(1.0)
    changed = [k for k in range(9) if q.update(record(k=k, r=1.0, s=1e-3)) != 1.0]
    assert changed == [2, 5, 8]


def test_wohlberg_edge_cases():
    p = Wohlberg()
    p.reset(1.0)
    assert p.update(record(k=0, r=0.0, s=0.0)) == 1.0                 # first iteration, nothing moved
    assert p.update(record(r=1.0, s=0.0)) == pytest.approx(100.0)     # s = 0: tau_max
    assert p.update(record(r=0.0, s=1.0)) == pytest.approx(0.01)
    assert p.update(record(r=1.0, s=1.0, dual_scale=0.0)) == pytest.approx(0.01)  # s_rel = inf
    assert p.update(record(r=math.nan, s=1.0)) == 1.0
    with pytest.raises(ValueError, match="tau_max"):
        Wohlberg(tau_max=0.5)
    with pytest.raises(ValueError, match="period"):
        Wohlberg(period=0)


# ---------------------------------------------------------------- OSQP
def test_osqp_rule_interval_and_tolerance():
    p = OSQPRule()
    p.reset(1.0)
    assert all(p.update(record(k=k, r=1.0, s=1e-4)) == 1.0 for k in range(49))   # only every 50 iterations
    assert p.update(record(k=49, r=1.0, s=1e-4)) == pytest.approx(100.0)          # sqrt(1e4) > 5
    assert p.update(record(k=99, r=4.0, s=1.0)) == 1.0                            # factor 2 < 5: keep
    assert p.update(record(k=99, r=1e-4, s=1.0)) == pytest.approx(0.01)
    assert p.update(record(k=99, r=25.0, s=1.0)) == 1.0                           # exactly 5: keep
    q = OSQPRule(interval=1, tolerance=1.0)
    q.reset(1.0)
    assert q.update(record(k=0, r=4.0, s=1.0)) == pytest.approx(2.0)


def test_osqp_rule_edge_cases():
    p = OSQPRule(interval=1)
    p.reset(1.0)
    assert p.update(record(r=0.0, s=0.0)) == 1.0                                # both floored: ratio 1
    assert p.update(record(r=0.0, s=1.0)) == pytest.approx(1e-5)                # r_rel floored at 1e-10
    assert p.update(record(r=1.0, s=1.0, dual_scale=0.0)) == pytest.approx(1e-5)  # s_rel = inf, capped
    clamped = OSQPRule(interval=1, rho_min=1e-3, rho_max=10.0)
    clamped.reset(1.0)
    assert clamped.update(record(r=1.0, s=1e-8)) == 10.0
    assert clamped.update(record(r=1e-8, s=1.0)) == 1e-3
    own = OSQPRule(interval=1, residuals=lambda rec: (1.0, 1e-2))
    own.reset(1.0)
    assert own.update(record(r=1.0, s=1.0)) == pytest.approx(10.0)
    for bad in (dict(interval=0), dict(tolerance=0.5), dict(rho_min=2.0, rho_max=1.0), dict(residuals=3)):
        with pytest.raises(ValueError):
            OSQPRule(**bad)


# ---------------------------------------------------------------- AADMM
def test_hybrid_step_and_curvature():
    assert hybrid_step(4.0, 3.0) == 3.0                 # 2 mg > sd: minimum gradient
    assert hybrid_step(10.0, 2.0) == 9.0                # sd - mg/2
    dot = lambda a, b: float(np.dot(a, b))  # noqa: E731
    g = np.array([1.0, -2.0, 0.5])
    assert curvature(g, 7.0 * g, dot, 0.2) == pytest.approx(7.0)    # exact linear relation: sd = mg = 7
    assert curvature(g, np.zeros(3), dot, 0.2) is None              # no change
    assert curvature(g, -g, dot, 0.2) is None                       # negative correlation
    assert curvature(np.array([1.0, 0.0]), np.array([1.0, 3.0]), dot, 0.2) == pytest.approx(10 - 0.5)
    assert curvature(np.array([1.0, 0.0]), np.array([1.0, 10.0]), dot, 0.2) is None   # correlation 0.0995


def spectral_record(k, rho, Ax, z, lam_x, lam_z, order="xz"):
    """A record whose lam_x, lam_z are given (z_prev / Ax_prev chosen to produce them)."""
    Ax, z, lam_x, lam_z = (np.asarray(v, dtype=float) for v in (Ax, z, lam_x, lam_z))
    if order == "xz":   # lam = lam_z; lam_x = lam + rho (z - z_prev)
        return record(k=k, rho=rho, order=order, Ax=Ax, z=z, lam=lam_z, x=Ax, z_prev=z - (lam_x - lam_z) / rho)
    # zx: lam = lam_x; lam_z = lam - rho (Ax - Ax_prev)
    return record(k=k, rho=rho, order=order, Ax=Ax, z=z, lam=lam_x, x=Ax, Ax_prev=Ax - (lam_x - lam_z) / rho)


@pytest.mark.parametrize("order", ["xz", "zx"])
def test_spectral_estimate_on_linear_duals(order):
    # dual of f: Dlam_x = a Dh with Dh = -A Dx; dual of g: Dlam_z = b Dz  ->  rho = sqrt(a b)
    a, b = 4.0, 9.0
    p = AADMM()
    p.reset(1.0)
    assert p.update(spectral_record(0, 1.0, [0, 0], [0, 0], [0, 0], [0, 0], order)) == 1.0   # first: record only
    rho = p.update(spectral_record(1, 1.0, [1.0, 0.0], [0.0, 1.0], [-a, 0.0], [0.0, b], order))
    assert rho == pytest.approx(6.0)
    assert p.last == (pytest.approx(a), pytest.approx(b)) and p.updates == 1
    # k = 2: not an update iteration (period 2)
    assert p.update(spectral_record(2, 6.0, [5, 5], [5, 5], [1, 1], [1, 1], order)) == 6.0


def test_spectral_safeguards():
    p = AADMM()
    p.reset(2.0)
    p.update(spectral_record(0, 2.0, [0, 0], [0, 0], [0, 0], [0, 0]))
    # only g's pair is correlated: rho = beta
    assert p.update(spectral_record(1, 2.0, [1, 0], [0, 1], [0, 5.0], [0, 3.0])) == pytest.approx(3.0)
    # nothing moved since the last update: keep rho
    assert p.update(spectral_record(3, 3.0, [1, 0], [0, 1], [0, 5.0], [0, 3.0])) == 3.0
    # both pairs anti-correlated: keep rho
    assert p.update(spectral_record(5, 3.0, [2, 0], [0, 2], [1.0, 5.0], [0, 2.0])) == 3.0


def test_spectral_freezes_after_a_fixed_number_of_iterations():
    p = AADMM(freeze=1000)
    p.reset(1.0)
    rho, changes = 1.0, []
    for k in range(1500):   # a long run: each update sees a new curvature
        t = float(k + 1)
        c = 2.0 + math.sin(k)
        new = p.update(spectral_record(k, rho, [t, 0], [0, t], [-c * t, 0], [0, c * t]))
        if new != rho:
            changes.append(k)
        rho = new
    assert changes and max(changes) < 1000 and min(changes) >= 1
    assert all(k % 2 == 1 for k in changes)
    never = AADMM(freeze=None)
    never.reset(1.0)
    never.update(spectral_record(0, 1.0, [0, 0], [0, 0], [0, 0], [0, 0]))
    assert never.update(spectral_record(5001, 1.0, [1, 0], [0, 1], [-4, 0], [0, 9])) == pytest.approx(6.0)
    with pytest.raises(ValueError, match="eps_cor"):
        AADMM(eps_cor=1.5)


# ---------------------------------------------------------------- wrappers
def test_summable_steps_clips_to_the_paper_schedule():
    p = SummableSteps(Wish(factors=[100.0] * 6 + [1.0, 0.01]), tau=2.0, c_max=3)
    p.reset(1.0)
    rho, ratios = 1.0, []
    for k in range(8):
        new = p.update(record(k=k, rho=rho))
        ratios.append(new / rho)
        rho = new
    # s = tau for the first c_max changes, then 1/(c - c_max)^2; an unchanged wish is not a change
    assert ratios == pytest.approx([3, 3, 3, 2, 1.25, 1 + 1 / 9, 1, 1 / (1 + 1 / 16)])
    assert p.changes == 7 and p.clipped == 7
    assert p.s_sum == pytest.approx(6 + 1 + 1 / 4 + 1 / 9 + 1 / 16)


def test_summable_steps_keeps_rho_within_the_bound():
    rng = np.random.default_rng(1)
    p = SummableSteps(Wish(factors=list(10.0 ** rng.uniform(-3, 3, 3000))), tau=1.0, c_max=5)
    p.reset(1.0)
    rho, lo, hi = 1.0, 1.0, 1.0
    for k in range(3000):
        rho = p.update(record(k=k, rho=rho))
        lo, hi = min(lo, rho), max(hi, rho)
    assert 1 / p.bound <= lo and hi <= p.bound
    assert p.s_sum <= 1.0 * 5 + math.pi ** 2 / 6


def test_summable_steps_wraps_names_and_inherits_requires():
    assert SummableSteps().requires == ("dual_residual",)          # default inner: Wohlberg
    assert SummableSteps("aadmm").requires == ()
    assert isinstance(SummableSteps("osqp").inner, OSQPRule)
    with pytest.raises(ValueError, match="inner"):
        SummableSteps(inner=3)
    with pytest.raises(ValueError, match="unknown policy"):
        SummableSteps(inner="nope")
    p = SummableSteps(Wish(factors=[1.0]))
    p.reset(1.0)
    assert p.update(record(rho=1.0)) == 1.0 and p.changes == 0      # an unchanged rho is not a change


def test_quantized_snaps_to_the_grid_and_returns_exact_values():
    p = Quantized(Wish(values=[3.7, 4.1, 3.9, 1.2, 0.05, 3.0]), per_decade=2)
    p.reset(1.0)
    grid = 10 ** 0.5
    out = []
    rho = 1.0
    for k in range(6):
        rho = p.update(record(k=k, rho=rho))
        out.append(rho)
    assert out[:3] == [grid, grid, grid]            # 3.7, 4.1, 3.9 all snap to 10^(1/2): one value
    assert out[3] == 1.0                            # 1.2: back to rho_0 exactly
    assert out[4] == pytest.approx(10 ** -1.5)      # 0.05 -> log10 = -1.3 -> j = -3
    assert out[5] == out[0]                         # the same float: a cache hit
    assert p.levels == {0, 1, -3}
    q = Quantized(Wish(factors=[1.5]))
    q.reset(2.0)
    assert q.update(record(rho=2.0)) == 2.0         # a small wish stays on rho_k
    assert Quantized().requires == () and Quantized("wohlberg").requires == ("dual_residual",)
    with pytest.raises(ValueError, match="per_decade"):
        Quantized(per_decade=0)


def test_quantized_reuses_factorisations_on_a_qp():
    from admmkit.problems.qp import random_qp
    runs = {}
    for name in ("aadmm", "quantized"):
        qp = random_qp(40, 60, kind="mixed", seed=4)
        res = solve(qp, rho=0.1, policy=name, order="xz", stop=ResidualTolerance(1e-8, 1e-8), max_iter=5000)
        assert res.converged
        distinct = len(set(res.history["rho"]))
        assert res.factorizations == distinct           # one factorisation per rho value, reused on return
        runs[name] = res
    assert runs["quantized"].factorizations < runs["aadmm"].factorizations


# ---------------------------------------------------------------- the record's multipliers and the loop
@pytest.mark.parametrize("order", ["xz", "zx"])
def test_lam_x_and_lam_z_satisfy_the_block_optimality_conditions(vector_problem, order):
    p = vector_problem
    recs = []
    solve(p, rho=0.7, order=order, policy="wohlberg", max_iter=8, stop=ResidualTolerance(1e-300, 1e-300),
          callback=recs.append)
    for rec in recs:
        # x-step: D x - b + M lam_x = 0 (A = I);  z-step: z <= g, M lam_z >= 0, lam_z (g - z) = 0
        assert np.allclose(p.d * rec.x - p.b + p.m * rec.lam_x, 0.0, atol=1e-12)
        assert np.all(rec.lam_z >= -1e-12) and np.allclose(rec.lam_z * (p.g - rec.z), 0.0, atol=1e-12)
        assert rec.dot(rec.z, rec.z) == pytest.approx(float(np.sum(p.m * rec.z ** 2)))


NEW = ["wohlberg", "osqp", "aadmm", "summable_steps", "quantized"]


@pytest.mark.parametrize("order", ["xz", "zx"])
@pytest.mark.parametrize("name", NEW)
def test_every_new_rule_converges_to_the_exact_solution(vector_problem, name, order):
    for rho in (1e-3, 1e3):
        res = solve(vector_problem, rho=rho, order=order, policy=name, stop=ResidualTolerance(1e-11, 1e-11))
        x, lam = vector_problem.solution()
        assert res.converged, (name, order, rho, res.message)
        assert np.allclose(res.x, x, atol=1e-8) and np.allclose(res.lam, lam, atol=1e-6)


def test_rules_register_and_declare_what_they_need():
    names = admmkit.policy_names()
    assert set(NEW) <= set(names)
    for name in names:   # every registered rule builds with its defaults
        assert isinstance(admmkit.make_policy(name), Policy)

    class NoAdjoint(admmkit.Problem):
        n = 1

        def x_step(self, z, lam, rho, x):
            return (4.0 - lam + rho * z) / (2.0 + rho)

        def z_step(self, Ax, lam, rho, z):
            return np.minimum(1.0, Ax + lam / rho)

        def apply_A(self, x):
            return x.copy()

    for name in ("wohlberg", "osqp", "summable_steps"):
        with pytest.raises(ValueError, match="adjoint_norm"):
            solve(NoAdjoint(), policy=name, order="xz")
    for name in ("aadmm", "quantized"):   # no dual residual needed: both orders run
        res = solve(NoAdjoint(), policy=name, order="xz", stop=admmkit.RelativeChange(1e-12))
        assert res.converged and res.x[0] == pytest.approx(1.0)


def test_rules_on_the_obstacle_plug_in():
    from admmkit.problems.obstacle import make_problem
    from admmkit.problems.obstacle.scene import radial
    problem = make_problem(radial(h=1 / 4))
    for name in NEW:
        res = solve(problem, rho=1e2, policy=name, order="zx", stop=ResidualTolerance(1e-9, 1e-9), max_iter=5000)
        assert res.converged and res.kkt["sign"] < 1e-6, name
