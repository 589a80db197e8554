"""admmkit's QP preset in the studies (#50 items 2-4): ``bench rules --presets``, qpbenchmark's class, the split."""
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from admmkit.benchmarks.qp import maros_meszaros_runs as runs
from admmkit.benchmarks.qp.qp_rules_report import split
from admmkit.benchmarks.rules import cases as rank_cases, report as rank_report, study as rank
from admmkit.cli import main
from admmkit.problems.qp.settings import ADMMKIT_MAX_ITER

DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "maros_meszaros"


def test_qpbenchmark_counts_no_bound_row_as_a_constraint():
    P = sp.eye(4)
    A = sp.vstack([sp.eye(4), sp.csr_matrix(np.ones((2, 4))), sp.csr_matrix([[0, 0, 3.0, 0]])])
    assert rank.qp_size(P, A) == 4 + 2                    # the five single-entry rows are bounds


def test_the_admmkit_preset_runs_each_rule_a_second_time_under_its_own_cap(tmp_path):
    (tmp_path / "HS21.mat").write_bytes(b"")
    cases = rank.build_cases(["osqp"], [None], ["qp"], quick=True, data=tmp_path, presets=["osqp", "admmkit"])
    assert [(c.get("preset"), c["max_iter"]) for c in cases] == [(None, rank.QP_MAX_ITER), ("admmkit", None)]
    assert [rank_report.config_of(c) for c in cases] == ["osqp", "osqp@admmkit"]
    assert runs.settings_for("admmkit", "xz", 1e-6, None, 5.0).max_iter == ADMMKIT_MAX_ITER
    assert runs.settings_for("preset", "xz", 1e-6, 4000, 5.0).max_iter == 4000


@pytest.mark.parametrize("presets", [["admmkit", "admmkit"], ["scs"], []])
def test_bad_presets_are_refused_naming_the_option(presets):
    with pytest.raises(ValueError, match="--presets"):
        rank.check_presets(presets)


def test_bad_presets_on_the_command_line_one_line_exit_2(capsys):
    code = main(["bench", "rules", "--families", "qp", "--presets", "osqp,clarabel", "--out", "/tmp/never_written"])
    assert code == 2
    err = capsys.readouterr().err
    assert "admmkit: error: --presets" in err and "Traceback" not in err


def test_the_split_alternates_over_the_sorted_names():
    assert split(["B", "A", "D", "C"]) == {"A": "train", "B": "test", "C": "train", "D": "test"}


@pytest.mark.skipif(not (DATA / "HS118.mat").exists(), reason="Maros-Meszaros data not found")
def test_the_qp_case_in_admmkit_preset_is_judged_as_the_others():
    case = {"file": "HS118.mat", "rule": "osqp", "order": "xz", "eps": [1e-3, 1e-6], "time_limit": 5.0}
    import os
    os.environ[rank_cases.DATA_ENV] = str(DATA)
    plain = rank_cases.run_qp(case | {"max_iter": 4000})
    ours = rank_cases.run_qp(case | {"max_iter": None, "preset": "admmkit"})
    assert all(r["solved"] for r in plain + ours)
    assert [r["iterations"] for r in ours] < [r["iterations"] for r in plain]       # polished before OSQP's stop


def test_the_results_page_counts_successes_and_false_converged(tmp_path, monkeypatch):
    from admmkit.benchmarks.qp import qp_rules_report as page
    from admmkit.benchmarks.qp.maros_meszaros_report import FIELDS, write_rows
    rows = []
    for problem, ours, osqp in (("A", (True, True), (True, True)), ("B", (True, False), (False, False)),
                                ("C", (True, True), (False, False)), ("D", (False, False), (True, True))):
        for (variant, solver), (solved, neutral) in ((("admmkit", "osqp"), ours), (("preset", "osqp"), osqp),
                                                     (("default", "OSQP"), osqp)):
            rows.append({f: 0 for f in FIELDS} | {"problem": problem, "variant": variant, "solver": solver,
                                                  "order": "xz", "eps": 1e-6, "solved": solved, "neutral": neutral,
                                                  "status": "solved", "iterations": 10, "time": 0.5})
    write_rows(rows, tmp_path / "results.csv")
    monkeypatch.setattr(page, "qp_class", lambda data: {"A", "B", "C", "D"})
    text = page.report(tmp_path / "results.csv", tmp_path, tmp_path).read_text()
    assert "| admmkit_settings | 2/4 | 2/4 | 2/2 | 0/2 | B |" in text          # A, C train; B "solved", not neutral
    assert "lost against `osqp_settings`: D" in text and "gained against OSQP 1.1: C" in text
    assert (tmp_path / "profiles_iterations.png").stat().st_size > 0


@pytest.mark.skipif(not (DATA / "HS21.mat").exists(), reason="Maros-Meszaros data not found")
def test_a_worker_compiles_the_qp_kernels_once_before_its_first_timed_case(monkeypatch):
    """CI's cold numba cache put 4 s of compilation into HS118's first timed run, over its 5 CPU s limit."""
    import os
    from admmkit.benchmarks.framework import warm_up
    calls = []
    monkeypatch.setattr(warm_up, "qp_kernels", lambda: calls.append(True))
    from admmkit.benchmarks.qp import maros_meszaros_runs as harness
    monkeypatch.setattr(harness, "_WARM", [])
    monkeypatch.setitem(os.environ, rank_cases.DATA_ENV, str(DATA))
    case = {"file": "HS21.mat", "rule": "osqp", "order": "xz", "eps": [1e-3], "time_limit": 5.0, "max_iter": 4000}
    for _ in range(2):
        assert rank_cases.run_qp(case)[0]["solved"]
    assert calls == [True]


@pytest.mark.skipif(not (DATA / "HS21.mat").exists(), reason="Maros-Meszaros data not found")
def test_after_the_warm_up_a_timed_qp_case_compiles_nothing():
    """The harness's runs (its callback reads the tested iterations: the segment without the test in its kernel)
    load or compile no kernel inside a timed case once the workers' warm-up ran: CI's cold cache put 4 s of
    segment._xz_kkt into HS118's first timed run, over its 5 CPU s."""
    from admmkit import kernels
    if not kernels.AVAILABLE:
        pytest.skip("numba is not installed: nothing is compiled")
    from admmkit.benchmarks.framework.warm_up import qp_kernels
    from admmkit.benchmarks.qp.maros_meszaros_runs import run_admmkit
    from admmkit.problems.qp.mat import load_mat

    def signatures():        # every kernel's specialisations in this process (compiled or loaded from the cache)
        return {(k.py_func.__module__, k.py_func.__name__, sig) for ks in kernels.KERNELS.values() for k in ks
                if k._dispatcher is not None for sig in k._dispatcher.signatures}
    qp_kernels()
    before = signatures()
    qp = load_mat(DATA / "HS21.mat")
    for variant, cap in (("preset", 4000), ("admmkit", None)):
        rows = run_admmkit(qp, variant, "osqp", "xz", (1e-3, 1e-6), cap, 5.0)
        assert all(r["solved"] for r in rows)
    assert {name for _, name, _ in signatures() - before} == set()
