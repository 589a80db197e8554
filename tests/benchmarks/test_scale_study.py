"""``admmkit bench scale``: the accuracy of the computed solution next to the algebraic stop (small sizes)."""
import csv
import math

import pytest


@pytest.fixture
def accuracy_in_process(monkeypatch):
    """The study's cases run in this process, with the accuracy measurements (the subprocess path: below)."""
    from admmkit.benchmarks.contact import scale, scale_runs
    monkeypatch.setattr(scale, "run_in_subprocess", lambda example, h, mode, timeout=0, rho=1e3:
                        scale_runs.run_case(example, h, mode, accuracy=True) | {"wall_s": 0.0})


@pytest.mark.study   # bench scale end to end, child processes
def test_bench_scale_reports_zz_estimate_algebraic_error_and_error_against_finest(tmp_path, accuracy_in_process):
    from admmkit.benchmarks.contact.scale import run_scale_bench
    rows = run_scale_bench(out=tmp_path, hs=(1 / 5, 1 / 10, 1 / 20))
    for r in rows:
        assert r["status"] == "converged"
        assert 0 < r["last_change"] <= 1e-5                              # the stop's own quantity
        assert 0 < r["alg_error"] < 1e-3 and 0.01 < r["zz_rel"] < 0.5       # algebraic error far below ZZ
        assert r["zz"] == pytest.approx(r["zz_rel"] * r["u_energy"])
    coarse, middle, fine = rows
    assert coarse["zz_rel"] > middle["zz_rel"] > fine["zz_rel"]              # the estimate falls with h
    # the energy error against the finest run: only for sizes at least 3 times coarser (1/5 but not 1/10)
    assert math.isfinite(coarse["energy_error_rel"]) and "energy_error_rel" not in middle
    assert 0.3 < coarse["zz_rel"] / coarse["energy_error_rel"] < 3
    with open(tmp_path / "scale.csv") as fh:
        table = list(csv.DictReader(fh))
    assert {"zz_rel", "alg_error", "last_change", "energy_error_rel"} <= set(table[0])
    assert float(table[2]["zz_rel"]) == pytest.approx(fine["zz_rel"], rel=1e-5)
    text = (tmp_path / "scale.md").read_text()
    assert "## Accuracy at the stop" in text and "| ZZ rel. |" in text and "no guaranteed bound" in text
    assert f"| 1/20 | 1680 | converged | {fine['last_change']:.2e} | {fine['alg_error']:.2e} | " in text


@pytest.mark.study   # bench scale end to end, child processes
def test_the_child_process_measures_accuracy_only_when_asked_and_a_continued_run_agrees_with_the_reference(
        monkeypatch):
    from admmkit.benchmarks.contact import scale_runs
    plain = scale_runs.run_in_subprocess("ex1", 1 / 5, "iterative", timeout=120)
    assert plain["status"] == "converged" and "zz_rel" not in plain      # the other studies pay nothing
    measured = scale_runs.run_in_subprocess("ex1", 1 / 5, "iterative", timeout=120, accuracy=True)
    assert measured["reference"].startswith("cvxpy") and measured["alg_error"] < 1e-3
    monkeypatch.setattr(scale_runs, "REFERENCE_MAX_N", 10)        # above it: the run continued to a tight stop
    row = scale_runs.run_case("ex1", 1 / 5, "iterative", accuracy=True)
    assert row["zz_rel"] == pytest.approx(measured["zz_rel"], rel=1e-6) and row["accuracy_s"] > 0
    assert row["reference"].startswith("the run continued") and "converged" in row["reference"]
    assert row["alg_error"] == pytest.approx(measured["alg_error"], rel=1e-2)


def test_the_child_process_runs_in_the_stated_environment(monkeypatch, tmp_path):
    """run_in_subprocess hands the child CHILD_ENVIRONMENT (BLAS on one thread, no huge-page advice), and the
    report says so."""
    import json
    import subprocess
    from admmkit.benchmarks.contact import scale, scale_runs
    seen, real_run = {}, subprocess.run

    def fake_run(cmd, **kwargs):
        if "admmkit.benchmarks.contact.scale_runs" not in cmd:        # git, for the report's machine line
            return real_run(cmd, **kwargs)
        seen.update(kwargs["env"])
        row = {"example": "ex1", "h": 0.5, "mode": "iterative", "status": "refused", "message": "x"}
        return subprocess.CompletedProcess(cmd, 0, stdout=json.dumps(row) + "\n", stderr="")
    monkeypatch.setattr(scale_runs.subprocess, "run", fake_run)
    scale_runs.run_in_subprocess("ex1", 0.5, "iterative")
    assert {k: seen[k] for k in scale_runs.CHILD_ENVIRONMENT} == scale_runs.CHILD_ENVIRONMENT
    assert seen["NUMPY_MADVISE_HUGEPAGE"] == "0" and seen["OMP_NUM_THREADS"] == "1"
    calls = []
    monkeypatch.setattr(scale, "run_in_subprocess", lambda example, h, mode, timeout=0: calls.append(h) or
                        scale_runs.run_in_subprocess(example, h, mode, timeout=timeout))
    rows = scale.run_scale_bench(out=tmp_path, hs=(0.5,))
    assert calls == [scale.WARM_UP_H, 0.5] and len(rows) == 1     # an untimed warm-up first, not in the table
    text = (tmp_path / "scale.md").read_text()
    assert "`NUMPY_MADVISE_HUGEPAGE=0`" in text and "untimed one at h = 1/10" in text
