"""The QP's compiled segment (issue #25): the iterations between checks in one numba call, bit for bit the Python loop's."""
from pathlib import Path

import numpy as np
import pytest

import admmkit
from admmkit import Policy
from admmkit import kernels
from admmkit.policies import Fixed, OSQPRule, Summable
from admmkit.problems.qp import load_mat, osqp_settings, random_qp, solve_qp
from admmkit.problems.qp.generate import infeasible_qp, unbounded_qp
from admmkit.problems.qp.segment import run_segment
from admmkit.problems.qp.solve import qp_for

MM = Path(__file__).resolve().parents[3] / "shared" / "data" / "maros_meszaros"
pytestmark = pytest.mark.skipif(not kernels.AVAILABLE, reason="numba is not installed: no compiled segment")


def same_run(a, b):
    """Two results with the same iterates, iterations, rho path and status."""
    assert a.status == b.status and a.iterations == b.iterations and a.rho == b.rho
    assert np.array_equal(a.x, b.x) and np.array_equal(a.y, b.y) and np.array_equal(a.z, b.z)
    assert np.array_equal(a.history["rho"], b.history["rho"])
    assert a.termination == b.termination
    assert a.objective == b.objective or (np.isnan(a.objective) and np.isnan(b.objective))


def qdldl_or_skip():
    if "qdldl" not in admmkit.linalg.linsolve.available_backends():
        pytest.skip("the segment reads qdldl's factors; qdldl is not installed")


@pytest.mark.parametrize("make", [
    lambda: random_qp(40, 60, seed=1),
    lambda: random_qp(30, 50, kind="equality", seed=2),
    lambda: random_qp(25, 40, kind="lp", seed=3),
    lambda: infeasible_qp(seed=4),
    lambda: unbounded_qp(seed=5),
], ids=["mixed", "equality", "lp", "infeasible", "unbounded"])
def test_compiled_iterates_are_the_python_ones_bit_for_bit(make):
    qdldl_or_skip()
    qp = make()
    fast, slow = solve_qp(qp, compiled=True), solve_qp(qp, compiled=False)
    same_run(fast, slow)
    assert fast.counters["compiled_iterations"] >= fast.iterations - 2 * (fast.iterations // 25 + 1)
    assert "compiled_iterations" not in slow.counters
    assert fast.counters["solves"] == slow.counters["solves"]      # the segment counts its x-step solves


def test_tight_tolerances_and_no_relaxation_bit_for_bit():
    qdldl_or_skip()
    qp = random_qp(50, 80, seed=7)
    for changes in (dict(eps_abs=1e-9, eps_rel=1e-9), dict(alpha=1.0, relax_x=False), dict(check_every=7)):
        same_run(solve_qp(qp, compiled=True, **changes), solve_qp(qp, compiled=False, **changes))


@pytest.mark.skipif(not MM.is_dir(), reason="Maros-Meszaros data not present")
@pytest.mark.parametrize("name", ["QPCBLEND", "HS21", "DUAL1", "CVXQP1_S", "QSHARE1B", "PRIMAL1"])
def test_maros_meszaros_bit_for_bit(name):
    qdldl_or_skip()
    qp = load_mat(MM / f"{name}.mat")
    same_run(solve_qp(qp, compiled=True), solve_qp(qp, compiled=False))


def test_a_rule_that_reads_every_record_gets_every_record():
    """Each iteration is then a read one: the segment runs it alone and the loop builds its record
    from the segment's numbers (admmkit.loop.segments, read=True); the run is the Python path's, bit for bit."""
    qdldl_or_skip()
    qp = random_qp(30, 40, seed=8)
    fast = solve_qp(qp, policy=Summable(), max_iter=200, compiled=True)
    assert fast.counters["compiled_iterations"] == fast.iterations   # the first too: the QP's steps are trusted
    same_run(fast, solve_qp(qp, policy=Summable(), max_iter=200, compiled=False))


def test_the_read_iteration_from_the_segment_is_the_python_ones():
    """The segment's read iteration: its inputs and relaxed vector as the Python steps compute them."""
    qdldl_or_skip()
    qp = random_qp(20, 30, seed=21)
    run, run6 = qp_for(qp, osqp_settings()), qp_for(qp, osqp_settings())     # each keeps its own relaxed x (Q4)
    run.setup(0.1)
    run6.setup(0.1)
    x, z, lam = np.zeros(run.n), np.zeros(run.m), np.zeros(run.m)
    x1, z1, lam1, Ax1, done, last = run_segment(run, x, z, lam, run.As @ x, 0.1, 1.6, "xz", 7, read=True)
    x6, z6, lam6, Ax6, done6 = run_segment(run6, x, z, lam, run.As @ x, 0.1, 1.6, "xz", 6)
    assert done == 7 and done6 == 6
    x_j, z_j, lam_j, Ax_j, hat = last
    for a, b in ((x_j, x6), (z_j, z6), (lam_j, lam6), (Ax_j, Ax6)):
        assert np.array_equal(a, b)
    assert np.array_equal(hat, 1.6 * Ax1 + (1.0 - 1.6) * z6)


def test_a_callback_or_the_full_history_sees_every_iteration():
    qp = random_qp(30, 40, seed=9)
    seen = []
    res = solve_qp(qp, callback=lambda rec: seen.append(rec.k), compiled=True)
    assert seen == list(range(res.iterations)) and "compiled_iterations" not in res.counters


def test_history_rows_of_a_segment():
    qdldl_or_skip()
    res = solve_qp(random_qp(30, 40, seed=10), eps_abs=1e-8, eps_rel=1e-8, compiled=True)
    h = res.history
    assert len(h) == res.iterations and np.array_equal(h["k"], np.arange(res.iterations))
    assert np.isnan(h["primal_residual"][0]) and np.isfinite(h["primal_residual"][-1])   # unread / the last
    assert np.isnan(h["primal_residual"][24])          # tested in the segment's kernel (segment_checks): no norm
    assert np.all(np.diff(h["time"]) >= 0)


def test_kernel_stops_before_a_non_finite_step():
    qdldl_or_skip()
    run = qp_for(random_qp(20, 30, seed=11), osqp_settings())
    run.setup(0.1)
    x, z, lam = np.zeros(run.n), np.zeros(run.m), np.zeros(run.m)
    z[3] = np.nan
    out = run_segment(run, x, z, lam, run.As @ x, 0.1, 1.6, "xz", 10)
    assert out[-1] == 0 and np.array_equal(out[0], x)


def test_segment_declines_what_it_does_not_compile():
    qp = random_qp(20, 30, seed=12)
    reduced = qp_for(qp, osqp_settings(xstep="reduced"))
    x, z = np.zeros(qp.n), np.zeros(qp.m)
    assert run_segment(reduced, x, z, z, z, 0.1, 1.6, "xz", 10) is None
    assert run_segment(qp_for(qp, osqp_settings()), x, z, z, z, 0.1, 1.6, "zx", 10) is None


def test_policies_say_when_they_read_a_record():
    assert OSQPRule(interval=50).unchanged_until(0) == 49 and OSQPRule(interval=50).unchanged_until(49) == 49
    assert OSQPRule(interval=50).unchanged_until(50) == 99
    assert Fixed().unchanged_until(7) > 10 ** 9

    class EveryIteration(Policy):
        def update(self, rec):
            return rec.rho
    assert EveryIteration().unchanged_until(7) == 7 and Summable().unchanged_until(3) == 3


def test_compiled_must_be_a_bool():
    qp = random_qp(10, 10, seed=13)
    with pytest.raises(TypeError, match="compiled must be True or False"):
        admmkit.solve(qp_for(qp, osqp_settings()), compiled="yes")
    with pytest.raises(ValueError, match="compiled must be 'auto', True or False"):
        osqp_settings(compiled=1)


@pytest.mark.parametrize("settings", [osqp_settings(), osqp_settings(scaling=0, row_weights="uniform")],
                         ids=["scaled", "plain"])
def test_compiled_residuals_are_numpys(settings):
    """OSQP's residuals in one compiled pass: every inf-norm bit for bit, the gap's inner products summed in order
    (as OSQP's C) to round-off of numpy's blockwise BLAS sums; with A x given or computed."""
    from admmkit.problems.qp.residual_kernel import iterate_residuals_compiled
    from admmkit.problems.qp.residuals import iterate_residuals
    qp = qp_for(random_qp(30, 40, seed=14), settings)
    rng = np.random.default_rng(0)
    x, z, lam = rng.standard_normal(qp.n), rng.standard_normal(qp.m), rng.standard_normal(qp.m)
    for Ax in (None, qp.As @ x):
        a, b = iterate_residuals(qp, x, z, lam, Ax, scaled=True), iterate_residuals_compiled(qp, x, z, lam, Ax, True)
        assert a.keys() == b.keys()
        for key in a:
            if key.startswith("gap"):
                assert b[key] == pytest.approx(a[key], rel=1e-12)
            else:
                assert b[key] == a[key], key


def test_a_progress_bar_lets_the_segments_run():
    """The command line's progress bar (every_record = False) is fed the tested iterations; the rest run compiled."""
    qdldl_or_skip()
    from admmkit.cli.output import Progress
    qp = random_qp(30, 40, seed=15)
    with Progress(4000, delay=0.0, interval=0.0, file=open("/dev/null", "w")) as bar:
        watched = solve_qp(qp, callback=bar, compiled=True)
    same_run(watched, solve_qp(qp, compiled=True))
    assert watched.counters["compiled_iterations"] > 0


def test_the_summary_shows_the_compiled_time():
    qdldl_or_skip()
    res = solve_qp(random_qp(30, 40, seed=16), compiled=True)
    time_line = next(line for line in res.summary().splitlines() if line.startswith("time"))
    assert f"compiled segments {res.timings['segments']:.4f}" in time_line
    assert "compiled_iterations" in next(line for line in res.summary().splitlines() if line.startswith("work"))


def test_a_fixed_rho_without_a_policy_runs_in_segments():
    """policy=None keeps rho fixed and reads no record: its iterations between checks are compiled too."""
    from admmkit.problems.qp import random_qp, solve_qp
    qp = random_qp(20, 30, seed=4)
    fast, slow = solve_qp(qp, policy=None, compiled=True), solve_qp(qp, policy=None, compiled=False)
    assert fast.counters.get("compiled_iterations", 0) > 0 and "compiled_iterations" not in slow.counters
    assert fast.iterations == slow.iterations and np.array_equal(fast.x, slow.x)


def test_the_kkt_x_step_reads_z_tilde_off_its_solve(monkeypatch):
    """OSQP's z~ = b_z + R^-1 v (Q6): the KKT form's A x~ comes from the solve, no product with A, on both paths."""
    from admmkit.problems.qp import products
    qp = qp_for(random_qp(20, 30, seed=11), osqp_settings())

    def no_product(*args):
        raise AssertionError("A x computed by a product after a KKT x-step")
    monkeypatch.setattr(products, "apply_A", no_product)
    for flag in (False, True):
        with kernels.compiled_code(flag):
            qp.begin_run()
            rng = np.random.default_rng(0)
            x, z, lam = rng.standard_normal(qp.n), rng.standard_normal(qp.m), rng.standard_normal(qp.m)
            x1 = qp.x_step(z, lam, 0.1, x)
            z_tilde = qp.apply_A(x1)
            # the second block row of the KKT system: A x~ - R^-1 v = z - R^-1 M lam
            assert np.allclose(z_tilde, qp.As @ x1, rtol=1e-8, atol=1e-10)
    monkeypatch.undo()
    assert np.array_equal(qp.apply_A(np.ones(qp.n)), qp.As @ np.ones(qp.n))     # any other x: the product


def test_a_warm_kernel_call_does_not_list_numba_signatures(monkeypatch):
    """A kernel's call asks numba's dispatcher for its compiled overloads, not ``signatures`` (a list of hashed
    types built anew at every call: 0.1 ms, 32 calls in a small QP's solve)."""
    from admmkit.kernels import all_finite
    with kernels.compiled_code(True):
        all_finite(np.ones(3), 0, 3)
        kind = type(all_finite._dispatcher)
        monkeypatch.setattr(kind, "signatures", property(lambda self: pytest.fail("signatures listed")))
        assert all_finite(np.ones(3), 0, 3)


@pytest.mark.parametrize("make", [lambda: random_qp(40, 60, seed=1), lambda: random_qp(25, 40, kind="lp", seed=3)],
                         ids=["mixed", "lp"])
def test_anderson_runs_in_the_segment_bit_for_bit(make):
    """Anderson's steps on the compiled path (issue #50): the segment takes them between its iterations, with the
    loop's kernel, so a run is the Python loop's bit for bit and most of its iterations are compiled."""
    qdldl_or_skip()
    qp = make()
    for eps in (1e-3, 1e-7):
        fast = solve_qp(qp, compiled=True, acceleration="anderson", eps_abs=eps, eps_rel=eps)
        slow = solve_qp(qp, compiled=False, acceleration="anderson", eps_abs=eps, eps_rel=eps)
        same_run(fast, slow)
        assert fast.acceleration == slow.acceleration and fast.acceleration["extrapolated"] > 0
        assert fast.counters["compiled_iterations"] >= fast.iterations - 2 * (fast.iterations // 25 + 1)


@pytest.mark.skipif(not MM.is_dir(), reason="Maros-Meszaros data not present")
@pytest.mark.parametrize("name", ["HS268", "S268"])
def test_anderson_does_not_lose_what_plain_admm_solves(name):
    """HS268 and S268 at 1e-6: plain ADMM solves them in 250 iterations; Anderson stalled at the cap (1310 of 1376
    extrapolations rejected).  The safeguard's back-off now makes it plain ADMM with rare probes: solved, the
    safeguard having fired, on both paths alike."""
    qdldl_or_skip()
    qp = load_mat(MM / f"{name}.mat")
    plain = solve_qp(qp, compiled=True, eps_abs=1e-6, eps_rel=1e-6)
    fast = solve_qp(qp, compiled=True, acceleration="anderson", eps_abs=1e-6, eps_rel=1e-6)
    assert plain.termination == "solved" and fast.termination == "solved"
    assert fast.iterations <= 2 * plain.iterations
    assert fast.acceleration["rejected"] > 0 and fast.acceleration["extrapolated"] > 0
    same_run(fast, solve_qp(qp, compiled=False, acceleration="anderson", eps_abs=1e-6, eps_rel=1e-6))


def test_an_accelerator_without_a_kernel_still_runs_in_python():
    """An accelerator with no kernel state (a user's own) takes its steps in Python only: no segment runs with it.
    (Restarted fast ADMM has one since fast_kernel: tests/problems/test_qp_fast.py.)"""
    from admmkit.loop.acceleration import Accelerator

    class Plain(Accelerator):
        def propose(self, s, f, rho, inner):
            return f

    qdldl_or_skip()
    res = solve_qp(random_qp(20, 30, seed=2), compiled=True, acceleration=Plain())
    assert "compiled_iterations" not in res.counters


def test_z_tilde_is_read_once():
    """The loop asks for A x~ once, right after the x-step; any later A x of the same array (a warm start's x0)
    is the product, as OSQP's warm start computes z = A x."""
    qp = qp_for(random_qp(10, 15, seed=4), osqp_settings())
    qp.begin_run()
    x1 = qp.x_step(np.zeros(qp.m), np.ones(qp.m), 0.1, np.zeros(qp.n))
    first = qp.apply_A(x1)
    assert np.array_equal(qp.apply_A(x1), qp.As @ x1) and first is not None
