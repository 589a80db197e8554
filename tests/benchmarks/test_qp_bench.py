"""The QP policy benchmark: OSQP's termination test, the statistics, and a smoke run on tiny MAT files.

The tests that read the Maros-Meszaros set skip when ../shared/data/maros_meszaros is absent.
"""
import csv
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.io
import scipy.sparse as sp

import admmkit
from admmkit.problems.qp import load_mat, random_qp
from admmkit.benchmarks.qp.maros_meszaros import (kkt_form_reason, performance_profile, run_benchmark, shifted_geometric_mean,
                                       skip_reason, summarize)
from admmkit.benchmarks.qp.maros_meszaros_stats import target
from admmkit.benchmarks.qp.maros_meszaros_runs import run_admmkit, run_osqp
from admmkit.problems.qp import osqp_settings, solve_qp, textbook_settings
from admmkit.problems.qp.reference import solve_with_cvxpy
from admmkit.problems.qp.termination import OSQPTermination, osqp_relative_residuals, osqp_residuals, osqp_satisfied

MM = Path(__file__).resolve().parents[3] / "shared" / "data" / "maros_meszaros"
needs_mm = pytest.mark.skipif(not MM.is_dir(), reason=f"Maros-Meszaros data not found at {MM}")


def save_mat(qp, path):
    l = np.where(np.isfinite(qp.l), qp.l, -1e20)
    u = np.where(np.isfinite(qp.u), qp.u, 1e20)
    scipy.io.savemat(str(path), {"P": qp.P, "q": qp.q, "A": qp.A, "l": l, "u": u, "r": qp.r})


@pytest.mark.parametrize("order", ["xz", "zx"])
def test_osqp_termination_certifies_the_cvxpy_solution(order):
    qp = random_qp(30, 45, kind="mixed", seed=2)
    x_ref, lam_ref, _ = solve_with_cvxpy(qp)
    stop = OSQPTermination(qp, eps=(1e-3, 1e-6))
    recs = []
    res = admmkit.solve(qp, rho=0.1, policy="wohlberg", order=order, stop=stop, max_iter=20_000,
                        callback=recs.append)
    assert res.converged and set(stop.met) == {1e-3, 1e-6}
    assert stop.met[1e-3][0] <= stop.met[1e-6][0] == res.iterations
    assert np.linalg.norm(res.x - x_ref) <= 1e-4 * max(1.0, np.linalg.norm(x_ref))
    # the reference itself passes the test, a perturbed point does not
    Ax = qp.A @ x_ref
    assert osqp_satisfied(osqp_residuals(qp, x_ref, np.clip(Ax, qp.l, qp.u), lam_ref), 1e-6)
    assert not osqp_satisfied(osqp_residuals(qp, x_ref + 0.1, np.clip(Ax, qp.l, qp.u), lam_ref), 1e-3)
    r, s = osqp_relative_residuals(qp)(recs[-1])       # the last record before the stop
    assert 0 <= r < 1e-5 and 0 <= s < 1e-5


def test_statistics():
    assert shifted_geometric_mean([10.0, 40.0]) == pytest.approx(math.sqrt(20 * 50) - 10)
    assert shifted_geometric_mean([0.0, 0.0]) == pytest.approx(0.0)
    rows = [dict(problem=p, variant="preset", solver=s, order="xz", eps=1e-3, solved=ok, neutral=ok, iterations=it,
                 time=t, factorizations=1, rho_max=1.0, status="solved" if ok else "max_iter")
            for p, s, ok, it, t in [("a", "s1", True, 10, 1.0), ("a", "s2", True, 20, 4.0),
                                    ("b", "s1", False, 100, 9.0), ("b", "s2", True, 50, 2.0)]]
    rows += [dict(problem=p, variant="default", solver="OSQP", order="-", eps=1e-3, solved=True, neutral=ok,
                  iterations=5, time=0.5, factorizations=1, rho_max=1.0, status="solved")
             for p, ok in (("a", True), ("b", False))]     # b: OSQP said solved, the neutral criteria say no
    prof = performance_profile(rows, "time", 1e-3)
    taus, frac = prof[("preset", "s1", "xz")]
    assert frac[0] == 0.0 and frac[-1] == 0.5            # a: 2x OSQP's time; fails b
    taus, frac = prof[("preset", "s2", "xz")]
    assert frac[0] == 0.5 and frac[np.searchsorted(taus, 8.0)] == 1.0
    summary = {(s["solver"]): s for s in summarize(rows, max_iter=100, time_limit=10.0)}
    assert summary["s1"]["rate"] == 0.5 and summary["s1"]["failures"] == {"max_iter": 1}
    assert summary["s1"]["sgm_time"] == pytest.approx(math.sqrt(11 * 20) - 10)
    assert summary["OSQP"]["neutral"] == 1 and summary["OSQP"]["solved"] == 2
    assert summary["OSQP"]["failures"] == {"solved, neutral criteria not met": 1}
    (t,) = target(list(summary.values()))
    assert t["best"] == "preset/s2 (xz)" and t["best_neutral"] == 2 and t["osqp_neutral"] == 1 and t["met"]


def test_osqp_direct_run():
    qp = random_qp(20, 30, kind="mixed", seed=1)
    row = run_osqp(qp, 1e-6, max_iter=4000, time_limit=5.0)
    assert row["solved"] and row["neutral"] and row["solver"] == "OSQP" and row["iterations"] >= 1
    assert max(row["neutral_primal"], row["neutral_dual"], row["neutral_gap"]) <= 1e-6


@pytest.mark.study
@pytest.mark.parametrize("variant,order", [("preset", "xz"), ("preset", "zx"), ("textbook", "xz")])
def test_one_run_gives_the_looser_accuracy_of_a_run_stopped_there(variant, order):
    # the 1e-3 row of a run to 1e-6 is where a run asked for 1e-3 stops, and is judged at that iterate
    qp = random_qp(25, 40, kind="mixed", seed=4)
    rows = {r["eps"]: r for r in run_admmkit(qp, variant, "wohlberg", order, (1e-3, 1e-6), 4000, 5.0)}
    settings = osqp_settings() if variant == "preset" else textbook_settings()
    alone = solve_qp(qp, settings.replace(order=order, eps_abs=1e-3, eps_rel=0.0), policy="wohlberg")
    assert alone.termination == "solved" and rows[1e-3]["solved"]
    assert rows[1e-3]["iterations"] == alone.iterations < rows[1e-6]["iterations"]
    assert rows[1e-3]["neutral_dual"] == pytest.approx(alone.neutral["dual"], rel=1e-9, abs=1e-15)
    assert rows[1e-3]["neutral"] == (max(alone.neutral.values()) <= 1e-3)
    x_ref, _, obj_ref = solve_with_cvxpy(qp)
    tight = solve_qp(qp, settings.replace(order=order, eps_abs=1e-6, eps_rel=0.0), policy="wohlberg")
    assert rows[1e-6]["iterations"] == tight.iterations and rows[1e-6]["solved"] == (tight.termination == "solved")
    assert rows[1e-6]["neutral"] == (max(tight.neutral.values()) <= 1e-6)
    if (variant, order) == ("preset", "xz"):
        assert rows[1e-6]["neutral"]
    if rows[1e-6]["neutral"]:
        assert np.linalg.norm(tight.x - x_ref) <= 1e-3 * max(1.0, np.linalg.norm(x_ref))


@pytest.mark.study   # the whole Maros-Meszaros study, smoke-sized
def test_benchmark_smoke(tmp_path, capsys):
    data = tmp_path / "data"
    data.mkdir()
    save_mat(random_qp(15, 20, kind="mixed", seed=1), data / "RAND1.mat")
    save_mat(random_qp(10, 12, kind="inequality", seed=2), data / "RAND2.mat")
    dense = random_qp(40, 5, kind="equality", seed=3)
    dense.A = sp.csc_matrix(np.ones((5, 40)))             # dense rows: A'A is full (bound 5 x 40^2 + nnz P)
    dense.l, dense.u = np.full(5, -1.0), np.full(5, 1.0)
    save_mat(dense, data / "DENSE.mat")
    # reduced form: up to 5 x 40^2 + nnz(P) entries; KKT form: nnz(P) + 2 x 200 + 45
    assert skip_reason(data / "DENSE.mat", nnz_limit=1000) is not None
    assert skip_reason(data / "DENSE.mat", nnz_limit=3000) is None          # its KKT form fits
    out = tmp_path / "out"
    from admmkit.cli import main
    code = main(["bench", "qp", "--data", str(data), "--out", str(out), "--policies", "wohlberg,osqp",
                 "--variants", "preset,textbook,polish", "--max-iter", "3000", "--time-limit", "5", "--quiet"])
    assert code == 0
    for name in ("README.md", "results.csv", "summary.csv", "profiles_iterations.png", "profiles_time.svg"):
        assert (out / name).stat().st_size > 0, name
    with (out / "results.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    # 3 problems (the dense one runs here: its bound is small) x ((2 rules x 2 orders x 2 variants + polish) x 2
    # accuracies + OSQP with and without polishing x 2 accuracies)
    assert len(rows) == 3 * (9 * 2 + 4)
    assert {r["solver"] for r in rows} == {"wohlberg", "osqp", "OSQP"}
    assert {r["variant"] for r in rows} == {"preset", "textbook", "polish", "default"}
    assert all(r["neutral"] == "True" for r in rows if r["variant"] == "preset" and r["solver"] == "osqp")
    text = (out / "README.md").read_text()
    assert "admmkit bench qp --data" in text and "## eps = 1e-06" in text and "## Skipped" in text
    assert "## Targets" in text and "preset/osqp (xz)" in text
    # a low fill limit lists the dense problem as skipped, with the reason
    res = run_benchmark(data, tmp_path / "out2", policy_names=["aadmm"], orders=["zx"], max_iter=500,
                        time_limit=5.0, nnz_limit=1000, osqp_direct=False, progress=False, variants=["preset"])
    assert set(res["skipped"]) == {"DENSE"} and "DENSE" in (tmp_path / "out2" / "README.md").read_text()
    assert {r["problem"] for r in res["rows"]} == {"RAND1", "RAND2"}


def test_benchmark_bad_input(tmp_path):
    with pytest.raises(ValueError, match="workers must be 1 or 2"):
        run_benchmark(tmp_path, tmp_path / "o", workers=3)
    with pytest.raises(ValueError, match="unknown policies"):
        run_benchmark(tmp_path, tmp_path / "o", policy_names=["nope"])
    with pytest.raises(ValueError, match="variants must be among"):
        run_benchmark(tmp_path, tmp_path / "o", variants=["turbo"])
    with pytest.raises(FileNotFoundError):
        run_benchmark(tmp_path / "missing", tmp_path / "o")


@needs_mm
def test_maros_meszaros_hs35_against_cvxpy():
    qp = load_mat(MM / "HS35.mat")
    x_ref, _, obj_ref = solve_with_cvxpy(qp)
    for name in ("wohlberg", "osqp", "aadmm", "summable_steps", "quantized"):
        stop = OSQPTermination(qp, 1e-6)
        res = admmkit.solve(qp, rho=0.1, policy=name, order="zx", stop=stop, max_iter=5000)
        assert res.converged, name
        assert abs(res.objective - obj_ref) <= 1e-4 * max(1.0, abs(obj_ref)), name


@needs_mm
def test_maros_meszaros_dense_row_problems_run_in_kkt_form():
    # BOYD1 has a row of A with all 93261 entries: A'A would be dense, the KKT matrix is not
    assert skip_reason(MM / "BOYD1.mat") is None and kkt_form_reason(MM / "BOYD1.mat") is not None
    assert load_mat(MM / "BOYD1.mat").xstep == "kkt"
    assert kkt_form_reason(MM / "HS21.mat") is None and load_mat(MM / "HS21.mat").xstep == "reduced"


@needs_mm
def test_a_nonconvex_problem_is_skipped_with_the_reason():
    # VALUES: P has an eigenvalue of about -1.27e-5; load_mat refuses it, the study lists it as skipped
    why = skip_reason(MM / "VALUES.mat")
    assert why is not None and "not a convex QP" in why and "-1.27e-05" in why
    assert skip_reason(MM / "HS21.mat") is None


def test_a_worker_loads_the_qp_kernels_once_before_its_first_timed_case(monkeypatch):
    """bench qp's worker warms admmkit's kernels before its first case (no case's time holds their load) and only
    once; afterwards compiled="auto" takes the compiled path on a small QP too."""
    from admmkit.benchmarks.qp import maros_meszaros
    from admmkit.problems.qp.segment import AVAILABLE, compiled_pays
    calls = []
    from admmkit.benchmarks.qp import maros_meszaros_runs as harness
    monkeypatch.setattr(maros_meszaros, "_WARM", [])
    monkeypatch.setattr(harness, "_WARM", [])            # the kernels' own once-per-process flag
    import admmkit.benchmarks.framework.warm_up as warm_up
    original = warm_up.qp_kernels
    monkeypatch.setattr(warm_up, "qp_kernels", lambda: (calls.append(1), original())[1])
    maros_meszaros.warm_worker()
    maros_meszaros.warm_worker()
    assert calls == [1]
    if AVAILABLE:
        assert compiled_pays(2, 3, 5)            # HS21's size: compiled once the kernels are in the process
