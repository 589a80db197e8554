"""The QP plug-in against an independent cvxpy (Clarabel) solve of the same QP."""
from pathlib import Path

import numpy as np
import pytest

import policies  # noqa: F401  (registers the rules by name)
from admmkit import ResidualTolerance, Status, solve
from problems.qp import QP, list_problems, load_mat, random_qp
from problems.qp.reference import solve_with_cvxpy

MM = Path(__file__).resolve().parents[2] / "shared" / "data" / "maros_meszaros"
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
