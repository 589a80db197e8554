"""The QP plug-in against an independent cvxpy (Clarabel) solve of the same QP."""
from pathlib import Path

import numpy as np
import pytest

from admmkit import ResidualTolerance, Status, solve
from admmkit.problems.qp import QP, list_problems, load_mat, random_qp
from admmkit.problems.qp.reference import solve_with_cvxpy

MM = Path(__file__).resolve().parents[3] / "shared" / "data" / "maros_meszaros"
TIGHT = dict(tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12)


def rel(a, b):
    return np.linalg.norm(a - b) / max(1.0, np.linalg.norm(b))


@pytest.mark.parametrize("kind", ["inequality", "equality", "mixed"])
@pytest.mark.parametrize("policy, order", [("fixed", "xz"), ("fixed", "zx"), ("residual_balancing", "xz"),
                                           ("residual_balancing", "zx")])
def test_random_qps_match_cvxpy(kind, policy, order):
    qp = random_qp(30, 40, kind=kind, seed=1)
    x_ref, lam_ref, obj_ref = solve_with_cvxpy(qp, **TIGHT)
    res = solve(qp, rho=1.0, policy=policy, order=order, stop=ResidualTolerance(1e-10, 1e-10), max_iter=20_000)
    assert res.status is Status.CONVERGED
    assert rel(res.x, x_ref) < 1e-6
    assert abs(res.objective - obj_ref) < 1e-6 * max(1.0, abs(obj_ref))
    assert rel(res.lam, lam_ref) < 1e-6
    assert res.kkt["dual"] < 1e-6 and res.kkt["infeasibility"] < 1e-8


def test_summable_on_an_inequality_qp():
    qp = random_qp(30, 40, kind="inequality", seed=1)
    x_ref, _, obj_ref = solve_with_cvxpy(qp, **TIGHT)
    res = solve(qp, rho=1.0, policy="summable", order="zx", stop=ResidualTolerance(1e-10, 1e-10))
    assert res.converged and rel(res.x, x_ref) < 1e-6 and res.rho_changes > 0


def test_factorisations_are_cached_per_rho():
    qp = random_qp(20, 25, kind="inequality", seed=2)
    res = solve(qp, rho=1.0, policy="residual_balancing", order="zx", stop=ResidualTolerance(1e-10, 1e-10))
    distinct_rho = len(set(res.history["rho"]))
    assert res.counters["factorizations"] == distinct_rho
    assert res.counters["solves"] == res.iterations
    again = solve(qp, rho=1.0, policy="residual_balancing", order="zx", stop=ResidualTolerance(1e-10, 1e-10))
    assert again.counters["factorizations"] == 0  # every rho already seen


# small Maros-Meszaros problems with a unique solution
MM_CASES = ["HS35", "HS51", "HS52", "HS53", "HS76", "GENHS28", "TAME", "ZECEVIC2", "LOTSCHD", "QPTEST"]


@pytest.mark.skipif(not MM.is_dir(), reason=f"Maros-Meszaros data not found at {MM}")
@pytest.mark.parametrize("name", MM_CASES)
def test_maros_meszaros_match_cvxpy(name):
    qp = load_mat(MM / f"{name}.mat")
    x_ref, _, obj_ref = solve_with_cvxpy(qp, **TIGHT)
    res = solve(qp, rho=1.0, policy="residual_balancing", order="zx", stop=ResidualTolerance(1e-10, 1e-10),
                max_iter=20_000)
    assert res.converged
    assert rel(res.x, x_ref) < 1e-6
    assert abs(res.objective - obj_ref) < 1e-6 * max(1.0, abs(obj_ref))


@pytest.mark.skipif(not MM.is_dir(), reason=f"Maros-Meszaros data not found at {MM}")
def test_loader_reads_every_file_and_infinite_bounds():
    files = list_problems(MM)
    assert len(files) == 137
    qp = load_mat(MM / "HS21.mat")
    assert qp.n == 2 and qp.m == 3 and qp.u[0] == np.inf and qp.r == -100


def test_loader_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="QP file not found"):
        load_mat(tmp_path / "missing.mat")
    import scipy.io
    scipy.io.savemat(tmp_path / "partial.mat", {"P": np.eye(2), "q": np.zeros(2)})
    with pytest.raises(ValueError, match="lacks the field"):
        load_mat(tmp_path / "partial.mat")
    (tmp_path / "junk.mat").write_text("not a mat file")
    with pytest.raises(ValueError, match="not a readable MAT file"):
        load_mat(tmp_path / "junk.mat")
    with pytest.raises(FileNotFoundError, match="QP folder not found"):
        list_problems(tmp_path / "nope")


@pytest.mark.parametrize("change, match", [
    (dict(P=np.ones((2, 3))), "P must be square"),
    (dict(P=np.array([[1.0, 2.0], [0.0, 1.0]])), "P must be symmetric"),
    (dict(q=np.zeros(3)), "q must have length n = 2"),
    (dict(A=np.ones((3, 3))), "A must have n = 2 columns"),
    (dict(l=np.zeros(2)), "l must have length m = 3"),
    (dict(l=np.array([0.0, 2.0, 0.0]), u=np.array([1.0, 1.0, 1.0])), "l must be <= u; row 1"),
    (dict(q=np.array([np.nan, 0.0])), "q must be finite"),
    (dict(u=np.array([1.0, np.nan, 1.0])), "u must not contain NaN"),
])
def test_qp_validation(change, match):
    data = dict(P=np.eye(2), q=np.zeros(2), A=np.ones((3, 2)), l=-np.ones(3), u=np.ones(3))
    data.update(change)
    with pytest.raises(ValueError, match=match):
        QP(**data)
    with pytest.raises(ValueError, match="sigma must be"):
        QP(np.eye(2), np.zeros(2), np.ones((3, 2)), -np.ones(3), np.ones(3), sigma=-1)


# -- the KKT form of the x-step ------------------------------------------------------------------------
def _with_xstep(qp, xstep, **kw):
    return QP(qp.P, qp.q, qp.A, qp.l, qp.u, qp.r, name=qp.name, xstep=xstep, **kw)


@pytest.mark.parametrize("backend", ["superlu", "qdldl"])
def test_kkt_form_gives_the_reduced_iterates(backend):
    if backend == "qdldl":
        pytest.importorskip("qdldl")
    qp = random_qp(30, 40, kind="mixed", seed=4)
    runs = [solve(_with_xstep(qp, xs, **({"backend": backend} if xs == "kkt" else {})), rho=0.5,
                  policy="residual_balancing", order=order, stop=ResidualTolerance(1e-12, 1e-12), max_iter=300)
            for order in ("xz", "zx") for xs in ("reduced", "kkt")]
    for reduced, kkt in (runs[0:2], runs[2:4]):
        assert kkt.iterations == reduced.iterations
        assert rel(kkt.x, reduced.x) < 1e-9 and rel(kkt.lam, reduced.lam) < 1e-9
        assert kkt.counters["factorizations"] == reduced.counters["factorizations"]


def test_kkt_form_matches_cvxpy():
    qp = _with_xstep(random_qp(25, 30, kind="inequality", seed=5), "kkt")
    x_ref, lam_ref, obj_ref = solve_with_cvxpy(qp, **TIGHT)
    res = solve(qp, rho=1.0, policy="osqp", order="xz", stop=ResidualTolerance(1e-10, 1e-10), max_iter=20_000)
    assert res.converged and rel(res.x, x_ref) < 1e-6 and rel(res.lam, lam_ref) < 1e-6


def test_auto_takes_the_kkt_form_when_a_row_of_A_is_dense(monkeypatch):
    import admmkit.problems.qp.problem as qp_module
    qp = random_qp(40, 5, kind="equality", seed=3)
    assert _with_xstep(qp, "auto").xstep == "reduced"
    monkeypatch.setattr(qp_module, "REDUCED_MAX_NNZ", 10.0)   # any A'A is "too dense" now
    assert _with_xstep(qp, "auto").xstep == "kkt"


def test_kkt_form_bad_input():
    qp = random_qp(10, 12, kind="mixed", seed=6)
    with pytest.raises(ValueError, match="xstep must be one of auto, reduced, kkt"):
        _with_xstep(qp, "normal")
    with pytest.raises(ValueError, match="backend for xstep 'kkt'"):
        _with_xstep(qp, "kkt", backend="cholmod")
