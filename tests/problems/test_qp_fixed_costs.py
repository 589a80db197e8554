"""#49 item 3: a small QP's fixed costs cut without changing a number.

Each speed trick here has its library path (compiled code off), and the tests check that both give the same
bits: ``ScaleCheck``'s arrays (one compiled pass, ``termination.scale_facts``), the shifted P of the convexity
test (``convexity.shifted``), and whole solves with and without the compiled helpers.
"""
import dataclasses
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from admmkit.kernels import compiled_code
from admmkit.problems.qp import QP, load_mat, solve_qp
from admmkit.problems.qp.convexity import check_convex, shifted
from admmkit.problems.qp.generate import random_qp
from admmkit.problems.qp.termination import ScaleCheck

numba = pytest.importorskip("numba")

DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "maros_meszaros"
FIELDS = ("nu", "live", "bound", "kappa", "span_rows", "void_rows", "span_columns")


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def awkward_qp() -> QP:
    """Every kind of row and column ScaleCheck names: a span row (1e-12 against 1), a tiny row, a void row whose
    bounds exclude 0, a void row that admits 0, free and one-sided rows, and a span column."""
    A = sp.csc_matrix(np.array([[1.0, 2.0, 0.0, 0.0],
                                [1e-12, 0.0, 0.0, 0.0],       # span row
                                [0.0, 0.0, 0.0, 0.0],         # void row, bounds exclude 0
                                [0.0, 0.0, 0.0, 0.0],         # void row, bounds admit 0
                                [0.0, 3.0, -4.0, 0.0],        # free row
                                [0.0, 0.0, 1.0, 0.0],         # one-sided
                                [0.0, 0.0, 0.0, 1e-13]]))     # span column 3 (P's is 0 too)
    P = sp.csc_matrix(np.diag([2.0, 1.0, 0.5, 0.0]))
    l = np.array([-1.0, -1e-9, 1e-9, -1.0, -np.inf, -np.inf, -1.0])
    u = np.array([1.0, 1e-9, 2.0, 1.0, np.inf, 5.0, 1.0])
    return QP(P, np.ones(4), A, l, u)


@pytest.mark.parametrize("make", [awkward_qp, lambda: random_qp(30, 40, seed=3), lambda: random_qp(8, 3, kind="lp", seed=1)])
def test_scale_check_compiled_gives_the_library_paths_arrays(make):
    qp = make()
    with compiled_code(True):
        fast = ScaleCheck(qp)
    with compiled_code(False):
        slow = ScaleCheck(qp)
    for name in FIELDS:
        assert _same_bits(getattr(fast, name), getattr(slow, name)), name


def test_the_awkward_qp_has_what_the_scale_check_names():
    fast = ScaleCheck(awkward_qp())
    assert list(fast.span_rows) == [1, 6] and list(fast.void_rows) == [2] and list(fast.span_columns) == [3]
    assert fast.bound[4] == 0.0 and fast.bound[5] == 5.0 and not fast.live[4]


@pytest.mark.parametrize("P", [sp.csc_matrix(np.array([[2.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])),
                               sp.csc_matrix(np.array([[-1e-9, 1.0], [1.0, 3.0]])),      # a diagonal sum of 0
                               sp.random(40, 40, density=0.1, random_state=2, format="csc")])
def test_shifted_p_is_scipys_sum(P):
    P = (P + P.T).tocsc()
    P.sort_indices()
    with compiled_code(True):
        fast = shifted(P, 1e-9)
    with compiled_code(False):
        slow = shifted(P, 1e-9)
    assert slow.has_sorted_indices
    assert np.array_equal(fast.indptr, slow.indptr) and np.array_equal(fast.indices, slow.indices)
    assert _same_bits(fast.data, slow.data)


def test_convexity_verdicts_are_the_same_on_both_paths():
    indefinite = sp.csc_matrix(np.array([[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]]))
    for flag in (True, False):
        with compiled_code(flag):
            with pytest.raises(ValueError, match="positive semidefinite"):
                check_convex(indefinite)
            check_convex(sp.csc_matrix(np.array([[2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 0.0]])))


def _fingerprint(res) -> tuple:
    return (res.x.tobytes(), res.z.tobytes(), res.y.tobytes(), res.iterations, res.status, res.termination,
            res.rho, tuple(res.history["rho"]), tuple(sorted((res.residuals or {}).items())),
            tuple(sorted((res.neutral or {}).items())), tuple(res.warnings))


@pytest.mark.skipif(not DATA.exists(), reason="needs ../shared/data/maros_meszaros")
@pytest.mark.parametrize("name", ["HS21", "HS118", "QAFIRO", "DUAL1"])
def test_a_whole_solve_is_the_same_with_the_helpers_compiled_or_not(name):
    qp = load_mat(DATA / f"{name}.mat")
    runs = []
    for flag in (True, False):
        with compiled_code(flag):
            runs.append(_fingerprint(solve_qp(QP(qp.P, qp.q, qp.A, qp.l, qp.u), eps_abs=1e-6, eps_rel=1e-6,
                                              compiled=False)))
    assert runs[0] == runs[1]


def _verdict(P) -> str:
    try:
        check_convex(P)
        return "convex"
    except ValueError as err:
        return str(err)


def test_a_small_sparse_p_gets_superlus_verdict_from_the_dense_cholesky(monkeypatch):
    """Up to DENSE_ANY rows a sparse P goes to the dense Cholesky factorisation; its verdicts (and messages) are
    SuperLU's, the route taken with DENSE_ANY = 0, on matrices whose smallest eigenvalue is near -delta."""
    from admmkit.problems.qp import convexity
    rng = np.random.default_rng(0)
    refused = 0
    for i in range(40):
        n = int(rng.integers(2, 120))
        G = sp.random(n, n, density=min(1.0, 3.0 / n), random_state=i, format="csc")
        S = (G + G.T).tocsc()
        lowest = np.linalg.eigvalsh(S.toarray())[0]
        shift = [0.0, 1e-12, 1e-9, 1e-6, 1.0][i % 5] * (1 if i % 2 else -1)
        P = (S - (lowest - shift) * sp.identity(n)).tocsc()
        P.sort_indices()
        monkeypatch.setattr(convexity, "DENSE_ANY", 128)
        dense = _verdict(P)
        monkeypatch.setattr(convexity, "DENSE_ANY", 0)
        sparse = _verdict(P)
        assert dense == sparse, i
        refused += dense != "convex"
    assert 0 < refused < 40           # both kinds met


@pytest.mark.parametrize("seed", [0, 5])
def test_the_read_iterations_residuals_from_the_kernel_are_the_ones_computed_anew(seed, monkeypatch):
    """The segment's kernel keeps the residuals it computed at the iteration it ends on; the Python test takes them
    (termination.KERNEL_RESIDUALS) and the run is the one that computes them anew, bit for bit."""
    from admmkit.problems.qp import termination
    qp = random_qp(30, 40, seed=seed)
    taken = []
    original = termination._from_kernel
    monkeypatch.setattr(termination, "_from_kernel", lambda *a: taken.append(original(*a)) or taken[-1])
    fast = solve_qp(qp, eps_abs=1e-6, eps_rel=1e-6, compiled=True)
    assert any(t is not None for t in taken)             # the kernel's numbers were used
    monkeypatch.setattr(termination, "KERNEL_RESIDUALS", False)
    slow = solve_qp(qp, eps_abs=1e-6, eps_rel=1e-6, compiled=True)
    assert _fingerprint(fast) == _fingerprint(slow)
    rec = fast.last_record
    run_qp = rec._ctx.problem
    anew = termination.residuals_of_iterate()(run_qp, run_qp.relaxed_x(rec.x), rec.z, rec.lam_z, None, scaled=True)
    assert list(anew.items()) == list(fast.residuals.items()) + [(k, v) for k, v in anew.items()
                                                                  if k.startswith("scaled_")]


def test_a_qp_says_it_has_an_adjoint_norm_without_a_trial_product(monkeypatch):
    from admmkit.loop.checks import has_adjoint
    from admmkit.problems.qp.problem import QP as QPClass

    def refuse(self, y):
        raise NotImplementedError
    qp = random_qp(5, 4, seed=0)
    monkeypatch.setattr(QPClass, "adjoint_norm", refuse)
    assert has_adjoint(qp, np.zeros(4))                   # the class says so; no call is made
    monkeypatch.setattr(QPClass, "adjoint_norm_implemented", False)
    assert not has_adjoint(qp, np.zeros(4))               # without the flag, the trial call tells


def test_the_qps_start_is_the_problems_default_bit_for_bit():
    from admmkit import Problem
    qp = awkward_qp()
    qp._build()
    for own, default in zip(qp.initial_point(), Problem.initial_point(qp)):
        assert _same_bits(own, np.asarray(default, dtype=float))
        assert not np.signbit(own).any()


@pytest.mark.parametrize("make", [awkward_qp, lambda: random_qp(30, 40, seed=3)])
def test_may_be_blind_is_span_rows_or_rows_tiny_at_zero(make):
    qp = make()
    for eps in (1e-14, 1e-9, 1e-3, 1.0, 10.0):
        fresh = ScaleCheck(qp)
        assert fresh.may_be_blind(eps) == bool(fresh.span_rows.size or fresh.tiny_rows(np.zeros(1), eps).size)


def test_the_same_settings_are_built_and_checked_once():
    from admmkit.problems.qp import osqp_settings
    a = osqp_settings(eps_abs=1e-3, eps_rel=1e-3, compiled=True)
    assert osqp_settings(eps_abs=1e-3, eps_rel=1e-3, compiled=True) is a           # frozen: shared
    assert osqp_settings(eps_abs=1e-4, eps_rel=1e-3, compiled=True) is not a
    assert type(osqp_settings(max_iter=10).rho) is float and osqp_settings() is osqp_settings()
    one, one_float = osqp_settings(alpha=1), osqp_settings(alpha=1.0)               # a value's type is its own
    assert type(one.alpha) is int and type(one_float.alpha) is float
    minus = osqp_settings(sigma=-0.0)
    assert str(minus.sigma) == "-0.0" and str(osqp_settings(sigma=0.0).sigma) == "0.0"
    for _ in range(2):                                   # a bad value raises every time: nothing was kept
        with pytest.raises(ValueError, match="alpha must be in"):
            osqp_settings(alpha=3.0)
    big = np.float64(2.0)
    assert osqp_settings(polish_backoff=big).polish_backoff == 2.0


@pytest.mark.parametrize("l, u, message", [
    ([0.0, np.nan], [1.0, 1.0], "l must not contain NaN"),
    ([0.0, 0.0], [np.nan, 1.0], "u must not contain NaN"),
    ([np.nan, 0.0], [np.nan, 1.0], "l must not contain NaN"),              # l's check first
    ([np.inf, 0.0], [np.inf, 1.0], "l < \\+inf and u > -inf"),
    ([0.0, -np.inf], [1.0, -np.inf], "l < \\+inf and u > -inf"),
    ([0.0, 2.0, 3.0], [1.0, 1.0, 1.0], "row 1 has l = 2 > u = 1 \\(2 such rows\\)"),
    ([0.0], [1.0, 1.0], "l must have length m = 2"),
    ([0.0, np.nan], [1.0], "l must not contain NaN"),                      # l's NaN before u's length
])
def test_the_bounds_are_refused_alike_compiled_or_not(l, u, message):
    m = len(l) if len(l) == len(u) else 2
    A = sp.csc_matrix(np.ones((m, 2)))
    for flag in (True, False):
        with compiled_code(flag):
            with pytest.raises(ValueError, match=message):
                QP(sp.identity(2, format="csc"), np.zeros(2), A, np.array(l), np.array(u))


def test_the_bounds_kernel_answers_numpys_questions():
    from admmkit.problems.qp.validate_kernel import bound_facts
    rng = np.random.default_rng(0)
    l, u = rng.standard_normal(50), rng.standard_normal(50)
    l[[3, 7]], u[9], l[11] = np.nan, -np.inf, np.inf
    crossed = np.flatnonzero(l > u)
    with compiled_code(True):
        assert bound_facts(l, u) == (True, False, True, crossed.size, crossed[0])
        assert bound_facts(np.zeros(4), np.ones(4)) == (False, False, False, 0, -1)


def test_ruiz_lifts_a_tiny_row_alike_compiled_or_not():
    from admmkit.problems.qp.scaling import ruiz
    A = sp.csc_matrix(np.array([[1.0, 2.0], [3e-8, 0.0], [0.0, 1e-5]]))
    P, q = sp.csc_matrix(np.diag([2.0, 1.0])), np.array([1.0, -1.0])
    out = {}
    for flag in (True, False):
        with compiled_code(flag):
            S, Ps, qs, As = ruiz(P, q, A, 10)
        out[flag] = np.concatenate([S.D, S.E, [S.c], Ps.data, qs, As.data])
    assert _same_bits(out[True], out[False])
    assert out[True][3] > 1e6          # the tiny row's E lifts it (2^25 before the steps)


def test_a_compiled_solve_skips_the_question_whether_compiled_code_pays(monkeypatch):
    from admmkit import kernels
    from admmkit.problems.qp import solve as solve_module
    qp = random_qp(5, 5, seed=0)
    assert solve_module.compiled_for(True, qp) == solve_module.choose_compiled(True, qp)
    def asked(*args):
        raise LookupError("asked")
    monkeypatch.setattr(solve_module, "choose_compiled", asked)
    assert solve_module.compiled_for(True, qp) == (kernels.AVAILABLE, kernels.AVAILABLE)
    with pytest.raises(LookupError, match="asked"):
        solve_module.compiled_for("auto", qp)


def test_a_results_fields_are_copied_whole_or_read_one_by_one():
    from admmkit.problems.qp.solve import _RESULT_FIELDS, _fields_of
    import admmkit
    res = admmkit.solve(random_qp(5, 5, seed=0), max_iter=20)
    plain = _fields_of(res)
    assert list(plain) == list(res.__dict__) and set(plain) == set(_RESULT_FIELDS) and plain["x"] is res.x
    res.note = "an attribute that is no field"
    assert set(_fields_of(res)) == set(_RESULT_FIELDS)
    assert set(_fields_of(solve_qp(random_qp(5, 5, seed=0)))) == set(_RESULT_FIELDS)       # a QPResult: more


def test_the_zero_settings_are_built_anew_and_keep_their_sign():
    from admmkit.problems.qp import osqp_settings
    assert osqp_settings(sigma=0.0) is not osqp_settings(sigma=0.0)
    assert str(osqp_settings(sigma=-0.0).sigma) == "-0.0" and osqp_settings(polish=False).polish is False


def test_a_completed_record_holds_what_reading_each_norm_gives():
    from admmkit.loop.record import LAZY_FIELDS, loop_record
    from admmkit.problems.qp.solve import qp_for
    from admmkit.problems.qp import osqp_settings
    import admmkit
    qp = qp_for(random_qp(20, 30, seed=1), osqp_settings())
    seen = []
    admmkit.solve(qp, rho=0.1, alpha=1.6, max_iter=3, callback=lambda rec: seen.append(rec) and None,
                  compiled=False)
    rec = seen[-1]
    k, rho, t, x1, z1, lam1, Ax1, x, z, lam, Ax, hat, r_norm = rec._d
    fresh = [loop_record(rec._ctx, k, rho, t + rec._ctx.start, x1, z1, lam1, Ax1, x, z, lam, Ax, hat, r_norm)
             for _ in range(2)]
    one_by_one = [getattr(fresh[0], name) for name in LAZY_FIELDS]
    assert fresh[1].complete().computed() == tuple(one_by_one) and None not in one_by_one


def test_read_only_bounds_take_the_numpy_checks(monkeypatch):
    from admmkit.problems.qp import validate
    l, u = np.array([0.0, 2.0]), np.array([1.0, 1.0])
    l.flags.writeable = False
    monkeypatch.setattr(validate, "bound_facts", lambda *a: pytest.fail("the kernel was called"))
    with compiled_code(True):
        with pytest.raises(ValueError, match="row 1 has l = 2 > u = 1"):
            validate._check_bounds(l, u, 2, True)


def test_solve_qp_checks_the_settings_qp_options_once_per_settings(monkeypatch):
    """The QP options a settings object asks for are checked once (``solve.qp_options``), not again at each copy of a
    QP: a second solve with the same settings runs ``check_options`` only in the QP's own construction; a bad
    ``row_weights`` in the settings is still refused with the QP's message, every time."""
    from admmkit.problems.qp import osqp_settings, problem, solve, validate
    calls = []

    def counted(**options):
        calls.append(options)
        return validate.check_options(**options)
    monkeypatch.setattr(problem, "check_options", counted)
    monkeypatch.setattr(solve, "check_options", counted, raising=False)
    qp = random_qp(6, 8, seed=3)
    settings = osqp_settings(eps_abs=1e-5, eps_rel=1e-5)
    first = solve_qp(QP(qp.P, qp.q, qp.A, qp.l, qp.u), settings)
    calls.clear()
    again = solve_qp(QP(qp.P, qp.q, qp.A, qp.l, qp.u), settings)
    assert len(calls) == 1                                   # the QP's construction, not the copy
    assert np.array_equal(first.x, again.x) and first.iterations == again.iterations
    copy = solve.qp_for(qp, settings)
    assert copy.options == qp.with_options(**solve.qp_options(settings)).options
    bad = dataclasses.replace(settings, row_weights="per-row")
    for _ in range(2):
        with pytest.raises(ValueError, match="row_weights must be one of uniform, osqp"):
            solve_qp(qp, bad)


def test_a_tiny_p_is_factorised_in_one_kernel_call_with_lapacks_verdicts(monkeypatch):
    """Up to COMPILED_CHOLESKY_MAX rows, where compiled code runs, the convexity test's Cholesky factorisation is one
    kernel call on P's arrays (no dense copy, no LAPACK call), with LAPACK's verdicts on PD, singular PSD and
    indefinite matrices; as Python (no numba) LAPACK still decides."""
    pytest.importorskip("numba")
    from admmkit.problems.qp import convexity
    from admmkit.problems.qp.sparse_kernels import shifted_cholesky_holds
    rng = np.random.default_rng(5)
    cases = []
    for n, rank, shift in ((1, 1, 0.0), (2, 1, 0.0), (7, 7, 0.0), (12, 5, 0.0), (30, 30, -1e-3), (64, 20, 0.0),
                           (64, 64, -1e-6)):
        G = rng.standard_normal((n, rank))
        M = G @ G.T + shift * np.abs(G @ G.T).max() * np.eye(n)
        cases.append(sp.csc_matrix(M))
    lapack = []
    for P in cases:
        delta = convexity.SHIFT * np.abs(P.data).max()
        try:
            np.linalg.cholesky(P.toarray() + delta * np.eye(P.shape[0]))
            lapack.append(True)
        except np.linalg.LinAlgError:
            lapack.append(False)
        with compiled_code(True):
            assert shifted_cholesky_holds(P.indptr, P.indices, P.data, delta) == lapack[-1]
    assert True in lapack and False in lapack
    verdicts = [_verdict(P) for P in cases]
    monkeypatch.setattr(np.linalg, "cholesky", lambda *a, **k: pytest.fail("LAPACK called for a tiny P"))
    with compiled_code(True):
        assert [_verdict(P) for P in cases] == verdicts
    with compiled_code(False), pytest.raises(pytest.fail.Exception):
        _verdict(cases[2])


def test_row_weights_and_free_rows_in_one_pass_are_numpys(monkeypatch):
    """Where compiled code runs, OSQP's row weights and the free rows come from one kernel pass
    (``rows.osqp_weights``), equal to the numpy steps (values and index dtype); "uniform" has no weights and no free
    rows either way."""
    pytest.importorskip("numba")
    from admmkit.problems.qp import rows
    l = np.array([0.0, -np.inf, 1.0, -np.inf, 2.0, -1.0])
    u = np.array([1.0, np.inf, 1.0 + 1e-5, 3.0, np.inf, -1.0])
    with compiled_code(False):
        w_numpy, free_numpy = rows.weights_and_free_rows(l, u)
    assert list(w_numpy) == [1.0, rows.FREE_ROW_WEIGHT, rows.EQ_ROW_WEIGHT, 1.0, 1.0, rows.EQ_ROW_WEIGHT]
    monkeypatch.setattr(rows, "row_weights", lambda *a: pytest.fail("the numpy steps ran"))
    with compiled_code(True):
        w, free = rows.weights_and_free_rows(l, u)
    assert np.array_equal(w, w_numpy) and np.array_equal(free, free_numpy) and free.dtype == free_numpy.dtype
    assert list(free) == [1]
    monkeypatch.undo()
    for flag in (True, False):
        with compiled_code(flag):
            none, no_free = rows.weights_and_free_rows(l, u, "uniform")
        assert none is None and no_free.size == 0
