"""Restarted fast ADMM on the QP's compiled path: the segment (OSQP's test and rule in its kernel included) takes the
loop's steps (``admmkit.loop.fast_kernel``) bit for bit."""
import math
from pathlib import Path

import numpy as np
import pytest

from admmkit import kernels
from admmkit.loop.acceleration import Acceleration, FastADMM
from admmkit.loop.fast_kernel import (A, BACKOFF, C, EXTRAPOLATED, FAILED, FOREVER, HAVE_PREV, RESTARTS, SKIP, STREAK,
                                      FastArrays, fast_reads_state, fast_update, fast_update_numpy)
from admmkit.problems.qp import admmkit_settings, load_mat, random_qp, solve_qp
from tests import qp_paths

MM = Path(__file__).resolve().parents[3] / "shared" / "data" / "maros_meszaros"
pytestmark = pytest.mark.skipif(not kernels.AVAILABLE, reason="numba is not installed: no compiled segment")


def three_ways(qp, monkeypatch, settings=None, **changes):
    """Fast ADMM: with OSQP's test in the segment, with it in Python, and the Python loop."""
    return qp_paths.three_ways(qp, monkeypatch, settings, FastADMM, **changes)


@pytest.mark.parametrize("make", [
    lambda: random_qp(40, 60, seed=1),
    lambda: random_qp(30, 50, kind="equality", seed=2),
    lambda: random_qp(25, 40, kind="lp", seed=3),
], ids=["mixed", "equality", "lp"])
@pytest.mark.parametrize("eps", [1e-3, 1e-6])
def test_compiled_is_python_bit_for_bit(make, eps, monkeypatch):
    inside, outside, python = three_ways(make(), monkeypatch, eps_abs=eps, eps_rel=eps)
    qp_paths.same_run(inside, python)
    qp_paths.same_run(outside, python)
    assert python.acceleration["extrapolated"] > 0 and python.acceleration["restarts"] > 0
    assert inside.counters["compiled_iterations"] > inside.iterations / 2     # the segment ran most iterations


def test_the_admmkit_preset_too(monkeypatch):
    """admmkit's preset (a penalty per row, polishing during the run): the segment ends where its rule reads."""
    inside, outside, python = three_ways(random_qp(40, 60, seed=7), monkeypatch, admmkit_settings(),
                                         eps_abs=1e-6, eps_rel=1e-6)
    qp_paths.same_run(inside, python)
    qp_paths.same_run(outside, python)
    assert inside.counters["compiled_iterations"] > 0


def test_fast_runs_in_the_segment_and_keeps_the_test_there():
    """Before the kernel, every iteration of a run with acceleration="fast" ran in Python (no segment, 24 tested
    rows with norms here); now the segment runs them and tests in its kernel."""
    res = solve_qp(random_qp(40, 60, seed=1), acceleration="fast", eps_abs=1e-6, eps_rel=1e-6, compiled=True)
    assert res.termination == "solved" and res.iterations >= 75
    assert res.counters["compiled_iterations"] >= res.iterations - 3
    assert np.isfinite(res.history["primal_residual"]).sum() <= 3


@pytest.mark.skipif(not MM.is_dir(), reason="Maros-Meszaros data not present")
@pytest.mark.parametrize("eps", [1e-3, 1e-6])
def test_hs118_is_python_bit_for_bit(eps, monkeypatch):
    inside, outside, python = three_ways(load_mat(MM / "HS118.mat"), monkeypatch, eps_abs=eps, eps_rel=eps)
    qp_paths.same_run(inside, python)
    qp_paths.same_run(outside, python)
    assert python.acceleration["restarts"] > 0


def test_a_change_of_rho_restarts_it_in_the_segment_too(monkeypatch):
    """A run whose rho changes (OSQP's rule) restarts fast ADMM at each change: with the restart made by the loop
    between segments, the compiled run is the Python one; and :meth:`FastADMM.reset` clears the kernel's state.
    (Without the fallback (A7), whose end of momentum here leaves fewer changes of rho to test.)"""
    inside, outside, python = qp_paths.three_ways(random_qp(40, 60, seed=11), monkeypatch, None,
                                                  lambda: FastADMM(give_up=0), eps_abs=1e-7, eps_rel=1e-7, rho=1e-4)
    assert len(set(python.history["rho"])) >= 4
    qp_paths.same_run(inside, python)
    qp_paths.same_run(outside, python)
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
    bound, free = FastADMM(eta=0.9, patience=3), FastADMM(eta=0.9, patience=3)
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
    assert bound.stats["restarts"] > 0 and bound.stats["extrapolated"] > 0 and bound.stats["rejected"] > 0


@pytest.mark.parametrize("patience, give_up", [(0, 0), (2, 0), (8, 0), (2, 3)])
@pytest.mark.parametrize("m", [0, 1, 9, 300])
def test_the_numpy_twin_is_the_kernel_bit_for_bit(m, patience, give_up):
    """Where kernels run as Python the loop takes ``fast_update_numpy``: the compiled kernel's bits, counts and
    state, restarts and extrapolations both met (and, with a patience, failed phases and their back-offs)."""
    rng = np.random.default_rng(m)
    w, rho = rng.uniform(0.5, 2.0, m), 0.7
    twin, compiled = FastArrays(2 * m, patience, give_up), FastArrays(2 * m, patience, give_up)
    R = np.linalg.qr(rng.standard_normal((m, m)))[0] if m else np.zeros((0, 0))
    s = (rng.standard_normal(m), rng.standard_normal(m))
    for k in range(80):
        f = (0.97 * R @ s[0] + 1e-3 * rng.standard_normal(m), 0.9 * s[1])
        out_twin, out_comp = (np.empty(m), np.empty(m)), (np.empty(m), np.empty(m))
        fast_update_numpy(rho, w, 0.95, *s, *f, *out_twin, *twin.args()[:3])
        with kernels.compiled_code(True):
            fast_update(rho, w, 0.95, *s, *f, *out_comp, *compiled.args()[:3])
        assert all(np.array_equal(a, b) for a, b in zip(out_twin, out_comp))
        assert np.array_equal(twin.ist, compiled.ist) and np.array_equal(twin.ac, compiled.ac)
        assert np.array_equal(twin.f_prev, compiled.f_prev)
        s = out_twin
    if m:
        assert twin.ist[EXTRAPOLATED] > 0 and twin.ist[RESTARTS] > 0
        assert (twin.ist[FAILED] > 0) == (patience > 0)


def test_a_run_with_the_kernels_as_python_is_the_compiled_run(monkeypatch):
    """Kernels as Python (``compiled_now()`` False, as in a process without numba: the loop's steps by the numpy
    twin) against the compiled segment: the same run."""
    from admmkit.loop import fast_kernel
    calls = []
    twin = fast_kernel.fast_update_numpy
    monkeypatch.setattr(fast_kernel, "fast_update_numpy", lambda *a: (calls.append(1), twin(*a))[1])
    qp = random_qp(30, 50, seed=5)
    compiled = solve_qp(qp, acceleration="fast", eps_abs=1e-6, eps_rel=1e-6, compiled=True)
    from admmkit.loop import acceleration
    for module in (kernels, acceleration):
        monkeypatch.setattr(module, "compiled_now", lambda: False)
    python = solve_qp(qp, acceleration="fast", eps_abs=1e-6, eps_rel=1e-6, compiled=False)
    assert len(calls) > python.iterations // 2 > 50              # a step after each iteration but a few
    qp_paths.same_run(compiled, python)


@pytest.mark.parametrize("eta", [0, 1.0, -0.5, 1.5, math.nan, "0.9", None, True])
def test_bad_eta_is_refused(eta):
    with pytest.raises(ValueError, match="eta"):
        FastADMM(eta=eta)


@pytest.mark.parametrize("patience", [-1, 2.0, "8", True, math.inf])
def test_bad_patience_is_refused(patience):
    with pytest.raises(ValueError, match=r"patience .*integer >= 0"):
        FastADMM(patience=patience)


@pytest.mark.parametrize("give_up", [-1, 2.0, "4", True, math.inf])
def test_bad_give_up_is_refused(give_up):
    with pytest.raises(ValueError, match=r"give_up .*integer >= 0"):
        FastADMM(give_up=give_up)


def steps(arrays, states, rho=1.0, eta=0.999):
    """fast_update on a sequence of (s, f) pairs of one-entry states (weight 1): the outputs."""
    outs = []
    for s, f in states:
        out = (np.empty(1), np.empty(1))
        fast_update_numpy(rho, np.ones(1), eta, np.array([s]), np.zeros(1), np.array([f]), np.zeros(1), *out,
                          arrays.ist, arrays.ac, arrays.f_prev)
        outs.append(float(out[0][0]))
    return outs


def test_a_restart_after_a_plain_step_keeps_its_image():
    """c_k >= eta c_{k-1} after a step that was not extrapolated: the run goes on from f_k (before: from f_{k-1},
    which is s_k itself, so the iteration was made twice)."""
    arrays = FastArrays(2, patience=0)
    out = steps(arrays, [(0.0, 1.0), (1.0, 3.0)])     # c_0 = 1, then c_1 = 4: no momentum yet (a_1 gives beta 0)
    assert arrays.ist[RESTARTS] == 1 and arrays.ist[EXTRAPOLATED] == 0
    assert out == [1.0, 3.0]


def test_a_failed_phase_backs_off_doubling_and_a_lasting_one_ends_it():
    """Patience 2: a restart after one extrapolation fails the phase, and the next b steps are plain (s not read:
    NaN there changes nothing), b = 1, 2, 4; a phase of two extrapolations resets b to 1."""
    arrays = FastArrays(2, patience=2)
    x = [0.0]

    def contract(n):           # n steps of f = s + (1 - s) / 2 from the last output: c falls, momentum builds
        for _ in range(n):
            x.append(steps(arrays, [(x[-1], x[-1] + (1 - x[-1]) / 2)])[0])

    def overshoot():           # a step whose residual grows: a restart
        x.append(steps(arrays, [(x[-1], x[-1] + 10.0)])[0])

    def plain(n):              # back-off steps: f itself, s not read
        for k in range(n):
            f = 0.5 + k
            assert steps(arrays, [(math.nan, f)]) == [f]
            x.append(f)

    contract(2)                                   # afresh: a step with beta 0, then one extrapolation
    assert arrays.ist[EXTRAPOLATED] == 1
    for failures, b in enumerate((1, 2, 4), start=1):
        overshoot()
        assert arrays.ist[FAILED] == failures and arrays.ist[SKIP] == b and arrays.ist[HAVE_PREV] == 0
        plain(b)
        assert arrays.ist[SKIP] == 0
        contract(2)                               # afresh again: one extrapolation, short of the patience
    assert arrays.ist[FAILED] == 3 and arrays.ist[BACKOFF] == 8 and arrays.ist[EXTRAPOLATED] == 4
    contract(1)                                   # a second extrapolation: the phase lasted
    overshoot()
    assert arrays.ist[FAILED] == 3 and arrays.ist[SKIP] == 0 and arrays.ist[BACKOFF] == 1


@pytest.mark.skipif(not MM.is_dir(), reason="Maros-Meszaros data not present")
@pytest.mark.parametrize("name", ["HS268", "QADLITTL"])
def test_the_safeguard_solves_what_plain_admm_solves(name):
    """HS268 and QADLITTL at 1e-6 under OSQP's preset: plain ADMM solves them (250, 2300 iterations); fast ADMM
    without the safeguard (before it) stalled at the cap of 4000, and now solves them."""
    qp = load_mat(MM / f"{name}.mat")
    plain = solve_qp(qp, eps_abs=1e-6, eps_rel=1e-6)
    fast = solve_qp(qp, eps_abs=1e-6, eps_rel=1e-6, acceleration="fast")
    assert plain.termination == "solved" and fast.termination == "solved"     # before: max_iter at 4000
    assert fast.acceleration["rejected"] > 0                  # the back-off did the work


@pytest.mark.skipif(not MM.is_dir(), reason="Maros-Meszaros data not present")
def test_the_back_off_runs_in_the_segment_bit_for_bit(monkeypatch):
    """HS268 at 1e-6: failed phases and back-offs met inside the segment (its plain steps read nothing), the same
    run as the Python loop's."""
    inside, outside, python = three_ways(load_mat(MM / "HS268.mat"), monkeypatch, eps_abs=1e-6, eps_rel=1e-6)
    qp_paths.same_run(inside, python)
    qp_paths.same_run(outside, python)
    assert python.acceleration["rejected"] > 0 and python.acceleration["restarts"] > 0


def test_the_give_up_th_short_failed_phase_in_a_row_ends_momentum_for_good():
    """(A7), patience 8, give_up 3: two short failed phases (one extrapolation each) back off (b = 1, 2); a phase of
    five extrapolations fails the patience but is not short, and starts the count again; then three short failed
    phases in a row turn momentum off for good: every later step is f itself and reads no state, across a reset (a
    change of rho) too."""
    arrays = FastArrays(2, patience=8, give_up=3)
    x = [0.0]

    def contract(n, q=2):      # f = s + (1 - s) / q: c falls, momentum builds (q = 4: smoothly enough to last)
        for _ in range(n):
            x.append(steps(arrays, [(x[-1], x[-1] + (1 - x[-1]) / q)])[0])

    def overshoot():
        x.append(steps(arrays, [(x[-1], x[-1] + 10.0)])[0])

    def plain(n):
        for k in range(n):
            assert steps(arrays, [(math.nan, 0.5 + k)]) == [0.5 + k]
            x.append(0.5 + k)

    for b in (1, 2):                              # two short failed phases: back-offs, momentum not yet given up
        contract(2)
        overshoot()
        assert arrays.ist[STREAK] == b and arrays.ist[SKIP] == b
        plain(b)
    done = arrays.ist[EXTRAPOLATED]
    contract(6, q=4)                              # five extrapolations: short of the patience, but not short
    overshoot()
    assert arrays.ist[EXTRAPOLATED] == done + 5
    assert arrays.ist[STREAK] == 0 and arrays.ist[FAILED] == 3 and arrays.ist[SKIP] == 4
    plain(4)
    for failures in (1, 2, 3):
        contract(2)
        overshoot()
        assert arrays.ist[STREAK] == failures
        if failures < 3:
            plain(arrays.ist[SKIP])
    assert arrays.ist[FAILED] == 6 and arrays.ist[SKIP] == FOREVER     # off for good (before: a back-off of 32)
    arrays.reset()
    plain(50)
    assert not fast_reads_state(arrays.ist) and arrays.ist[RESTARTS] == 6


def test_the_unbound_path_gives_up_as_the_kernel():
    """The numpy path (no weights: the problem's inner product) meets (A7) where the kernel does: same counts, the
    same plain steps after it."""
    rng = np.random.default_rng(4)
    m, w, rho = 6, rng.uniform(0.5, 2.0, 6), 0.4
    inner = (lambda a, b: float(np.dot(w * a, b)))
    bound, free = FastADMM(eta=0.9, patience=4, give_up=2), FastADMM(eta=0.9, patience=4, give_up=2)
    Acceleration(bound, "xz", inner, w, m)
    Acceleration(free, "xz", inner)
    s, R = (rng.standard_normal(m), rng.standard_normal(m)), np.linalg.qr(rng.standard_normal((m, m)))[0]
    for k in range(200):
        f = (0.95 * R @ s[0], 0.9 * s[1])
        a, b = bound.propose(s, f, rho, inner), free.propose(s, f, rho, inner)
        assert np.allclose(a[0], b[0], rtol=1e-13, atol=1e-15) and np.allclose(a[1], b[1], rtol=1e-13, atol=1e-15)
        assert bound.stats == free.stats
        s = b
    assert bound.stats["rejected"] == 2 and free._skip > 10 ** 12          # given up after two failed phases
    assert bound.kernel_state()[3].ist[SKIP] > 10 ** 12


@pytest.mark.skipif(not MM.is_dir(), reason="Maros-Meszaros data not present")
def test_qbeaconf_is_solved_as_plain_admm_solves_it(monkeypatch):
    """QBEACONF at 1e-6 under OSQP's preset: plain ADMM solves it in 3450 iterations; fast ADMM with the back-off
    alone failed 13 phases (the last beyond iteration 500), its probes moved rho's path, and it stopped at the cap
    of 4000, ``solved_inaccurate`` (it needed 4025).  The fallback (A7) ends momentum at the fourth failed phase in
    a row: solved, in the segment as in the Python loop."""
    qp = load_mat(MM / "QBEACONF.mat")
    inside, outside, python = three_ways(qp, monkeypatch, eps_abs=1e-6, eps_rel=1e-6)
    qp_paths.same_run(inside, python)
    qp_paths.same_run(outside, python)
    assert python.termination == "solved" and python.iterations < 4000       # before: solved_inaccurate at 4000
    assert python.acceleration["rejected"] == 4
    back_off_alone = solve_qp(qp, eps_abs=1e-6, eps_rel=1e-6, acceleration=FastADMM(give_up=0))
    assert back_off_alone.termination == "solved_inaccurate" and back_off_alone.iterations == 4000
    assert back_off_alone.acceleration["rejected"] == 13
