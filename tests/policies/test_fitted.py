"""The rule ``fitted`` (``rowwise`` with its exponents and thresholds as parameters) and the command that fits it."""
import math
import os
from pathlib import Path

import numpy as np
import pytest

import admmkit
from admmkit.policies.fitted import FittedRowwise
from admmkit.policies.osqp_rule import OSQPRule
from admmkit.policies.rowwise import RowwiseRule
from admmkit.problems.qp import solve_qp
from admmkit.problems.qp.generate import random_qp

DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "maros_meszaros"
needs_data = pytest.mark.skipif(not (DATA / "HS52.mat").exists(), reason="no Maros-Meszaros data")

#: the training split as docs/results/qp_rules/choice.md lists it (the preset was chosen on these)
TRAINING = ("CVXQP1_M CVXQP2_M CVXQP3_M DPKLO1 DUAL2 DUAL4 DUALC2 DUALC8 GOULDQP2 HS118 HS268 HS35MOD HS52 HS76 "
            "LASER MOSARQP2 PRIMAL2 PRIMAL4 PRIMALC2 PRIMALC8 QADLITTL QBANDM QBORE3D QCAPRI QETAMACR QFORPLAN "
            "QGROW15 QGROW7 QPCBLEND QPCBOEI2 QPTEST QSC205 QSCAGR7 QSCFXM2 QSCORPIO QSCSD1 QSCTAP1 QSEBA QSHARE2B "
            "QSHIP04L QSHIP08S QSTANDAT TAME").split()


def _record(r, dz, rho=1.0, w=None, k=49, rel=(1.0, 1.0)):
    """A hand-made record with A x - z = r, z - z_prev = dz and normalised residuals ``rel``."""
    r, dz = np.asarray(r, float), np.asarray(dz, float)
    z = np.ones_like(r)
    return admmkit.IterationRecord(k=k, rho=rho, order="xz", primal_residual=rel[0], dual_residual=rel[1],
                                   rho_Ax_change=1.0, lam_change=1.0, x_change=1.0, x_norm=1.0, z_change=1.0,
                                   primal_scale=1.0, dual_scale=1.0, primal_unit=1.0, dual_unit=1.0, time=0.0,
                                   x=np.zeros(2), z=z, lam=np.zeros_like(z), Ax=z + r, z_prev=z - dz,
                                   row_weights=np.ones_like(r) if w is None else np.asarray(w, float))


# ---------------------------------------------------------------- the update
def test_the_global_estimate_is_the_ratio_to_the_power_alpha():
    ratios = lambda rec: (1e-2, 1e-6)             # noqa: E731   r_rel / s_rel = 1e4
    rec = _record([1.0], [1.0], rho=2.0)
    assert FittedRowwise(alpha=0.25, residuals=ratios).estimate(rec) == pytest.approx(2.0 * 10.0)
    assert FittedRowwise(alpha=1.0, residuals=ratios).estimate(rec) == pytest.approx(2.0 * 1e4)
    assert FittedRowwise(alpha=0.5, residuals=ratios).estimate(rec) == OSQPRule(residuals=ratios).estimate(rec)


def test_the_rows_step_is_t_to_the_power_beta():
    rec = _record([1.0, 0.3, 0.1], [0.1, 0.3, 1.0])                    # t about 10, 1, 1/10: within the spread
    half, full, none = (FittedRowwise(beta=b) for b in (0.5, 1.0, 0.0))
    rowwise = RowwiseRule()
    for rule in (half, full, none, rowwise):
        rule.reset(1.0)
    d_half, d_full = half.row_factors(rec), full.row_factors(rec)
    assert np.array_equal(d_half, rowwise.row_factors(rec))             # beta = 1/2 is rowwise's step
    assert np.allclose(d_full, d_half ** 2) and d_full[0] > d_half[0] > 1 > d_half[2] > d_full[2]
    assert np.array_equal(none.row_factors(rec), np.ones(3))           # beta = 0: the rows never move


def test_it_acts_at_its_interval_only_and_changes_rho_past_its_tolerance():
    rule = FittedRowwise(interval=10, tolerance=3.0, residuals=lambda rec: (1e-2, 1e-4))   # estimate 10 x rho
    rule.reset(1.0)
    assert rule.update(_record([1.0, 1e-4], [1e-4, 1.0], k=5)) == 1.0
    answer = rule.update(_record([1.0, 1e-4], [1e-4, 1.0], k=9))
    assert isinstance(answer, admmkit.RowPenalties) and answer.rho == pytest.approx(10.0)
    calm = FittedRowwise(interval=10, tolerance=20.0, beta=0.0, residuals=lambda rec: (1e-2, 1e-4))
    calm.reset(1.0)
    assert calm.update(_record([1.0, 1e-4], [1e-4, 1.0], k=9)) == 1.0   # 10 x is within the tolerance 20


def test_the_defaults_are_the_class_constants():
    rule = FittedRowwise()
    assert (rule.alpha, rule.beta, rule.interval, rule.tolerance) == (FittedRowwise.ALPHA, FittedRowwise.BETA,
                                                                      FittedRowwise.INTERVAL, FittedRowwise.TOLERANCE)
    assert isinstance(admmkit.make_policy("admmkit.policies.fitted:FittedRowwise"), FittedRowwise)
    # (by its name "fitted" once the install has read pyproject.toml's entry point)


def test_with_rowwises_constants_it_is_rowwise_bit_for_bit():
    qp = random_qp(20, 30, seed=7)
    a = solve_qp(qp, policy=RowwiseRule(), eps_abs=1e-8, eps_rel=0.0, max_iter=5000)
    b = solve_qp(qp, policy=FittedRowwise(alpha=0.5, beta=0.5, interval=50, tolerance=5.0), eps_abs=1e-8,
                 eps_rel=0.0, max_iter=5000)
    assert a.history.row_weights and a.iterations == b.iterations and a.rho_changes == b.rho_changes
    for name in ("x", "z", "lam"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


# ---------------------------------------------------------------- validation
@pytest.mark.parametrize("kwargs, message", [
    ({"alpha": 0.0}, r"alpha must be a finite number in \(0, 1\], got 0.0"),
    ({"alpha": 1.5}, r"alpha must be a finite number in \(0, 1\]"),
    ({"alpha": math.nan}, r"alpha must be a finite number in \(0, 1\]"),
    ({"alpha": "half"}, r"alpha must be a finite number in \(0, 1\], got 'half'"),
    ({"alpha": True}, r"alpha must be a finite number in \(0, 1\]"),
    ({"beta": -0.1}, r"beta must be a finite number in \[0, 1\]"),
    ({"beta": 2}, r"beta must be a finite number in \[0, 1\], got 2"),
    ({"interval": 0}, r"interval must be an integer >= 1, got 0"),
    ({"tolerance": 0.5}, r"tolerance must be a finite number in \[1, inf\)"),
    ({"spread": 0.5}, r"spread must be a finite number in \[1, inf\)"),
])
def test_bad_parameters_are_refused_by_name_and_range(kwargs, message):
    with pytest.raises(ValueError, match=message):
        FittedRowwise(**kwargs)


# ---------------------------------------------------------------- the fit
@needs_data
def test_the_fit_sees_the_training_split_only():
    from admmkit.benchmarks.qp.fit_rule import GRID, RuleBuilder, build_cases, fit, split_of
    halves = split_of(DATA)
    assert halves["train"] == sorted(TRAINING) and len(halves["test"]) == 43
    assert not set(halves["train"]) & set(halves["test"])
    cases = build_cases(halves["train"], {n: RuleBuilder(n, "fitted", GRID[n]) for n in GRID})
    assert {c["problem"] for c in cases} == set(TRAINING) and len(cases) == 43 * len(GRID)
    with pytest.raises(ValueError, match=r"problems must be of the training split, got HS21"):
        fit(DATA, Path("/nonexistent/out"), problems=["HS52", "HS21"])          # HS21 is a test problem


@needs_data
def test_the_fit_writes_its_tables_whole(tmp_path, monkeypatch):
    from admmkit.benchmarks.qp import fit_rule
    out = tmp_path / "fit"
    result = fit_rule.fit(DATA, out, grid=["rowwise"], problems=["HS52", "HS76"], confirm=False, workers=1,
                          progress=False)
    assert result["chosen"] == "rowwise" and result["train"] == ["HS52", "HS76"]
    lines = (out / "grid.csv").read_text().splitlines()
    assert lines[0].startswith("config,alpha,beta,interval,tolerance,solved 0.001,solved 1e-06,solved,")
    assert len(lines) == 2 and lines[1].startswith("rowwise,0.5,0.5,50,5.0,2,2,4,")   # both solved at both eps
    assert "chosen: `rowwise`" in (out / "grid.md").read_text()
    assert (out / "grid.md").read_text().startswith("# ")        # titled: the docs build it (and links to it)
    assert sorted(p.name for p in out.iterdir()) == ["grid.csv", "grid.md", "grid_runs"]   # no temporary file left

    def refuse(src, dst):
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(os, "replace", refuse)
    before = (out / "grid.csv").read_text()
    with pytest.raises(OSError, match="could not write .*grid.csv"):
        fit_rule.write_table(out, "grid", [{"config": "other", "solved": 0}], "heading")
    assert (out / "grid.csv").read_text() == before                     # the old file stays whole
    assert sorted(p.name for p in out.iterdir()) == ["grid.csv", "grid.md", "grid_runs"]


@needs_data
def test_the_command_refuses_bad_input_in_one_line(capsys):
    from admmkit.benchmarks.qp.fit_rule import main
    assert main(["--data", str(DATA), "--out", "/tmp/unused", "--workers", "3"]) == 2
    assert capsys.readouterr().err.strip() == "admmkit: error: --workers must be 1 or 2 (a shared 2-core machine), got 3"
    assert main(["--data", str(DATA), "--out", "/tmp/unused", "--grid", "beta=9"]) == 2
    assert "admmkit: error: grid must name configurations among rowwise" in capsys.readouterr().err


@needs_data
def test_the_harness_runs_a_built_rule_as_the_preset_runs_rowwise():
    from admmkit.benchmarks.qp.fit_rule import GRID, RuleBuilder
    from admmkit.benchmarks.qp.maros_meszaros_runs import run_admmkit
    from admmkit.problems.qp.mat import load_mat
    qp = load_mat(DATA / "HS118.mat")                # training; on its record's residuals the rule takes 150 / 250
    by_name = run_admmkit(qp, "admmkit", "rowwise", "xz", (1e-3, 1e-6), None, 5.0)
    built = run_admmkit(qp, "admmkit", RuleBuilder("base", "fitted", GRID["rowwise"]), "xz", (1e-3, 1e-6), None, 5.0)
    assert [r["solver"] for r in built] == ["base", "base"]
    for a, b in zip(by_name, built):             # OSQP's normalisation of the run's QP: the same iterations
        assert (a["iterations"], a["rho_changes"], a["solved"]) == (b["iterations"], b["rho_changes"], b["solved"])
