"""Restarted fast ADMM on the QP's compiled path: the segment (OSQP's test and rule in its kernel included) takes the
loop's steps (``admmkit.loop.fast_kernel``) bit for bit."""
import math
from pathlib import Path

import numpy as np
import pytest

from admmkit import kernels
from admmkit.loop.acceleration import Acceleration, FastADMM
from admmkit.loop.fast_kernel import A, C, HAVE_PREV
from admmkit.problems.qp import admmkit_settings, load_mat, random_qp, solve_qp
from admmkit.problems.qp import segment_checks

MM = Path(__file__).resolve().parents[3] / "shared" / "data" / "maros_meszaros"
pytestmark = pytest.mark.skipif(not kernels.AVAILABLE, reason="numba is not installed: no compiled segment")


def same_run(a, b):
    """Two results with the same iterates, iterations, rho path, factorisations, status and fast ADMM's counts."""
    assert a.status == b.status and a.termination == b.termination
    assert a.iterations == b.iterations and a.rho == b.rho
    assert np.array_equal(a.x, b.x) and np.array_equal(a.y, b.y) and np.array_equal(a.z, b.z)
    assert np.array_equal(a.history["rho"], b.history["rho"])
    assert a.counters["factorizations"] == b.counters["factorizations"]
    assert a.acceleration == b.acceleration


def three_ways(qp, monkeypatch, settings=None, **changes):
    """Fast ADMM: with OSQP's test in the segment, with it in Python, and the Python loop."""
    solve = (lambda **kw: solve_qp(qp, settings, acceleration=FastADMM(), **kw, **changes))
    inside = solve(compiled=True)
    monkeypatch.setattr(segment_checks, "TESTS_IN_KERNEL", False)
    outside = solve(compiled=True)
    monkeypatch.setattr(segment_checks, "TESTS_IN_KERNEL", True)
    return inside, outside, solve(compiled=False)


@pytest.mark.parametrize("make", [
    lambda: random_qp(40, 60, seed=1),
    lambda: random_qp(30, 50, kind="equality", seed=2),
    lambda: random_qp(25, 40, kind="lp", seed=3),
], ids=["mixed", "equality", "lp"])
@pytest.mark.parametrize("eps", [1e-3, 1e-6])
def test_compiled_is_python_bit_for_bit(make, eps, monkeypatch):
    inside, outside, python = three_ways(make(), monkeypatch, eps_abs=eps, eps_rel=eps)
    same_run(inside, python)
    same_run(outside, python)
    assert python.acceleration["extrapolated"] > 0 and python.acceleration["restarts"] > 0
    assert inside.counters["compiled_iterations"] > inside.iterations / 2     # the segment ran most iterations


def test_the_admmkit_preset_too(monkeypatch):
    """admmkit's preset (a penalty per row, polishing during the run): the segment ends where its rule reads."""
    inside, outside, python = three_ways(random_qp(40, 60, seed=7), monkeypatch, admmkit_settings(),
                                         eps_abs=1e-6, eps_rel=1e-6)
    same_run(inside, python)
    same_run(outside, python)
    assert inside.counters["compiled_iterations"] > 0


def test_fast_runs_in_the_segment_and_keeps_the_test_there():
    """Before the kernel, every iteration of a run with acceleration="fast" ran in Python (no segment, 24 tested
    rows with norms here); now the segment runs them and tests in its kernel."""
    res = solve_qp(random_qp(40, 60, seed=1), acceleration="fast", eps_abs=1e-6, eps_rel=1e-6, compiled=True)
    assert res.termination == "solved" and res.iterations >= 300
    assert res.counters["compiled_iterations"] >= res.iterations - 3
    assert np.isfinite(res.history["primal_residual"]).sum() <= 3


@pytest.mark.skipif(not MM.is_dir(), reason="Maros-Meszaros data not present")
@pytest.mark.parametrize("eps", [1e-3, 1e-6])
def test_hs118_is_python_bit_for_bit(eps, monkeypatch):
    inside, outside, python = three_ways(load_mat(MM / "HS118.mat"), monkeypatch, eps_abs=eps, eps_rel=eps)
    same_run(inside, python)
    same_run(outside, python)
    assert python.acceleration["restarts"] > 0


def test_a_change_of_rho_restarts_it_in_the_segment_too(monkeypatch):
    """A run whose rho changes (OSQP's rule) restarts fast ADMM at each change: with the restart made by the loop
    between segments, the compiled run is the Python one; and :meth:`FastADMM.reset` clears the kernel's state."""
    inside, outside, python = three_ways(random_qp(40, 60, seed=11), monkeypatch, eps_abs=1e-7, eps_rel=1e-7,
                                         rho=1e-4)
    assert len(set(python.history["rho"])) >= 4
    same_run(inside, python)
    same_run(outside, python)
    fast = FastADMM()
    Acceleration(fast, "xz", None, np.ones(3), 3)
    fast.propose((np.zeros(3), np.zeros(3)), (np.ones(3), np.ones(3)), 1.0, None)
    fast.propose((np.ones(3), np.ones(3)), (np.full(3, 1.5), np.ones(3)), 1.0, None)
    arrays = fast.kernel_state()[3]
    assert arrays.ist[HAVE_PREV] == 1 and arrays.ac[A] > 1 and math.isfinite(arrays.ac[C])
    fast.reset()
    assert arrays.ist[HAVE_PREV] == 0 and arrays.ac[A] == 1 and arrays.ac[C] == math.inf


def test_the_kernel_is_the_numpy_step_to_rounding():
    """The kernel's steps (a weighted inner product) against the unbound numpy path with the same inner product:
    the same restarts and extrapolations, states equal to rounding."""
    rng = np.random.default_rng(0)
    m, w, rho = 7, rng.uniform(0.5, 2.0, 7), 0.3
    inner = (lambda a, b: float(np.dot(w * a, b)))
    bound, free = FastADMM(eta=0.9), FastADMM(eta=0.9)
    Acceleration(bound, "xz", inner, w, m)
    Acceleration(free, "xz", inner)
    assert bound.kernel_state() is not None and free.kernel_state() is None
    s, R = (rng.standard_normal(m), rng.standard_normal(m)), np.linalg.qr(rng.standard_normal((m, m)))[0]
    for k in range(60):                                     # T(s) = 0.95 R s on u: a rotation, slowly contracting
        f = (0.95 * R @ s[0], 0.9 * s[1])
        a, b = bound.propose(s, f, rho, inner), free.propose(s, f, rho, inner)
        assert np.allclose(a[0], b[0], rtol=1e-13, atol=1e-15) and np.allclose(a[1], b[1], rtol=1e-13, atol=1e-15)
        assert bound.stats == free.stats
        s = b
    assert bound.stats["restarts"] > 0 and bound.stats["extrapolated"] > 0


@pytest.mark.parametrize("eta", [0, 1.0, -0.5, 1.5, math.nan, "0.9", None])
def test_bad_eta_is_refused(eta):
    with pytest.raises(ValueError, match="eta"):
        FastADMM(eta=eta)
