"""The benchmark commands: the resumable sweep runner and a tiny smoke run of each target.

The benchmarks themselves never run here; these runs use the coarsest mesh and
two or three methods, and only check that the commands run, write their files
and resume without redoing finished cases.
"""
import csv
import json

import pytest

import admmkit
from admmkit.benchmarks.fixtures import methods
from admmkit.benchmarks.stability import study as stability
from admmkit.benchmarks.runner.sweep import append_result, case_id, load_results, run_sweep
from admmkit.cli import main


# ---------------------------------------------------------------- the sweep runner
def test_case_id_is_stable_and_order_free():
    a = {"scene": "ex1", "h": 0.025, "method": "sadmm"}
    b = {"method": "sadmm", "h": 0.025, "scene": "ex1"}
    assert case_id(a) == case_id(b) and len(case_id(a)) == 16
    assert case_id(a) != case_id(a | {"h": 0.05})


def test_results_file_keeps_whole_lines_and_skips_a_torn_one(tmp_path):
    path = tmp_path / "r.jsonl"
    append_result(path, {"id": "a", "result": {"x": 1}})
    append_result(path, {"id": "b", "result": {"x": 2}})
    with path.open("a") as fh:
        fh.write('{"id": "c", "result": ')       # an interrupted write
    done = load_results(path)
    assert set(done) == {"a", "b"} and done["b"]["result"] == {"x": 2}
    assert load_results(tmp_path / "missing.jsonl") == {}


def test_sweep_resumes_without_redoing_finished_cases(tmp_path):
    path = tmp_path / "r.jsonl"
    cases = [{"target": "t", "value": v, "group": "g" if v < 2 else "h"} for v in range(4)]
    append_result(path, {"id": case_id(cases[1]), "case": cases[1], "result": {"square": "from before"}})
    records = run_sweep(cases, "tests.benchmarks.test_benchmarks:square_case", path, workers=1, progress=False)
    assert len(records) == 4
    assert records[case_id(cases[1])]["result"] == {"square": "from before"}     # not redone
    assert records[case_id(cases[3])]["result"] == {"square": 9}
    assert "error" in records[case_id(cases[0])]                                  # a raising case is recorded
    assert records[case_id(cases[0])]["fault"] == "harness"                       # raised outside any rule
    lines = path.read_text().splitlines()
    assert len(lines) == 4
    run_sweep(cases, "tests.benchmarks.test_benchmarks:square_case", path, workers=1, progress=False)
    again = [json.loads(line)["case"]["value"] for line in path.read_text().splitlines()[4:]]
    assert again == [0]                        # only the harness failure runs again (#46 item 4), nothing finished
    with pytest.raises(ValueError, match="workers must be an integer >= 1"):
        run_sweep(cases, "tests.benchmarks.test_benchmarks:square_case", path, workers=0)


def square_case(case):
    """A sweep function for the test above (case 0 raises)."""
    if case["value"] == 0:
        raise RuntimeError("case zero fails on purpose")
    return {"square": case["value"] ** 2}


# ---------------------------------------------------------------- methods
def test_every_registered_policy_is_benchmarked_in_both_orders():
    labels = methods.admm_methods(rows=True)             # with the rules that set a penalty per row (QPs)
    assert labels[:3] == ["admm1", "admm2", "sadmm"]
    for name in admmkit.policy_names():
        if name in methods.skipped_policies():
            continue
        for order in ("xz", "zx"):
            assert methods.method_label(name, order) in labels
            assert methods.resolve(methods.method_label(name, order)) == (name, order)
    with pytest.raises(ValueError, match="unknown method 'sadm'"):
        methods.resolve("sadm")


def test_outcome_marks_false_convergence():
    assert stability.outcome({"status": "converged", "err": 1e-6}) == "converged"
    assert stability.outcome({"status": "converged", "err": 2e-3}) == "false_convergence"
    assert stability.outcome({"status": "max_iter", "err": 1e-9}) == "max_iter"
    assert stability.outcome({"status": "diverged"}) == "diverged"


# ---------------------------------------------------------------- smoke runs of the commands
def _rows(path):
    with open(path) as fh:
        return list(csv.DictReader(fh))


@pytest.mark.study
def test_bench_precision_smoke(tmp_path, capsys):
    out = tmp_path / "precision"
    argv = ["bench", "precision", "--out", str(out), "--scene", "ex1", "--h", "1/10", "--methods", "admm1,sadmm",
            "--repeats", "1", "--workers", "2", "--no-progress"]
    assert main(argv) == 0
    for name in ("precision.csv", "time_to_error.csv", "time_to_error.md", "precision_ex1.png",
                 "precision_ex1.svg", "README.md", "results.jsonl"):
        assert (out / name).stat().st_size > 0, name
    rows = _rows(out / "precision.csv")
    assert {r["method"] for r in rows} == {"admm1", "sadmm", "pdas", "clarabel", "cvxpy-osqp", "osqp"}
    pdas_final = [r for r in rows if r["method"] == "pdas"][-1]
    assert float(pdas_final["err"]) < 1e-10                 # the exact active-set solution
    sadmm = [float(r["err"]) for r in rows if r["method"] == "sadmm"]
    assert min(sadmm) < 1e-8 and max(sadmm) > 1e-3          # the ladder spans loose to tight
    readme = (out / "README.md").read_text()
    assert "## Machine" in readme and "admmkit bench precision" in readme and "Clarabel" in readme
    lines = (out / "results.jsonl").read_text().splitlines()
    assert main(argv) == 0                                   # resumed: nothing re-runs
    assert (out / "results.jsonl").read_text().splitlines() == lines
    assert "wrote" in capsys.readouterr().out


@pytest.mark.study
def test_bench_stability_smoke(tmp_path):
    out = tmp_path / "stability"
    assert main(["bench", "stability", "--out", str(out), "--quick", "--methods", "admm2,sadmm", "--workers", "1",
                 "--no-progress"]) == 0
    for name in ("stability.csv", "failures.md", "rho_sweep.png", "rho_sweep.svg", "mesh_sweep.png",
                 "mesh_error.svg", "README.md"):
        assert (out / name).stat().st_size > 0, name
    rows = _rows(out / "stability.csv")
    assert len(rows) == 2 * 3 * 2 + 2 * 2                   # rho: 2 examples x 3 rho x 2 methods; mesh: 2 x 2
    assert {r["outcome"] for r in rows} <= set(stability.OUTCOMES)
    sadmm = [r for r in rows if r["method"] == "sadmm"]
    assert all(r["outcome"] == "converged" for r in sadmm)
    assert "| sadmm |" in (out / "failures.md").read_text()


def test_bench_paper_compare_smoke(tmp_path):
    out = tmp_path / "paper"
    assert main(["bench", "paper-compare", "--out", str(out), "--quick", "--repeats", "1", "--workers", "1",
                 "--no-progress"]) == 0
    for name in ("times.csv", "times.md", "speedups.md", "speedups.png", "speedups.svg", "iterations.md", "README.md"):
        assert (out / name).stat().st_size > 0, name
    rows = _rows(out / "times.csv")
    assert len(rows) == 2 * 3 * 2                            # 2 examples x 3 methods x 2 rho at h = 1/10
    assert all(float(r["paper_s"]) > 0 and float(r["ours_s"]) > 0 for r in rows)
    speed = _rows(out / "speedups.csv")
    assert all(float(r["our_iteration_ratio"]) > 0 for r in speed)


def test_bench_bad_input(tmp_path, capsys):
    assert main(["bench", "precision", "--out", str(tmp_path), "--scene", "moon"]) == 2
    assert "unknown benchmark scene 'moon'" in capsys.readouterr().err
    assert main(["bench", "stability", "--out", str(tmp_path), "--methods", "sadm"]) == 2
    assert "--methods: unknown method 'sadm'" in capsys.readouterr().err
    assert main(["bench", "precision", "--workers", "0"]) == 2   # argparse's error: main() returns its code


def test_active_set_polish_sharpens_the_clarabel_reference():
    import numpy as np

    from admmkit.benchmarks.fixtures import families as scenes
    from admmkit.problems.qp import random_qp

    qp = random_qp(40, 60, kind="mixed", seed=3)
    d = scenes.Discrete(key="t", kind="qp", n=qp.n, P=qp.P, q=qp.q, A=qp.A, l=qp.l, u=qp.u, weights=np.ones(qp.m),
                        x_norm=np.linalg.norm, lam_norm=np.linalg.norm, norm_name="", make_admm=None, rho_unit=1.0)
    x, y, status, _ = scenes.clarabel_solve(d, 1e-6)
    assert status == "optimal"
    xp, yp, kkt = scenes.active_set_polish(d, x, y)
    assert max(kkt.values()) < 1e-10 < max(scenes._qp_kkt(d, x, y).values())
    assert np.linalg.norm(xp - x) <= 1e-4 * np.linalg.norm(x)      # the same solution, sharpened
