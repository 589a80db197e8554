"""admmkit bench loop-overhead: the hand-written algorithms are the algorithms admmkit runs (issue #14).

No timing is asserted: only that every loop the benchmark compares does the same
work (same iterations, same x, same rho) and that the command writes its table.
"""
import numpy as np
import pytest

import admmkit
from admmkit.benchmarks.framework import loop_overhead as lo


@pytest.mark.parametrize("n", [10, 300])
@pytest.mark.parametrize("check_every", [1, 7, 25])
@pytest.mark.parametrize("tol", [1e-300, 1e-6])
def test_hand_written_residual_test_is_admmkits(n, check_every, tol):
    p = lo.Obstacle1D(n).problem
    if tol > 1e-300:
        p.d = np.linspace(0.2, 1.0, n)                  # well conditioned: fixed rho converges in < 100 iterations
    res = admmkit.solve(p, rho=1.0, order="zx", stop=admmkit.ResidualTolerance(tol, tol), max_iter=3000,
                        check_every=check_every, blas_threads=None)
    _, its, x = lo.hand_residual(p, 1.0, 3000, check_every, eps_abs=tol, eps_rel=tol)
    assert its == res.iterations and np.array_equal(x, res.x_iterate)
    if tol == 1e-6:
        assert res.converged and its < 3000             # the rule fired, in both loops at the same iteration


@pytest.mark.parametrize("n", [10, 300])
@pytest.mark.parametrize("check_every", [1, 7, 25])
@pytest.mark.parametrize("tol", [1e-300, 1e-5])
def test_hand_written_sadmm_is_admmkits(n, check_every, tol):
    p = lo.Obstacle1D(n).problem
    res = admmkit.solve(p, rho=1.0, order="zx", policy="summable", stop=admmkit.RelativeChange(tol),
                        max_iter=3000, check_every=check_every, blas_threads=None)
    _, its, x, rho = lo.hand_sadmm(p, 1.0, 3000, check_every, tol=tol)
    assert its == res.iterations and np.array_equal(x, res.x_iterate) and rho == res.rho
    assert res.rho_changes > 5                          # the summable rule did change rho on the way
    if tol == 1e-5:
        assert res.converged and its < 3000             # the relative change fired, in both at the same iteration


def test_hand_sadmm_with_few_allowed_changes_matches_the_policy():
    # c_max small: the s_k = 1/(c - c_max)^2 branch of the summable rule is taken
    p = lo.Obstacle1D(50).problem
    res = admmkit.solve(p, rho=1.0, order="zx", policy=admmkit.make_policy("summable", c_max=2),
                        stop=admmkit.RelativeChange(1e-300), max_iter=400, blas_threads=None)
    _, its, x, rho = lo.hand_sadmm(p, 1.0, 400, 1, c_max=2)
    assert res.rho_changes > 3 and its == res.iterations and np.array_equal(x, res.x_iterate) and rho == res.rho


def test_measure_checks_agreement_and_reports_both_comparators():
    rows = lo.measure(10, 40, 1)
    assert [r["configuration"] for r in rows] == list(lo.CONFIGS)
    for r in rows:
        assert r["overhead_vs_hand_us"] == pytest.approx(r["admmkit_us"] - r["hand_us"])
        assert r["overhead_vs_bare_us"] == pytest.approx(r["admmkit_us"] - r["bare_us"])
        assert r["met"] == (r["overhead_vs_hand_us"] <= 10)


def test_command_writes_the_table(tmp_path, capsys):
    assert lo.main(["--out", str(tmp_path), "--sizes", "10,2000", "--iterations", "30", "--repeats", "1"]) == 0
    text = (tmp_path / "loop_overhead.md").read_text()
    assert "judged against the hand-written algorithm" in text
    assert text.count("| 10 |") == len(lo.CONFIGS) and text.count("| 2000 |") == len(lo.CONFIGS)
    assert "overhead_pct_of_hand" in (tmp_path / "loop_overhead.csv").read_text().splitlines()[0]
