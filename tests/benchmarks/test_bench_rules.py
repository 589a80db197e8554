"""``admmkit bench rules`` (#26 item 2): the grid, the profiles, the ranking, a rule from a file, bad input."""
import csv
import math
import textwrap

import numpy as np
import pytest

from admmkit.benchmarks.rules import report as rank_report, study as rank
from admmkit.benchmarks.runner import profiles
from admmkit.cli import main
from admmkit.policy import canonical_spec

RULE = textwrap.dedent('''
    import admmkit
    from admmkit.policies.fixed import Fixed

    class MyFixed(Fixed):
        """The fixed rule under another name: it must rank exactly as 'fixed'."""
''')


@pytest.fixture
def rule_file(tmp_path):
    path = tmp_path / "outside" / "my_rule.py"
    path.parent.mkdir()
    path.write_text(RULE)
    return path


# ---------------------------------------------------------------- the profile arithmetic
def test_the_profile_counts_the_problems_within_tau_of_the_best():
    inf = math.inf
    costs = np.array([[10, 20, inf],        # best 10: ratios 1, 2, inf
                      [30, 15, 15],         # best 15: ratios 2, 1, 1
                      [inf, inf, inf],      # nobody: counts against everyone
                      [5, 50, 5]])          # ratios 1, 10, 1
    taus, frac = profiles.profile(costs, np.array([1.0, 2.0, 10.0, 100.0]))
    assert frac[0].tolist() == [0.5, 0.25, 0.5]
    assert frac[1].tolist() == [0.75, 0.5, 0.5]
    assert frac[2].tolist() == [0.75, 0.75, 0.5]
    assert frac[3].tolist() == [0.75, 0.75, 0.5]
    s = profiles.score(costs)
    assert s[0] > s[1] > 0 and s[2] == pytest.approx(0.5)    # column 2: best on 2 of 4, fails the rest


def test_acceleration_effect_counts_rescued_and_broken_runs():
    def row(problem, accel, solved, its):
        return {"family": "f", "problem": problem, "rule": "r", "acceleration": accel, "solved": solved,
                "iterations": its, "seconds": its / 100}
    rows = [row("a", "none", True, 100), row("a", "anderson", True, 40),
            row("b", "none", True, 200), row("b", "anderson", True, 100),
            row("c", "none", False, 4000), row("c", "anderson", True, 300),
            row("d", "none", True, 50), row("d", "anderson", False, 4000)]
    (e,) = rank_report.acceleration_effect(rows)
    assert (e["runs"], e["both"], e["rescued"], e["broken"]) == (4, 2, 1, 1)
    assert e["iteration_ratio"] == pytest.approx(0.45)       # median of 0.4 and 0.5


def test_a_case_that_raised_fails_at_each_of_its_accuracies():
    case = {"family": "qp", "problem": "HS21", "rule": "osqp", "order": "xz", "acceleration": None,
            "eps": [1e-3, 1e-6]}
    rows = rank_report.rows_of({"x": {"case": case, "error": "CaseTimeout: over 5 s"}})
    assert [(r["solved"], r["status"]) for r in rows] == [(False, "CaseTimeout")] * 2
    assert rows[0]["problem"] != rows[1]["problem"]


# ---------------------------------------------------------------- the grid
def test_every_configuration_meets_the_same_problems(tmp_path):
    cases = rank.build_cases(["osqp", "summable"], [None, "anderson"], ["obstacle", "framework", "stability"],
                             quick=True)
    rows = rank_report.rows_of({str(i): {"case": c, "result": {"runs": [
        {"solved": True, "status": "solved", "iterations": 1, "seconds": 0.1}]}} for i, c in enumerate(cases)})
    by_config = {}
    for r in rows:
        by_config.setdefault(r["config"], set()).add((r["family"], r["problem"]))
    assert set(by_config) == {"osqp", "summable", "osqp+anderson", "summable+anderson"}
    first = next(iter(by_config.values()))
    assert all(v == first for v in by_config.values()) and len(first) == 6 + 24 + 6


def test_the_quick_qp_grid_reads_the_named_problems(tmp_path):
    data = tmp_path / "mm"
    data.mkdir()
    (data / "HS21.mat").write_bytes(b"")
    files = rank.qp_files(data, quick=True)
    assert [f.name for f in files] == ["HS21.mat"]


# ---------------------------------------------------------------- a run, with a rule from a file
@pytest.mark.study
def test_a_rule_in_a_file_is_ranked_beside_ours(rule_file, tmp_path):
    spec = canonical_spec(f"{rule_file}:MyFixed")
    files = rank.run(tmp_path / "out", rules=["fixed", spec, "summable"], acceleration=["none", "anderson"],
                     families=["obstacle"], quick=True, progress=False,
                     executor=rank.Executor(workers=2))
    names = {f.name for f in files}
    assert {"README.md", "runs.csv", "failures.md", "profiles_iterations.png", "profiles_time.png"} <= names
    with open(tmp_path / "out" / "runs.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 3 * 2 * 3 * 2                      # rules x accelerations x rho_0 x orders
    mine = sorted((r["problem"], r["acceleration"], r["iterations"]) for r in rows if r["rule"] == spec)
    ours = sorted((r["problem"], r["acceleration"], r["iterations"]) for r in rows if r["rule"] == "fixed")
    assert mine == ours                                     # the same class under another name: the same runs
    readme = (tmp_path / "out" / "README.md").read_text()
    assert f"{spec}+anderson" in readme and "| 1 |" in readme and "What acceleration does" in readme
    failed = [r for r in rows if r["solved"] == "False"]
    failures = (tmp_path / "out" / "failures.md").read_text()
    assert f"{len(failed)} of {len(rows)} runs did not solve" in readme
    assert failures.count("\n| obstacle |") == len(failed)


@pytest.mark.study
def test_the_ranking_is_the_same_on_a_dask_local_cluster(rule_file, tmp_path):
    pytest.importorskip("distributed")
    spec = canonical_spec(f"{rule_file}:MyFixed")
    kwargs = dict(rules=[spec, "osqp"], acceleration=["none", "anderson"], families=["obstacle"], quick=True,
                  progress=False)
    rank.run(tmp_path / "local", executor=rank.Executor(workers=1), **kwargs)
    rank.run(tmp_path / "dask", executor=rank.Executor(dask_workers=2), **kwargs)

    def runs(folder):
        with open(folder / "runs.csv") as fh:
            return sorted((r["config"], r["problem"], r["iterations"], r["solved"]) for r in csv.DictReader(fh))
    assert runs(tmp_path / "dask") == runs(tmp_path / "local")


# ---------------------------------------------------------------- bad input: one line, exit 2, nothing run
@pytest.mark.parametrize("args,names", [
    (["--rules", "summable,no_such_rule"], "--rules"),
    (["--rules", "{file}:Missing"], "Missing"),
    (["--acceleration", "none,nesterov"], "--acceleration"),
    (["--acceleration", ""], "--acceleration"),
    (["--families", "contact,fluids"], "--families"),
    (["--families", "qp", "--data", "{dir}/nowhere"], "--data"),
])
def test_bad_input_is_one_line_before_any_case(args, names, rule_file, tmp_path, capsys):
    args = [a.format(file=rule_file, dir=tmp_path) for a in args]
    code = main(["bench", "rules", "--quick", "--out", str(tmp_path / "o"), "-q", *args])
    cost, *err = capsys.readouterr().err.strip().splitlines()
    assert cost.startswith("bench rules: about 13 min")          # announced once its packages were checked
    assert code == 2 and len(err) == 1 and names.format(file=rule_file) in err[0]
    assert not (tmp_path / "o" / "results.jsonl").exists()


def test_a_rule_with_a_penalty_per_row_runs_on_the_qps_only():
    """rowwise sets a penalty per row: the FE and framework families' problems take one rho, so its cases are the qp
    family's only, every-rule lists of the FE studies leave it out, and bench policies refuses it at once."""
    from admmkit.benchmarks.fixtures.methods import admm_methods, per_row
    from admmkit.benchmarks.rules.study import build_cases
    from admmkit.cli import main
    assert per_row("rowwise") and not per_row("osqp")
    assert not any(m.startswith("rowwise/") for m in admm_methods())
    assert {"rowwise/xz", "rowwise/zx"} <= set(admm_methods(rows=True))
    cases = build_cases(["osqp", "rowwise"], ["none"], ["framework", "obstacle"], quick=True)
    assert cases and {c["rule"] for c in cases} == {"osqp"}
    assert main(["bench", "policies", "--quick", "--rules", "rowwise"]) == 2
