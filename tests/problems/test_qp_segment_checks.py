"""OSQP's test and rule inside the compiled segment (admmkit.problems.qp.segment_checks): Python runs only where the
loop must look, and the run is the one without it (iterates, iterations, status, rho path) bit for bit."""
from pathlib import Path

import numpy as np
import pytest

import admmkit
from admmkit import kernels
from admmkit.problems.qp import admmkit_settings, load_mat, random_qp, solve_qp
from admmkit.problems.qp.generate import infeasible_qp, unbounded_qp
from admmkit.problems.qp.termination import QPTermination
from tests.qp_paths import same_run, three_ways

MM = Path(__file__).resolve().parents[3] / "shared" / "data" / "maros_meszaros"
pytestmark = pytest.mark.skipif(
    not kernels.AVAILABLE or "qdldl" not in admmkit.linalg.linsolve.available_backends(),
    reason="the segment needs numba and reads qdldl's factors")


@pytest.mark.parametrize("make", [
    lambda: random_qp(40, 60, seed=1),
    lambda: random_qp(30, 50, kind="equality", seed=2),
    lambda: random_qp(25, 40, kind="lp", seed=3),
    lambda: infeasible_qp(seed=4),
    lambda: unbounded_qp(seed=5),
    lambda: unbounded_qp(seed=6, lp=True),
], ids=["mixed", "equality", "lp", "infeasible", "unbounded", "unbounded-lp"])
@pytest.mark.parametrize("eps", [1e-3, 1e-8])
def test_the_test_in_the_segment_changes_nothing(make, eps, monkeypatch):
    qp = make()
    inside, outside, python = three_ways(qp, monkeypatch, eps_abs=eps, eps_rel=eps)
    same_run(inside, outside)
    same_run(inside, python)


def test_infeasible_problems_are_declared_as_before(monkeypatch):
    """A candidate certificate ends the segment: the loop's Python confirms it (the LP) and declares it."""
    for make, status in ((infeasible_qp, "primal_infeasible"), (unbounded_qp, "dual_infeasible")):
        inside, outside, python = three_ways(make(seed=12), monkeypatch)
        assert inside.termination == status
        same_run(inside, outside)
        same_run(inside, python)


@pytest.mark.parametrize("changes", [dict(alpha=1.0, relax_x=False), dict(check_every=7), dict(check_every=50),
                                     dict(adaptive_rho_interval=30), dict(max_iter=60), dict(time_limit=1e6),
                                     dict(adaptive_rho="kkt_error"), dict(gap=False), dict(infeasibility=False)])
def test_other_settings_change_nothing(changes, monkeypatch):
    qp = random_qp(50, 80, seed=7)
    inside, outside, python = three_ways(qp, monkeypatch, eps_abs=1e-7, eps_rel=1e-7, **changes)
    same_run(inside, outside)
    same_run(inside, python)


def test_admmkits_preset_polishes_as_before(monkeypatch):
    """PolishingTermination's gate ends the segment where a polish may be tried; the polished answer is the same."""
    qp = random_qp(40, 60, seed=13)
    inside, outside, python = three_ways(qp, monkeypatch, admmkit_settings(1e-6, 1e-6))
    for other in (outside, python):
        same_run(inside, other)
        assert inside.polish == other.polish


def test_another_rule_or_fixed_rho(monkeypatch):
    """A rule the kernel does not compute (residual balancing) ends the segment where it reads; no rule at all
    (fixed rho) lets it run to the test that fires."""
    qp = random_qp(40, 60, seed=14)
    for policy in ("residual_balancing", None):
        inside, outside, python = three_ways(qp, monkeypatch, policy=policy, max_iter=500)
        same_run(inside, outside)
        same_run(inside, python)


def test_python_tests_only_where_the_loop_must_look(monkeypatch):
    """With OSQP's test and rule in the segment, the loop's Python tests the iterate only at a change of rho and at
    the end (before: every 25 iterations); the history rows of the iterations tested in the kernel have NaN norms."""
    qp = random_qp(40, 60, kind="equality", seed=3)
    tested = []
    fired = QPTermination.fired

    def counted(self, rec):
        tested.append(rec.k)
        return fired(self, rec)
    monkeypatch.setattr(QPTermination, "fired", counted)
    res = solve_qp(qp, eps_abs=1e-8, eps_rel=1e-8, compiled=True)
    assert res.iterations > 200 and res.status.value == "converged"
    assert len(tested) <= res.rho_changes + 1 and tested[-1] == res.iterations - 1
    h = res.history
    assert np.isnan(h["primal_residual"][24]) and np.isfinite(h["primal_residual"][-1])


def test_a_watcher_of_the_tested_records_still_sees_each(monkeypatch):
    """A callback with every_record = False (a progress bar) is given every tested record: no test in the kernel."""
    qp = random_qp(30, 40, seed=15)
    seen = []

    def watch(rec):
        seen.append(rec.k)
    watch.every_record = False
    res = solve_qp(qp, eps_abs=1e-6, eps_rel=1e-6, callback=watch, compiled=True)
    assert [k for k in seen if (k + 1) % 25 == 0] == list(range(24, res.iterations, 25))


def test_a_callback_content_with_fewer_records_keeps_the_test_in_the_kernel(monkeypatch):
    """A callback with every_tested = False (a deadline, as admmkit bench qp's) is given the records the loop reads
    in Python only, the tests stay in the kernel, and the run is the one without the callback."""
    qp = random_qp(40, 60, kind="equality", seed=3)
    seen = []

    def watch(rec):
        seen.append(rec.k)
    watch.every_record, watch.every_tested = False, False
    plain = solve_qp(qp, eps_abs=1e-8, eps_rel=1e-8, compiled=True)
    res = solve_qp(qp, eps_abs=1e-8, eps_rel=1e-8, callback=watch, compiled=True)
    same_run(res, plain)
    assert res.iterations > 200 and len(seen) <= res.rho_changes + 2 and seen[-1] == res.iterations - 1


@pytest.mark.skipif(not MM.is_dir(), reason="Maros-Meszaros data not present")
@pytest.mark.parametrize("name", ["HS118", "HS21", "QPCBLEND", "DUAL1", "PRIMALC1", "QSHIP04S"])
@pytest.mark.parametrize("eps", [1e-3, 1e-6])
def test_maros_meszaros(name, eps, monkeypatch):
    qp = load_mat(MM / f"{name}.mat")
    inside, outside, python = three_ways(qp, monkeypatch, eps_abs=eps, eps_rel=eps)
    same_run(inside, outside)
    same_run(inside, python)


def test_the_first_iteration_runs_in_the_segment_too(monkeypatch):
    """The QP's steps are trusted (``QP.trusted_steps``): no iteration of a plain solve runs its steps in Python,
    and the run is the Python loop's."""
    from admmkit.problems.qp.problem import QP
    qp = random_qp(30, 40, seed=17)

    def no_python_step(*args):
        raise AssertionError("an x-step ran in Python")
    fast = solve_qp(qp, compiled=True)
    assert fast.counters["compiled_iterations"] == fast.iterations
    monkeypatch.setattr(QP, "x_step", no_python_step)
    again = solve_qp(qp, compiled=True)
    monkeypatch.undo()
    same_run(again, fast)
    same_run(fast, solve_qp(qp, compiled=False))


def test_a_qp_without_constraint_rows(monkeypatch):
    """m = 0: r is empty, the loop's stall test reads x's change, so every test runs in Python; the same run."""
    import scipy.sparse as sp
    from admmkit.problems.qp import QP
    rng = np.random.default_rng(18)
    M = rng.standard_normal((6, 6))
    qp = QP(sp.csc_matrix(M @ M.T + np.eye(6)), rng.standard_normal(6), sp.csc_matrix((0, 6)), np.zeros(0),
            np.zeros(0))
    inside, outside, python = three_ways(qp, monkeypatch, eps_abs=1e-8, eps_rel=1e-8)
    same_run(inside, outside)
    same_run(inside, python)


@pytest.mark.parametrize("seed", [0, 5])
def test_a_per_row_rule_on_uniform_weights_is_tested_with_the_weights_it_set(seed, monkeypatch):
    """With row_weights="uniform" (no w) a per-row rule gives the QP new weights; the segment's in-kernel test must
    read them, not the unit weights it held (it did: 1700 against 1675 iterations on seed 0, a test on the wrong
    inner product), so the run equals the one whose tests all run in Python."""
    from admmkit.problems.qp import admmkit_settings, random_qp, segment_checks
    from admmkit.problems.qp.segment import AVAILABLE
    if not AVAILABLE:
        pytest.skip("numba is not installed: no in-kernel test")
    qp = random_qp(40, 60, seed=seed)
    settings = admmkit_settings(1e-6, 0.0, row_weights="uniform", early_polish=False)
    kernel = solve_qp(qp, settings, compiled=True)
    monkeypatch.setattr(segment_checks, "TESTS_IN_KERNEL", False)
    python = solve_qp(qp, settings, compiled=True)
    assert kernel.iterations == python.iterations and np.array_equal(kernel.x, python.x)
