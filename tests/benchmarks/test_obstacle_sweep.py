"""``admmkit bench obstacle``'s rho sweep on the sweep runner: the same runs as solve() itself, resumable."""
import pytest
import math

from admmkit import RelativeChange, solve
from admmkit.benchmarks.obstacle.study import sweep
from admmkit.problems.obstacle import make_problem
from admmkit.problems.obstacle.scene import radial


@pytest.mark.study
def test_sweep_runs_on_the_runner_and_reports_from_its_results(tmp_path):
    rows = sweep(16, rhos=(1e-2, 1e2), policy_names=["summable", "fixed"], max_iter=3000, out=tmp_path,
                 progress=False)
    assert [(r["policy"], r["order"], r["rho0"]) for r in rows][:3] == [("summable", "xz", 1e-2),
                                                                      ("summable", "xz", 1e2),
                                                                      ("summable", "zx", 1e-2)]
    assert len(rows) == 2 * 2 * 2 and (tmp_path / "results.jsonl").is_file()
    p = make_problem(radial(h=4 / 16))
    for r in rows:                               # each row is the run solve() makes itself
        res = solve(p, rho=r["rho0"], policy=r["policy"], order=r["order"], stop=RelativeChange(1e-5),
                    max_iter=3000)
        assert r["iterations"] == res.iterations and r["status"] == str(res.status)
    assert all(r["error_at_stop"] < 1e-2 for r in rows if r["policy"] == "summable")
    assert any(math.isnan(r["iterations_to_tol"]) or r["iterations_to_tol"] > 0 for r in rows)
    again = sweep(16, rhos=(1e-2, 1e2), policy_names=["summable", "fixed"], max_iter=3000, out=tmp_path,
                  progress=False, report_only=True)
    assert again == rows
