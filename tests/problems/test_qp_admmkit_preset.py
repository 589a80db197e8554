"""admmkit's QP preset (``admmkit_settings``): polishing during the run, OSQP 1.x's KKT-error rho mode, bad settings."""
import numpy as np
import pytest

from admmkit import Status
from admmkit.problems.qp import QP, admmkit_settings, osqp_settings, solve_qp
from admmkit.problems.qp.residuals import neutral_residuals, neutral_satisfied
from admmkit.problems.qp.settings import ADMMKIT_MAX_ITER


def hs118_like(seed=0, n=15, m=29):
    """A strictly convex box- and row-constrained QP with several active constraints (small: a fast test)."""
    rng = np.random.default_rng(seed)
    B = rng.standard_normal((n, n))
    P = B @ B.T / n + 0.1 * np.eye(n)
    A = np.vstack([np.eye(n), rng.standard_normal((m - n, n))])
    l = np.r_[np.full(n, -0.2), np.full(m - n, -np.inf)]
    u = np.r_[np.full(n, 0.2), rng.uniform(0.0, 0.5, m - n)]
    return QP(P, 3 * rng.standard_normal(n), A, l, u)


def test_admmkit_settings_is_osqps_with_polishing_during_the_run_and_its_own_cap():
    s = admmkit_settings(1e-6, 0.0)
    assert (s.eps_abs, s.eps_rel, s.max_iter, s.early_polish, s.adaptive_rho) == (1e-6, 0.0, ADMMKIT_MAX_ITER, True,
                                                                                  "rowwise")
    o = osqp_settings()
    assert (s.rho, s.sigma, s.alpha, s.scaling, s.check_every) == (o.rho, o.sigma, o.alpha, o.scaling, o.check_every)
    assert admmkit_settings(max_iter=10).max_iter == 10
    with pytest.raises(TypeError, match="unknown QP setting"):
        admmkit_settings(polishh=True)


@pytest.mark.parametrize("eps", [1e-3, 1e-6])
def test_polishing_during_the_run_stops_earlier_and_truthfully(eps):
    qp = hs118_like()
    plain = solve_qp(qp, osqp_settings(eps_abs=eps, eps_rel=0.0, max_iter=20000))
    early = solve_qp(qp, admmkit_settings(eps, 0.0, adaptive_rho="interval"))   # OSQP's rule: polishing is what differs
    assert plain.status is Status.CONVERGED and early.status is Status.CONVERGED
    assert early.iterations < plain.iterations                 # the polished point passed before the iterate did
    assert early.polish["status"] == "succeeded"
    assert neutral_satisfied(neutral_residuals(qp, early.x, early.y), eps)      # no false "converged"
    assert early.residuals["primal"] <= eps and early.residuals["dual"] <= eps and abs(early.residuals["gap"]) <= eps
    assert early.kkt["primal"] <= eps and early.kkt["dual"] <= eps
    assert np.allclose(early.x, plain.x, atol=1e-2)


def test_a_polished_point_that_misses_the_test_does_not_stop_the_run(monkeypatch):
    from admmkit.problems.qp import polish_stop
    tries = []

    def spoilt(qp, *args, **kwargs):                       # polishing, then the point moved off the solution
        x, y, info = polish_stop.__dict__["_polish"](qp, *args, **kwargs)
        tries.append(x is not None)
        return (None if x is None else x + 1e-2), y, info
    monkeypatch.setitem(polish_stop.__dict__, "_polish", polish_stop.polish)
    monkeypatch.setattr(polish_stop, "polish", spoilt)
    qp = hs118_like()
    plain = solve_qp(qp, osqp_settings(eps_abs=1e-6, eps_rel=0.0, max_iter=20000))
    early = solve_qp(qp, admmkit_settings(1e-6, 0.0, adaptive_rho="interval"))
    assert any(tries)                                      # polishing was tried, and refused every time
    assert early.status is Status.CONVERGED and early.polish is None
    assert early.iterations == plain.iterations and np.array_equal(early.x, plain.x)


@pytest.mark.parametrize("backoff", [1.0, 2.0, 3.0])
def test_each_failed_polishing_try_multiplies_the_wait_for_the_next(monkeypatch, backoff):
    """Tries refused every time (as above) come at iterations k0, k0 + every, k0 + every (1 + backoff), ...: with
    backoff 1 every ``every`` iterations (the rule before), and fewer tries the larger the backoff."""
    from admmkit.problems.qp import polish_stop
    at = []

    def refused(qp, xb, zb, yb, **kwargs):
        at.append(len(at))
        return None, None, {"status": "failed"}
    monkeypatch.setattr(polish_stop, "polish", refused)
    monkeypatch.setattr(polish_stop, "active_set", lambda qp, z, y: (bytes([len(at) % 256]), 0))   # a new guess each time
    seen = []
    original = polish_stop.PolishingTermination.fired

    def fired(self, rec):
        before = len(at)
        out = original(self, rec)
        if len(at) > before:
            seen.append(rec.k)
        return out
    monkeypatch.setattr(polish_stop.PolishingTermination, "fired", fired)
    qp = hs118_like()
    res = solve_qp(qp, admmkit_settings(1e-9, 0.0, adaptive_rho="interval", polish_gate=1e9, polish_interval=25,
                                        polish_backoff=backoff, max_iter=1000))
    assert res.polish is None and len(seen) >= 3
    gaps = np.diff(seen)
    wait = 25.0
    for gap in gaps:             # each gap is the wait rounded up to the next check (every 25 iterations)
        assert int(wait) <= gap < int(wait) + 25
        wait *= backoff


@pytest.mark.parametrize("surplus, tries", [(1, 1), (0, "many")])
def test_after_a_degenerate_try_fails_later_degenerate_guesses_are_skipped(monkeypatch, surplus, tries):
    """A guess with more active rows than unknowns (k = n + 1) is tried once; after it failed, the next degenerate
    guesses are not tried (the tries made with k = n keep coming every ``polish_interval`` iterations)."""
    from admmkit.problems.qp import polish_stop
    at = []

    def refused(qp, xb, zb, yb, **kwargs):
        at.append(len(at))
        return None, None, {"status": "failed"}
    monkeypatch.setattr(polish_stop, "polish", refused)
    monkeypatch.setattr(polish_stop, "active_set", lambda qp, z, y: (bytes([len(at) % 256]), qp.n + surplus))
    qp = hs118_like()
    res = solve_qp(qp, admmkit_settings(1e-9, 0.0, adaptive_rho="interval", polish_gate=1e9, polish_interval=25,
                                        polish_backoff=1.0, max_iter=1000))
    assert res.polish is None
    assert res.iterations == 200                      # the run's length does not depend on the tries refused
    assert len(at) == 1 if tries == 1 else len(at) >= 5


def test_the_guessed_active_set_counts_its_rows():
    from admmkit.problems.qp.polish_stop import active_set
    qp = hs118_like()
    z = np.clip(np.zeros(qp.m), qp.l, qp.u)
    y = np.zeros(qp.m)
    y[:3], y[3:5] = -1.0, 1.0                         # rows 0-2 pushed down to l, rows 3-4 up to u
    z[:5] = np.r_[qp.l[:3], qp.u[3:5]]
    guess, rows = active_set(qp, z, y)
    assert rows == 5 and isinstance(guess, bytes)
    assert active_set(qp, z, np.zeros(qp.m))[1] == 0


@pytest.mark.parametrize("changes, name", [({"polish_gate": 0.5}, "polish_gate"), ({"polish_interval": 0}, "polish_interval"),
                                           ({"polish_backoff": 0.5}, "polish_backoff"),
                                           ({"early_polish": "yes"}, "early_polish"),
                                           ({"adaptive_rho": "time"}, "adaptive_rho"),
                                           ({"adaptive_rho_fraction": 1.5}, "adaptive_rho_fraction")])
def test_bad_settings_name_themselves(changes, name):
    with pytest.raises(ValueError, match=name):
        osqp_settings(**changes)


def test_kkt_error_mode_solves_and_changes_rho_less_often():
    qp = hs118_like(seed=2)
    interval = solve_qp(qp, osqp_settings(eps_abs=1e-6, eps_rel=0.0, max_iter=20000))
    kkt = solve_qp(qp, osqp_settings(eps_abs=1e-6, eps_rel=0.0, max_iter=20000, adaptive_rho="kkt_error"))
    assert kkt.status is Status.CONVERGED
    assert "OSQPKKTRule" in kkt.policy and "OSQPRule" in interval.policy
    assert neutral_satisfied(neutral_residuals(qp, kkt.x, kkt.y), 1e-5)


def test_the_iterates_solved_is_confirmed_in_the_users_problem(monkeypatch):
    """QSHELL at 1e-3: OSQP's gap summed in the scaled problem held (9e-4) where the user's problem's is 0.015 (terms
    of 1e12); the preset confirms a solved iterate there.  Here the user's-problem residuals are made to fail."""
    from admmkit.problems.qp import polish_stop
    qp = hs118_like()
    failing = {"primal": 1.0, "primal_scale": 0.0, "dual": 1.0, "dual_scale": 0.0, "gap": 1.0, "gap_scale": 0.0}
    monkeypatch.setattr(polish_stop, "osqp_residuals", lambda *args: failing)
    res = solve_qp(qp, admmkit_settings(1e-3, 0.0, max_iter=300, early_polish=True))
    assert res.status is not Status.CONVERGED and res.iterations == 300


def test_polishing_solves_its_reduced_system_with_or_without_qdldl(monkeypatch):
    """(P1) is quasi-definite: qdldl's LDL' (AMD order) and, without qdldl, SuperLU in symmetric mode give the same
    polished point to round-off, and both polish the run to a point that passes the neutral test."""
    import sys
    from admmkit.problems.qp import polish as polish_module
    K = polish_module.sp.csc_matrix(np.array([[2.0, 0.0, 1.0], [0.0, 3.0, 1.0], [1.0, 1.0, -1e-6]]))
    U = polish_module.sp.triu(K, format="csc")                 # the solver is given the upper triangle
    b = np.array([1.0, -2.0, 0.5])
    reduced_solver = polish_module._reduced_solver

    def superlu_only(U, order=None):                       # import qdldl raises ImportError inside the polish only
        with monkeypatch.context() as m:
            m.setitem(sys.modules, "qdldl", None)
            return reduced_solver(U, order)
    with_qdldl, without = reduced_solver(U)(b), superlu_only(U)(b)
    assert type(superlu_only(U).__self__).__name__ == "SuperLU"
    assert np.allclose(with_qdldl, without, rtol=1e-12, atol=0) and np.allclose(K @ without, b, atol=1e-12)
    monkeypatch.setattr(polish_module, "_reduced_solver", superlu_only)
    qp = hs118_like()
    early = solve_qp(qp, admmkit_settings(1e-6, 0.0, adaptive_rho="interval"))   # the polish on SuperLU's path
    assert early.polish["status"] == "succeeded" and neutral_satisfied(neutral_residuals(qp, early.x, early.y), 1e-6)



@pytest.mark.parametrize("eps", [1e-3, 1e-6])
def test_the_preset_runs_the_rule_rowwise_and_names_it(eps):
    """admmkit_settings' rule is rowwise (a penalty per row, chosen on the training split): the run changes row
    weights, ends converged at a point that passes the neutral test, and adaptive_rho="interval" is OSQP's rule."""
    from admmkit.policies.rowwise import RowwiseRule
    from admmkit.problems.qp.solve import default_policy
    qp = hs118_like(seed=3)
    assert isinstance(default_policy(qp, admmkit_settings(eps, 0.0)), RowwiseRule)
    assert not isinstance(default_policy(qp, admmkit_settings(eps, 0.0, adaptive_rho="interval")), RowwiseRule)
    res = solve_qp(qp, admmkit_settings(eps, 0.0))
    assert res.status is Status.CONVERGED and neutral_satisfied(neutral_residuals(qp, res.x, res.y), eps)
    with pytest.raises(ValueError, match="adaptive_rho must be one of 'interval', 'kkt_error', 'rowwise'"):
        admmkit_settings(adaptive_rho="per-row")


def test_polishing_system_factorised_by_the_qp_kernels_is_qdldls_bit_for_bit(monkeypatch):
    """Where the process runs the QP's compiled code, (P1) is factorised by its kernels (AMD's port, qdldl's phases):
    the solve equals qdldl's wrapper's bit for bit."""
    qdldl = pytest.importorskip("qdldl")
    import scipy.sparse as sp
    from admmkit.problems.qp import polish as polish_module
    from admmkit.problems.qp.generate import random_qp
    from admmkit.problems.qp.segment import AVAILABLE, kernels_loaded
    if not AVAILABLE:
        pytest.skip("numba is not installed: qdldl's wrapper always")
    solve_qp(random_qp(30, 40, seed=1), compiled=True)          # the QP's kernels in this process
    assert kernels_loaded()
    rng = np.random.default_rng(4)
    n, k = 40, 25
    B = sp.random(n, n, density=0.1, random_state=rng)
    P = (B @ B.T + sp.eye(n)).tocsc()
    A = sp.random(k, n, density=0.2, random_state=rng, format="csc")
    K = sp.bmat([[P + 1e-6 * sp.eye(n), A.T], [A, -1e-6 * sp.eye(k)]], format="csc")
    b = rng.standard_normal(n + k)
    U = sp.triu(K, format="csc")
    reference = qdldl.Solver(U, upper=True).solve(b)
    assert np.array_equal(polish_module._reduced_solver(U)(b), reference)
    monkeypatch.setattr(polish_module, "COMPILED_FACTOR", False)
    assert np.array_equal(polish_module._reduced_solver(U)(b), reference)


def test_the_reduced_systems_upper_triangle_is_scipys_assembly():
    """reduced_upper builds triu(bmat([[P, A_act'], [A_act, None]]) + diags(delta, -delta)) entry for entry and in
    its order, for no, some and every row active."""
    import scipy.sparse as sp
    from admmkit.problems.qp.polish import reduced_upper
    qp = hs118_like(seed=3)
    qp._build()
    rng = np.random.default_rng(0)
    for act in (np.array([], dtype=np.int64), np.flatnonzero(rng.random(qp.m) < 0.4), np.arange(qp.m)):
        A_act = sp.csr_matrix(qp.As)[act]
        K0 = sp.bmat([[qp.Ps, A_act.T], [A_act, None]], format="csc") if act.size else sp.csc_matrix(qp.Ps)
        reg = sp.diags(np.r_[np.full(qp.n, 1e-6), np.full(act.size, -1e-6)], format="csc")
        reference = sp.triu((K0 + reg).tocsc(), format="csc")
        reference.sort_indices()
        U = reduced_upper(qp, act, 1e-6)
        assert np.array_equal(U.indptr, reference.indptr) and np.array_equal(U.indices, reference.indices)
        assert np.array_equal(U.data, reference.data)


def _kkt_and_reduced(seed=5, n=40, m=60, active=25):
    """A random KKT upper triangle [[P + I, A'], [A, -I]] (n + m unknowns), and a random set of ``active`` rows."""
    import scipy.sparse as sp
    rng = np.random.default_rng(seed)
    B = sp.random(n, n, density=0.08, random_state=rng)
    P = (B @ B.T + sp.eye(n)).tocsc()
    A = sp.random(m, n, density=0.08, random_state=rng, format="csc")
    full = sp.triu(sp.bmat([[P, A.T], [A, -sp.eye(m)]], format="csc"), format="csc")
    full.sort_indices()
    act = np.sort(rng.choice(m, active, replace=False))
    rows = A.tocsr()[act]
    sub = sp.triu(sp.bmat([[P + 1e-6 * sp.eye(n), rows.T], [rows, -1e-6 * sp.eye(active)]], format="csc"),
                  format="csc")
    sub.sort_indices()
    return full, sub, n, m, act


def test_the_induced_order_fills_the_reduced_factor_no_more_than_the_whole_one():
    """induced_order keeps x and the active rows in the whole order's sequence, renumbered; factorised in it, (P1)'s
    factor has no more entries than the whole KKT matrix's in its order, and solves (P1) as AMD's order does."""
    from admmkit.problems.qp.generate import random_qp
    from admmkit.problems.qp.kkt_factor import KKTFactor, amd_order
    from admmkit.problems.qp.polish import _reduced_solver, induced_order
    from admmkit.problems.qp.segment import AVAILABLE, kernels_loaded
    if not AVAILABLE:
        pytest.skip("numba is not installed: qdldl's wrapper, in AMD's order")
    solve_qp(random_qp(30, 40, seed=1), compiled=True)          # the QP's kernels in this process: the order is used
    assert kernels_loaded()
    full, sub, n, m, act = _kkt_and_reduced()
    order = amd_order(full)
    induced = induced_order(order, n, act, m)
    assert np.array_equal(np.sort(induced), np.arange(n + act.size))
    position = {v: i for i, v in enumerate(order)}
    back = np.r_[np.arange(n), n + act]                    # (P1)'s unknown -> the whole matrix's
    assert np.all(np.diff([position[v] for v in back[induced]]) > 0)
    whole, reduced = KKTFactor(lambda rho: full), KKTFactor(lambda rho: sub, induced)
    whole.prepare(1.0)
    reduced.prepare(1.0)
    assert np.array_equal(reduced.order, induced)
    assert reduced.ldl(1.0)[0][-1] <= whole.ldl(1.0)[0][-1]
    b = np.random.default_rng(1).standard_normal(n + act.size)
    K = sub + sub.T - __import__("scipy.sparse", fromlist=["diags"]).diags(sub.diagonal())
    x = _reduced_solver(sub, induced)(b)
    assert np.allclose(K @ x, b, atol=1e-9 * np.abs(b).max())
    y = _reduced_solver(sub)(b)                            # AMD's order of (P1): the same solution to round-off
    assert not np.array_equal(x, y) and np.allclose(x, y, rtol=1e-6, atol=1e-9)


def test_polishing_during_the_run_factorises_in_the_x_steps_order(monkeypatch):
    """The preset's tries hand polish() the order of the x-step's KKT factor (a try then factorises no more than a
    change of rho does); polish() without it (OSQP's polish at the end) orders (P1) by AMD."""
    from admmkit.problems.qp import polish_stop
    from admmkit.problems.qp.generate import random_qp
    from admmkit.problems.qp.segment import AVAILABLE
    if not AVAILABLE:
        pytest.skip("numba is not installed: no compiled KKT factor")
    seen = []
    original = polish_stop.polish

    def recording(qp, *args, **kwargs):
        seen.append((kwargs.get("order"), getattr(qp._solver, "order", None), qp.n + qp.m))
        return original(qp, *args, **kwargs)
    monkeypatch.setattr(polish_stop, "polish", recording)
    qp = random_qp(60, 80, seed=2)
    res = solve_qp(qp, admmkit_settings(1e-6, 0.0, compiled=True, xstep="kkt"))
    assert res.status is Status.CONVERGED and seen
    for given, held, size in seen:
        assert given is not None and given is held and given.shape == (size,)


@pytest.mark.parametrize("seed", range(20))
def test_the_polishing_parts_are_scipys_triu_and_csr(seed):
    """strict_upper and rows_of give the arrays of scipy's triu(P, k=1) and csr_matrix(A) (sorted), entry for entry,
    empty rows and columns included."""
    import scipy.sparse as sp
    from admmkit.problems.qp.polish import rows_of, strict_upper
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(1, 30)), int(rng.integers(1, 40))
    B = sp.random(n, n, density=rng.random() * 0.5, random_state=seed)
    P = (B + B.T).tocsc()
    A = sp.random(m, n, density=rng.random() * 0.3, random_state=seed + 1, format="csc")
    P.sort_indices()
    A.sort_indices()
    U, R = sp.triu(P, k=1, format="csc"), sp.csr_matrix(A)
    U.sort_indices()
    R.sort_indices()
    for ours, ref in ((strict_upper(P), U), (rows_of(A), R)):
        assert all(np.array_equal(getattr(ours, k), getattr(ref, k)) for k in ("indptr", "indices", "data"))
