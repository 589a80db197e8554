"""Studies tell the truth (#46 item 4): a missing package refuses in one line; a harness failure is no rule's.

A missing package is simulated with ``sys.modules[name] = None`` (an import then raises ImportError and
``importlib.util.find_spec`` finds nothing).  Every case function here is tiny; the workers run in this
process (``--workers 1``), where the monkeypatches hold.
"""
import csv
import sys
from pathlib import Path

import numpy as np
import pytest

import admmkit
from admmkit.benchmarks.rules import cases as rank_cases, report as rank_report
from admmkit.benchmarks.runner.harness import (HarnessFailed, MissingPackage, fault_of, is_harness_failure,
                                               require)
from admmkit.benchmarks.runner.sweep import load_results, run_sweep
from admmkit.benchmarks.runner.sweep_worker import run_case
from admmkit.cli import main

FLAKY = f"{__name__}:flaky_case"


def flaky_case(case):
    """{"value": v} -> its square; with ``marker``: an ImportError (the harness's) until the marker exists."""
    if case.get("marker") and not Path(case["marker"]).exists():
        import no_such_package_for_the_test  # noqa: F401
    return {"square": case["value"] ** 2}


class Broken(admmkit.Policy):
    """A rule whose own update raises: its failure is the rule's."""

    def update(self, state):
        raise ArithmeticError("the rule's own bug")


def without_cost_line(err: list[str]) -> list[str]:
    """stderr's lines without a study's announcement of its cost (benchmarks/runner/costs.py), which comes first."""
    from admmkit.benchmarks.runner.costs import COSTS
    return err[1:] if err and any(err[0] == f"{name}: {cost.text}" for name, cost in COSTS.items()) else err


def one_line(capsys) -> str:
    err = without_cost_line(capsys.readouterr().err.strip().splitlines())
    assert len(err) == 1, err
    return err[0]


# ---------------------------------------------------------------- a missing package: one line, exit 2, no work
@pytest.mark.parametrize("module, argv", [
    ("cvxpy", ["bench", "rules", "--quick"]),
    ("cvxpy", ["bench", "policies", "--quick"]),
    ("cvxpy", ["bench", "precision", "--quick"]),
    ("cvxpy", ["bench", "stability", "--quick"]),
    ("cvxpy", ["bench", "obstacle", "--quick"]),
    ("cvxpy", ["bench", "friction", "--quick"]),
    ("cvxpy", ["bench", "four-problems"]),
    ("cvxpy", ["bench", "qp-agreement"]),
    ("cvxpy", ["reproduce", "paper", "--quick"]),
    ("clarabel", ["reproduce", "paper", "--quick"]),
    ("osqp", ["bench", "qp-speed", "--data", "{data}"]),
    ("osqp", ["bench", "qp-fidelity", "--data", "{data}"]),
    ("numba", ["bench", "anderson-cost", "--data", "{data}"]),
    ("osqp", ["bench", "qp", "--data", "{data}"]),
    ("distributed", ["bench", "executors", "--quick"]),
    ("dask", ["bench", "precision", "--quick", "--dask-workers", "2"]),
    ("distributed", ["bench", "policies", "--quick", "--scheduler", "tcp://127.0.0.1:1"]),
])
def test_a_study_refuses_at_once_when_a_package_is_missing(module, argv, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, module, None)
    data = tmp_path / "data"
    data.mkdir()
    out = tmp_path / "out"
    code = main([a.replace("{data}", str(data)) for a in argv] + ["--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err                                 # the refusal alone: no cost announced before it
    line = err[0]
    command = " ".join(argv[:2])
    assert code == 2 and line.startswith(f"admmkit: error: {command} needs ")
    assert "pip install" in line and ("admmkit[sweep]" in line) == (module in ("dask", "distributed"))
    assert not out.exists()                                   # nothing ran, nothing written


def test_require_names_the_command_the_module_and_the_pip_command(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    expected = r'^bench executors needs dask.distributed: pip install "admmkit\[sweep\]"$'
    with pytest.raises(MissingPackage, match=expected):
        require("bench executors", "numpy", "distributed")
    require("bench executors", "numpy")                        # present: nothing said


def test_report_only_needs_no_reference_solver(tmp_path, monkeypatch, capsys):
    """--report-only runs nothing: an empty folder is the flag's error, not cvxpy's."""
    monkeypatch.setitem(sys.modules, "cvxpy", None)
    code = main(["bench", "rules", "--quick", "--families", "framework", "--report-only", "--out", str(tmp_path)])
    line = one_line(capsys)
    assert code == 2 and "--report-only" in line and "holds no finished case" in line
    assert not (tmp_path / "README.md").exists()


@pytest.mark.parametrize("study, results", [("stability", "results.jsonl"), ("precision", "results.jsonl"),
                                            ("paper-compare", "results.jsonl"), ("policies", "results.jsonl"),
                                            ("obstacle", "sweep/results.jsonl")])
def test_report_only_on_an_empty_folder_is_one_line(study, results, tmp_path, capsys):
    code = main(["bench", study, "--quick", "--report-only", "-q", "--out", str(tmp_path)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and err == [f"admmkit: error: --report-only: {tmp_path / results} holds no finished case of "
                                 "this grid; run the same command without --report-only first"]
    assert not list(tmp_path.glob("*.md")) and not list(tmp_path.glob("*.png"))


# ---------------------------------------------------------------- whose failure a failed case is
def _solve_with(rule):
    def case(_case):
        from admmkit.problems.qp import QP
        qp = QP(np.eye(2), np.ones(2), np.eye(2), -np.ones(2), np.ones(2))
        return {"status": admmkit.solve(qp, policy=rule, max_iter=20).status.value}
    return case


def test_an_exception_inside_the_rule_is_the_rules():
    rec = run_case(_solve_with(Broken()), "id", {"value": 1})
    assert rec["error"].startswith("ArithmeticError") and rec["fault"] == "case" and not is_harness_failure(rec)


@pytest.mark.parametrize("error", [ImportError("No module named 'cvxpy'"), RuntimeError("a bug in the study")])
def test_an_exception_outside_the_rule_is_the_harnesss(error):
    def case(_case):
        raise error
    rec = run_case(case, "id", {"value": 1})
    assert rec["fault"] == "harness" and is_harness_failure(rec)


def test_an_import_error_inside_a_rule_is_still_the_harnesss():
    class NeedsAPackage(admmkit.Policy):
        def update(self, state):
            import no_such_package_for_the_test  # noqa: F401
    rec = run_case(_solve_with(NeedsAPackage()), "id", {})
    assert rec["error"].startswith("ModuleNotFoundError") and rec["fault"] == "harness"
    assert fault_of(ImportError("x")) == "harness"


def test_records_without_the_mark_are_judged_by_their_error():
    assert is_harness_failure({"error": "ModuleNotFoundError: No module named 'cvxpy'\n..."})
    assert is_harness_failure({"error": "WorkerDied: the worker process ended"})
    assert not is_harness_failure({"error": "CaseTimeout: over 5 s"})
    assert not is_harness_failure({"result": {"square": 1}})


def test_a_harness_failure_is_run_again_on_resume(tmp_path):
    marker = tmp_path / "installed"
    cases = [{"value": 2, "marker": str(marker)}, {"value": 3}]
    first = run_sweep(cases, FLAKY, tmp_path / "results.jsonl", workers=1, progress=False, table=False)
    assert sorted(bool(is_harness_failure(r)) for r in first.values()) == [False, True]
    marker.touch()                                            # the package is "installed"
    again = run_sweep(cases, FLAKY, tmp_path / "results.jsonl", workers=1, progress=False, table=False)
    assert sorted(r["result"]["square"] for r in again.values()) == [4, 9]
    assert len((tmp_path / "results.jsonl").read_text().splitlines()) == 3       # only the failed case ran again
    assert all(not r.get("error") for r in load_results(tmp_path / "results.jsonl").values())


# ---------------------------------------------------------------- bench rules: nothing ranked on a harness failure
def _record(problem, rule, *, error=None, fault=None, iterations=10):
    case = {"family": "framework", "problem": problem, "rule": rule, "order": "xz", "rho0": 1.0,
            "acceleration": None}
    if error:
        return {"case": case, "result": None, "error": error, **({"fault": fault} if fault else {})}
    return {"case": case, "result": {"runs": [{"solved": True, "status": "solved", "iterations": iterations,
                                               "seconds": 0.01}]}}


def test_the_ranking_leaves_out_every_problem_with_a_harness_failure(tmp_path):
    records = {"1": _record("lasso", "fixed", iterations=10), "2": _record("lasso", "osqp", iterations=20),
               "3": _record("tv_2d", "fixed", iterations=5),
               "4": _record("tv_2d", "osqp", error="ModuleNotFoundError: No module named 'cvxpy'", fault="harness")}
    with pytest.raises(HarnessFailed, match=r"^1 of 4 cases failed in the harness \(ModuleNotFoundError: No module "
                                            r"named 'cvxpy'\); nothing ranked on them") as failed:
        rank_report.summarise(records, tmp_path, command="admmkit bench rules", wall=1.0, families=["framework"])
    assert tmp_path / "README.md" in failed.value.files
    rows = list(csv.DictReader((tmp_path / "runs.csv").open()))
    assert {r["problem"].split()[0] for r in rows} == {"problem=lasso"}       # tv_2d is out, for both rules
    readme = (tmp_path / "README.md").read_text()
    assert "1 cases failed in the harness" in readme and "| 1 | fixed | 1.000" in readme
    assert "tv_2d" not in (tmp_path / "failures.md").read_text()             # not the rule's failure


def test_a_rules_own_failure_is_ranked_as_its_failure(tmp_path):
    records = {"1": _record("lasso", "fixed"), "2": _record("lasso", "osqp", error="ArithmeticError: x", fault="case")}
    rank_report.summarise(records, tmp_path, command="admmkit bench rules", wall=1.0, families=["framework"])
    assert "ArithmeticError" in (tmp_path / "failures.md").read_text()
    assert "failed in the harness" not in (tmp_path / "README.md").read_text()


def _framework_runner(bad_problems):
    def runner(case):
        if case["problem"] in bad_problems:
            raise RuntimeError("the reference could not be built")    # outside the rule's code
        return [{"solved": True, "status": "solved", "iterations": 7 + len(case["rule"]), "seconds": 0.01}]
    return runner


def test_bench_rules_exits_1_and_ranks_nothing_on_harness_failures(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(rank_cases.RUNNERS, "framework", _framework_runner({"tv_2d"}))
    argv = ["bench", "rules", "--quick", "--rules", "fixed,osqp", "--acceleration", "none", "--families",
            "framework", "--workers", "1", "-q", "--out", str(tmp_path)]
    code = main(argv)
    captured = capsys.readouterr()
    err = without_cost_line(captured.err.strip().splitlines())
    assert code == 1 and len(err) == 1
    assert err[0] == ("admmkit: error: 12 of 48 cases failed in the harness (RuntimeError: the reference could not "
                      "be built); nothing ranked on them (their 6 problems left out for every configuration); fix it "
                      "and run the same command again: those cases run again")
    assert f"wrote {tmp_path / 'README.md'}" in captured.out
    problems = {r["problem"].split()[0] for r in csv.DictReader((tmp_path / "runs.csv").open())}
    assert problems == {"problem=lasso", "problem=box_ls_weighted", "problem=consensus_8"}
    # fixed: the harness runs them again, and the ranking is whole
    monkeypatch.setitem(rank_cases.RUNNERS, "framework", _framework_runner(set()))
    assert main(argv) == 0
    problems = {r["problem"].split()[0] for r in csv.DictReader((tmp_path / "runs.csv").open())}
    assert "problem=tv_2d" in problems and "failed in the harness" not in (tmp_path / "README.md").read_text()


def test_bench_rules_writes_no_ranking_when_every_case_failed_in_the_harness(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(rank_cases.RUNNERS, "framework", _framework_runner({"lasso", "box_ls_weighted",
                                                                           "consensus_8", "tv_2d"}))
    code = main(["bench", "rules", "--quick", "--rules", "fixed", "--acceleration", "none", "--families", "framework",
                 "--workers", "1", "-q", "--out", str(tmp_path)])
    line = one_line(capsys)
    assert code == 1 and line.startswith("admmkit: error: 24 of 24 cases failed in the harness")
    assert "no file written" in line and not (tmp_path / "README.md").exists()


# ---------------------------------------------------------------- bench policies
def test_bench_policies_keeps_harness_failures_out_of_its_tables(tmp_path, monkeypatch):
    from admmkit.benchmarks.policies import study as policies_fe

    def no_reference(h):
        raise ModuleNotFoundError("No module named 'cvxpy'")
    monkeypatch.setitem(policies_fe.PROBLEMS, "obstacle", no_reference)
    monkeypatch.setattr(policies_fe, "_CASES", {})
    with pytest.raises(HarnessFailed, match=r"^6 of 6 cases failed in the harness \(ModuleNotFoundError: No module "
                                            r"named 'cvxpy'\); no table written"):
        policies_fe.run(tmp_path, rules=("fixed",), quick=True, progress=False, workers=1, problems=("obstacle",))
    assert not (tmp_path / "README.md").exists() and not (tmp_path / "sweep.csv").exists()


# ---------------------------------------------------------------- reproduce: never a weaker reference
def test_reproduce_refuses_without_the_reference_solver_and_keeps_the_files(tmp_path, monkeypatch):
    from admmkit.benchmarks.contact import paper
    committed = tmp_path / "error_at_stop.md"
    committed.write_text("| ex1 | 1/10 | cvxpy + Clarabel, tol 1e-10 |\n")
    monkeypatch.setitem(sys.modules, "clarabel", None)
    with pytest.raises(MissingPackage, match="reproduce paper needs clarabel"):
        paper.run_reproduction(out=tmp_path, hs=(1 / 10,), rhos=(1e3,), progress=False)
    assert committed.read_text().startswith("| ex1 | 1/10 | cvxpy + Clarabel") and len(list(tmp_path.iterdir())) == 1


def test_reproduce_stops_before_writing_when_clarabel_falls_back(tmp_path, monkeypatch):
    from admmkit.benchmarks.contact import paper
    from admmkit.problems.contact.validation import reference

    def fallback(ops):
        """The reference as it is when Clarabel fails: the tight SADMM run."""
        ref = reference.reference_solution(ops)
        return reference.Reference(ref.u, ref.lam, "sadmm, ResidualTolerance(1e-12, 1e-12)", ref.kkt, ref.seconds)
    monkeypatch.setattr(paper, "reference_solution", fallback)
    committed = tmp_path / "error_at_stop.md"
    committed.write_text("committed\n")
    with pytest.raises(paper.WeakReference, match=r"ex1 h=1/10 is 'sadmm.*not cvxpy \+ Clarabel.*nothing written"):
        paper.run_reproduction(out=tmp_path, hs=(1 / 10,), rhos=(1e3,), progress=False, examples=("ex1",))
    assert committed.read_text() == "committed\n" and len(list(tmp_path.iterdir())) == 1


def test_reproduce_on_the_command_line_is_one_line(tmp_path, monkeypatch, capsys):
    from admmkit.benchmarks.contact import paper
    monkeypatch.setattr(paper, "REFERENCE_SOLVER", "a solver that is not there")
    code = main(["reproduce", "paper", "--quick", "-q", "--out", str(tmp_path)])
    line = one_line(capsys)
    assert code == 2 and "reproduce paper: the reference of ex1 h=1/10" in line and "nothing written" in line
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------- the QP studies' --problems
@pytest.fixture
def mm_folder(tmp_path):
    folder = tmp_path / "mm"
    folder.mkdir()
    for name in ("HS21", "HS35", "QAFIRO"):
        (folder / f"{name}.mat").write_bytes(b"")
    return folder


@pytest.mark.parametrize("study", ["qp-speed", "qp-fidelity"])
def test_an_unknown_problem_is_one_line_with_the_closest_names(study, mm_folder, tmp_path, capsys):
    code = main(["bench", study, "--data", str(mm_folder), "--problems", "HS2l", "--out", str(tmp_path / "out")])
    line = one_line(capsys)
    assert code == 2 and line == (f"admmkit: error: --problems: no problem named HS2l in --data {mm_folder}; "
                                  "did you mean HS21?")
    code = main(["bench", study, "--data", str(mm_folder), "--problems", "NOSUCH", "--out", str(tmp_path / "out")])
    line = one_line(capsys)
    assert code == 2 and line.endswith("no problem named NOSUCH in --data " + str(mm_folder)
                                       + "; it holds 3 problems, e.g. HS21, HS35, QAFIRO")
    assert not (tmp_path / "out").exists()


def test_qp_speed_on_a_missing_folder_is_one_line(tmp_path, capsys):
    code = main(["bench", "qp-speed", "--data", str(tmp_path / "nope"), "--out", str(tmp_path / "out")])
    assert code == 2 and one_line(capsys) == f"admmkit: error: --data: no folder {tmp_path / 'nope'}"


def test_the_harness_message_counts_other_causes():
    from admmkit.benchmarks.runner.harness import harness_message
    failed = [{"error": "ModuleNotFoundError: No module named 'cvxpy'"}] * 3 + [{"error": "WorkerDied: exit -9"}]
    text = harness_message(failed, 10)
    assert text.startswith("4 of 10 cases failed in the harness (ModuleNotFoundError: No module named 'cvxpy', "
                           "3 times; 1 other cause(s))")
