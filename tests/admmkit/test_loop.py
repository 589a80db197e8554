"""The ADMM loop: iterates computed by hand, residual definitions, statuses, history."""
import math
import subprocess
import sys

import numpy as np
import pytest

import admmkit
from admmkit import policies
from admmkit import RelativeChange, ResidualTolerance, Status, solve


def iterates(problem, order, n_iter, rho=1.0):
    seen = []
    solve(problem, rho=rho, order=order, max_iter=n_iter, stop=ResidualTolerance(1e-300, 1e-300),
          callback=lambda rec: seen.append((rec.x.copy(), rec.z.copy(), rec.lam.copy())))
    return seen


def test_order_xz_matches_hand_computation(scalar_problem):
    # x1 = (4 - 0 + 0)/3, z1 = min(1, x1), lam1 = x1 - z1; then again
    it = iterates(scalar_problem, "xz", 2)
    assert it[0][0][0] == pytest.approx(4 / 3) and it[0][1][0] == 1 and it[0][2][0] == pytest.approx(1 / 3)
    assert it[1][0][0] == pytest.approx(14 / 9) and it[1][1][0] == 1 and it[1][2][0] == pytest.approx(8 / 9)


def test_order_zx_matches_hand_computation(scalar_problem):
    # paper's ADMM2: p1 = min(g, u0 + lam0/rho) = 0, u1 = (4 + rho p1 - lam0)/3, lam1 = u1 - p1
    it = iterates(scalar_problem, "zx", 2)
    assert it[0][1][0] == 0 and it[0][0][0] == pytest.approx(4 / 3) and it[0][2][0] == pytest.approx(4 / 3)
    assert it[1][1][0] == 1 and it[1][0][0] == pytest.approx(11 / 9) and it[1][2][0] == pytest.approx(14 / 9)


@pytest.mark.parametrize("order", ["xz", "zx"])
def test_residuals_follow_their_definitions(vector_problem, order):
    p = vector_problem
    recs = []
    solve(p, rho=0.7, order=order, max_iter=5, stop=ResidualTolerance(1e-300, 1e-300), callback=recs.append)
    M = lambda v: math.sqrt(np.sum(p.m * v * v))
    for prev, rec in zip(recs, recs[1:]):
        r = rec.Ax - rec.z
        assert rec.primal_residual == pytest.approx(M(r))
        assert rec.lam_change == pytest.approx(M(rec.lam - prev.lam))
        assert rec.rho_Ax_change == pytest.approx(0.7 * M(rec.Ax - prev.Ax))
        assert rec.x_change == pytest.approx(np.linalg.norm(rec.x - prev.x))
        if order == "xz":
            assert rec.dual_residual == pytest.approx(0.7 * np.linalg.norm(p.m * (rec.z - prev.z)))
            assert rec.dual_scale == pytest.approx(np.linalg.norm(p.m * rec.lam))
        else:
            assert rec.dual_residual == rec.rho_Ax_change
            assert rec.dual_scale == pytest.approx(M(rec.lam))
        assert rec.primal_unit == pytest.approx(math.sqrt(p.m.sum()))


@pytest.mark.parametrize("order", ["xz", "zx"])
@pytest.mark.parametrize("policy", ["fixed", "residual_balancing", "summable"])
def test_converges_to_the_exact_solution(vector_problem, order, policy):
    res = solve(vector_problem, rho=1.0, order=order, policy=policy, stop=ResidualTolerance(1e-12, 1e-12))
    x, lam = vector_problem.solution()
    assert res.status is Status.CONVERGED and res.converged
    assert np.allclose(res.x, x, atol=1e-9) and np.allclose(res.lam, lam, atol=1e-8)


def test_papers_relative_change_rule(scalar_problem):
    # the paper's rule, passed explicitly (it was the default until issue #14)
    res = solve(scalar_problem, rho=1.0, stop=RelativeChange(1e-5))
    assert res.stopped_by == "relative_change(tol=1e-05)"
    h = res.history
    assert h["x_change"][-1] <= 1e-5 * h["x_norm"][-1]
    assert np.all(h["x_change"][:-1] > 1e-5 * h["x_norm"][:-1])


def test_default_stop_is_boyds_residuals(scalar_problem):
    res = solve(scalar_problem, rho=1.0)
    assert res.stopped_by == "residual(eps_abs=1e-06, eps_rel=1e-05)" and res.status is Status.CONVERGED
    h = res.history
    assert h["primal_residual"][-1] <= 1e-6 * h["primal_unit"][-1] + 1e-5 * h["primal_scale"][-1]


def test_composed_rules_report_which_fired(vector_problem):
    rule = ResidualTolerance(1e-3, 0) | RelativeChange(1e-14)
    res = solve(vector_problem, rho=1.0, stop=rule)
    assert res.stopped_by.startswith("residual(")
    both = ResidualTolerance(1e-3, 0) & RelativeChange(1e-3)
    res2 = solve(vector_problem, rho=1.0, stop=both)
    assert res2.stopped_by == both.name
    last = res2.history
    assert last["rel_change"][-1] <= 1e-3 and last["primal_residual"][-1] <= 1e-3 * last["primal_unit"][-1]


def test_max_iter_status(vector_problem):
    res = solve(vector_problem, rho=1.0, max_iter=3, stop=ResidualTolerance(1e-14, 0))
    assert res.status is Status.MAX_ITER and res.iterations == 3 and res.stopped_by is None


def test_relative_change_can_fire_far_from_the_solution(vector_problem):
    # with a tiny rho x barely moves: the paper's rule fires although x is wrong;
    # this is why results carry the true KKT residuals of the plug-in
    # -- and the result says so: the KKT check turns it into converged_inaccurate
    res = solve(vector_problem, rho=1e-6, stop=RelativeChange(1e-5))
    x, _ = vector_problem.solution()
    assert res.stopped_by and np.linalg.norm(res.x - x) > 0.1 * np.linalg.norm(x)
    assert res.status is Status.CONVERGED_INACCURATE and not res.converged
    assert max(res.accuracy.values()) > 10 * 1e-5


def test_callback_can_stop(vector_problem):
    res = solve(vector_problem, callback=lambda rec: rec.k == 4)
    assert res.status is Status.STOPPED and res.iterations == 5


def test_history_columns_and_csv(vector_problem, tmp_path):
    res = solve(vector_problem, rho=100.0, policy="summable", order="zx")
    d = res.history.as_dict()
    assert len(d["k"]) == res.iterations and list(d["k"]) == list(range(res.iterations))
    # rho_next of one row is the rho of the next row
    assert np.array_equal(d["rho_next"][:-1], d["rho"][1:])
    assert d["rho_changed"].sum() == res.rho_changes > 0
    path = res.history.to_csv(tmp_path / "h.csv")
    rows = path.read_text().splitlines()
    assert rows[0].split(",")[:3] == ["k", "rho", "order"] or rows[0].startswith("k,rho")
    assert len(rows) == res.iterations + 1
    with pytest.raises(KeyError, match="unknown history column"):
        res.history["nope"]


class Exploding(admmkit.Problem):
    """x-step returns inf after two iterations."""

    n = 2

    def x_step(self, z, lam, rho, x):
        return x + 1 if x[0] < 2 else np.full(2, np.inf)

    def z_step(self, Ax, lam, rho, z):
        return Ax

    def apply_A(self, x):
        return x.copy()


def test_non_finite_iterates_give_diverged():
    # order zx: Exploding has no adjoint_norm, so order xz would refuse ResidualTolerance at the start
    res = solve(Exploding(), max_iter=50, order="zx", stop=ResidualTolerance(1e-300, 1e-300))
    assert res.status is Status.DIVERGED and "non-finite" in res.message


def test_a_rule_needing_the_adjoint_is_refused_at_the_start():
    with pytest.raises(ValueError, match=r"implement Exploding.adjoint_norm\(y\) to return"):
        solve(Exploding(), order="xz")                     # the default stop reads the dual residual
    with pytest.raises(ValueError, match="policy .* needs Boyd.s dual residual"):
        solve(Exploding(), order="xz", policy="residual_balancing", stop=RelativeChange(1e-5))


def test_a_policy_returning_zero_is_refused_naming_it(vector_problem):
    class Zero(admmkit.Policy):
        def update(self, rec):
            return 0.0

    with pytest.raises(ValueError, match=r"policy Zero.update\(\) returned rho = 0.0 at iteration 1"):
        solve(vector_problem, policy=Zero())


def test_timings_and_result_summary(vector_problem):
    res = solve(vector_problem, policy="summable", order="zx")
    assert set(res.timings) == {"x_step", "z_step", "policy", "residuals", "total", "rho_update"}
    assert res.timings["total"] >= res.timings["x_step"] + res.timings["z_step"]
    assert "status       converged" in res.summary()


def test_core_imports_no_plugins():
    code = "import sys, admmkit; print(any(m.split('.')[0] in ('policies', 'problems') for m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


class _Verdict(admmkit.StoppingRule):
    """Fires at iteration ``at`` with a Stop of ``status`` and a certificate (a rule with its own verdict)."""

    def __init__(self, at, status):
        self.at, self.status, self.name = at, status, f"verdict({status})"

    def fired(self, rec):
        if rec.k + 1 < self.at:
            return None
        return admmkit.Stop(self.name, self.status, certificate=np.arange(3.0))


@pytest.mark.parametrize("status, objective", [("primal_infeasible", math.inf), ("dual_infeasible", -math.inf)])
def test_a_stop_ends_the_run_with_its_status_and_certificate(vector_problem, status, objective):
    res = solve(vector_problem, rho=1.0, stop=_Verdict(7, status), max_iter=100)
    assert res.status is Status(status) and res.iterations == 7 and not res.converged
    assert res.stopped_by == f"verdict({status})" and res.message.startswith(f"verdict({status}) fired")
    assert np.array_equal(res.certificate, np.arange(3.0)) and res.objective == objective
    assert res.accuracy is None                              # no KKT check of an infeasibility verdict
    # composed: | passes the first verdict on, & gives the Stop when every rule fires
    res = solve(vector_problem, rho=1.0, stop=_Verdict(5, status) | ResidualTolerance(1e-300, 1e-300), max_iter=100)
    assert res.status is Status(status) and res.iterations == 5
    res = solve(vector_problem, rho=1.0, stop=RelativeChange(1e3) & _Verdict(4, status), max_iter=100)
    assert res.status is Status(status) and res.iterations == 4 and res.certificate is not None
    plain = solve(vector_problem, rho=1.0, stop=RelativeChange(1e3), max_iter=100)
    assert plain.certificate is None and plain.status in (Status.CONVERGED, Status.CONVERGED_INACCURATE)
    with pytest.raises(ValueError):
        admmkit.Stop("x", "not_a_status")
