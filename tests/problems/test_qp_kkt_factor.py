"""The KKT factor held as arrays (problems/qp/kkt_factor.py) is qdldl's, bit for bit, and a solve with it is the
solve without it; the light scipy matrices (problems/qp/csc.py) and the lazy history rows are what they replace."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from admmkit.kernels import AVAILABLE, compiled_code
from admmkit.loop.history import History
from admmkit.problems.qp import QP, load_mat, solve_qp
from admmkit.problems.qp import csc as csc_module
from admmkit.problems.qp import kkt_factor
from admmkit.problems.qp.generate import random_qp
from admmkit.problems.qp.xstep_forms import _kkt_pattern

qdldl = pytest.importorskip("qdldl")
pytestmark = pytest.mark.skipif(not AVAILABLE, reason="the held factor needs numba")

DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "data" / "maros_meszaros"
MAROS = ("HS21", "HS118", "QAFIRO", "DUAL1", "CVXQP1_S", "QPCBLEND")


def _qps():
    """Generated QPs of every kind, and some Maros-Meszaros problems where the data is here."""
    out = [random_qp(12, 20, kind=kind, seed=seed) for kind in ("mixed", "equality", "lp") for seed in (0, 1)]
    out += [load_mat(DATA / f"{name}.mat") for name in MAROS if (DATA / f"{name}.mat").exists()]
    return out


def _osqp_form(qp):
    with compiled_code(True):
        run = qp.with_options(xstep="kkt", scaling=10, row_weights="osqp")
        run._build()
    return run


@pytest.mark.parametrize("index", range(6 + len(MAROS)))
def test_held_factor_is_qdldls_bit_for_bit(index):
    qps = _qps()
    if index >= len(qps):
        pytest.skip("Maros-Meszaros data not here")
    run = _osqp_form(qps[index])
    with compiled_code(True):
        factor = run._solver
        assert isinstance(factor, kkt_factor.KKTFactor)
        K = factor.matrix(0.1)
        assert np.array_equal(kkt_factor.amd_order(K), np.asarray(qdldl.Solver(K, upper=True).factors()[2]))
        solver = qdldl.Solver(K, upper=True)
        for rho in (0.1, 7.3, 1e-6, 1e6, 0.1):          # refactorised in place, back to the first rho too
            K = factor.matrix(rho)
            solver.update(K, upper=True)
            L, d, _ = solver.factors()
            Lp, Li, Lx, Dinv, _ = factor.ldl(rho)
            assert np.array_equal(Lp, L.indptr) and np.array_equal(Li, L.indices)
            assert np.array_equal(Lx, L.data) and np.array_equal(Dinv, 1.0 / d)
            b = np.linspace(-1.0, 2.0, K.shape[0])
            assert np.array_equal(factor.solve(rho, b), solver.solve(b))


@pytest.mark.parametrize("size", [(15, 25), (60, 90)])
def test_order_read_off_qdldls_factor_is_the_same(monkeypatch, size):
    """The three ways to qdldl's order give one permutation: AMD's compiled port (from AMD_COMPILED_MIN_NNZ
    entries on), qdldl's routine called directly, and the order read off qdldl's factor."""
    run = _osqp_form(random_qp(*size, seed=3))
    threshold = kkt_factor.AMD_COMPILED_MIN_NNZ
    with compiled_code(True):
        K = run._solver.matrix(1.0)
        chosen = kkt_factor.amd_order(K)
        monkeypatch.setattr(kkt_factor, "AMD_COMPILED_MIN_NNZ", None)
        direct = kkt_factor.amd_order(K)
        monkeypatch.setattr(kkt_factor, "AMD_DIRECT", False)
        assert np.array_equal(kkt_factor.amd_order(K), direct) and np.array_equal(chosen, direct)
    if size == (60, 90):
        assert K.nnz >= threshold                                  # the compiled port was the one chosen


@pytest.mark.parametrize("name", ("HS118", "QAFIRO", "CVXQP1_S"))
@pytest.mark.parametrize("policy", ("osqp", "rowwise"))
def test_solve_with_the_held_factor_is_the_solve_without(monkeypatch, name, policy):
    path = DATA / f"{name}.mat"
    if not path.exists():
        pytest.skip("Maros-Meszaros data not here")
    qp = load_mat(path)
    runs = []
    for enabled in (True, False):
        monkeypatch.setattr(kkt_factor, "ENABLED", enabled)
        runs.append(solve_qp(QP(qp.P, qp.q, qp.A, qp.l, qp.u), eps_abs=1e-6, eps_rel=1e-6, compiled=True,
                             policy=policy))
    held, plain = runs
    assert held.rho_changes > 0 or name != "HS118"             # HS118 refactorises (rho changes twice)
    assert held.iterations == plain.iterations and held.rho == plain.rho and held.status == plain.status
    for a, b in ((held.x, plain.x), (held.y, plain.y), (held.z, plain.z)):
        assert np.array_equal(a, b)
    assert held.counters["factorizations"] == plain.counters["factorizations"]


def test_a_zero_pivot_is_a_linalg_error():
    K = sp.csc_matrix(np.array([[1.0, 1.0], [0.0, 1.0]]))        # upper triangle of [[1, 1], [1, 1]]: singular
    factor = kkt_factor.KKTFactor(lambda rho: K)
    with pytest.raises(np.linalg.LinAlgError, match="zero pivot"):
        factor.prepare(1.0)
    assert 1.0 not in factor


@pytest.mark.parametrize("light", (True, False))
def test_light_csc_is_scipys_matrix(monkeypatch, light):
    monkeypatch.setattr(csc_module, "LIGHT", light)
    M = sp.random(7, 5, density=0.4, format="csc", random_state=1)
    M.sort_indices()
    light_M = csc_module.csc_of(M.data, M.indices, M.indptr, M.shape)
    assert type(light_M) is sp.csc_matrix and light_M.shape == M.shape and light_M.has_canonical_format
    assert (light_M != M).nnz == 0
    x = np.arange(5.0)
    assert np.array_equal(light_M @ x, M @ x) and np.array_equal(light_M.T @ np.ones(7), M.T @ np.ones(7))
    assert np.shares_memory(light_M.data, M.data)        # shared, not copied


def test_kkt_pattern_is_the_scipy_assembly():
    run = _osqp_form(random_qp(10, 14, seed=2))
    with compiled_code(True):
        K, slots = _kkt_pattern(run, upper=True)
    P, A, n, m = run.Ps, run.As, run.n, run.m
    whole = sp.bmat([[P + run.sigma * sp.identity(n), A.T], [A, sp.identity(m)]], format="csc")
    assert (K != sp.triu(whole, format="csc")).nnz == 0
    assert np.array_equal(K.indices[slots], n + np.arange(m))


class _Ctx:
    primal_unit, dual_unit = 2.0, 3.0


def test_unread_runs_become_rows_when_read():
    h = History("lean")
    h.append_unread(0, 3, 0.5, _Ctx, 0.25)
    h.append_unread(3, 2, 0.5, _Ctx, 0.5)
    assert len(h) == 5
    assert np.array_equal(h["k"], np.arange(5)) and np.array_equal(h["rho"], np.full(5, 0.5))
    assert np.array_equal(h["time"], [0.25] * 3 + [0.5] * 2) and np.isnan(h["primal_residual"]).all()
    h.append_unread(5, 1, 0.7, _Ctx, 0.75)
    assert len(h) == 6 and h["rho_next"][-1] == 0.7 and not h["rho_changed"].any()


def test_a_solve_keeps_one_history_row_per_iteration():
    qp = random_qp(8, 12, seed=4)
    res = solve_qp(qp, eps_abs=1e-6, eps_rel=1e-6, compiled=True)
    assert res.counters["compiled_iterations"] > 1
    assert len(res.history) == res.iterations and np.array_equal(res.history["k"], np.arange(res.iterations))
    assert res.history.complete_rows()[-1] == res.iterations - 1          # the last row complete


@pytest.mark.parametrize("kind", ("dense", "diagonal", "nonfinite", "asymmetric", "empty"))
def test_p_facts_in_one_call_are_numpys(kind):
    from admmkit.problems.qp.sparse_kernels import p_checks
    from admmkit.problems.qp.validate import _canonical, _symmetry_defect
    rng = np.random.default_rng(5)
    B = rng.standard_normal((6, 6))
    P = {"dense": B + B.T, "diagonal": np.diag(rng.standard_normal(6)), "nonfinite": B + B.T,
         "asymmetric": B, "empty": np.zeros((6, 6))}[kind]
    if kind == "nonfinite":
        P[2, 3] = np.inf
    M = _canonical(sp.csc_matrix(P))
    with compiled_code(True):
        finite, defect, scale, diagonal = p_checks(M.indptr, M.indices, M.data)
    assert finite == bool(np.all(np.isfinite(M.data)))
    if finite:
        assert (defect, scale) == _symmetry_defect(M)
        assert diagonal == bool(np.all(M.indices == np.repeat(np.arange(6), np.diff(M.indptr))))
