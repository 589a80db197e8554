"""``admmkit solve qp`` at OSQP's level (issue #15): presets, tolerances, termination, certificate, neutral criteria,
JSON/CSV and exit codes, through ``main()``; answers checked against Clarabel and exact certificate identities."""
import csv
import json
from pathlib import Path

import numpy as np
import pytest

import admmkit
from admmkit.cli import build_parser, main
from admmkit.loop.stopping import RelativeChange
from admmkit.problems.qp import load_mat, random_qp, solve_qp, osqp_settings
from admmkit.problems.qp.generate import infeasible_qp, unbounded_qp
from admmkit.problems.qp.reference import solve_with_cvxpy
from admmkit.problems.qp.residuals import neutral_residuals

HS21 = Path(__file__).resolve().parents[3] / "shared" / "data" / "maros_meszaros" / "HS21.mat"
QP = ["solve", "qp", "--random", "30", "40"]
TIGHT = dict(tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12)


def run(argv, capsys):
    """(exit code, stdout, stderr) of ``admmkit ARGV``."""
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def line(out, label):
    """The summary line that starts with ``label``."""
    return next(ln for ln in out.splitlines() if ln.startswith(label))


# ---------------------------------------------------------------- the osqp preset is the default
def test_default_is_the_osqp_preset_and_solves_a_random_qp(tmp_path, capsys):
    j = tmp_path / "r.json"
    code, out, _ = run([*QP, "--json", str(j), "-q"], capsys)
    assert code == 0 and "preset       osqp" in out
    assert line(out, "termination").startswith("termination  solved  (OSQP's test")
    assert "method       osqp: order=xz  policy=OSQPRule(interval=50" in out and "rho_0 = 0.1" in out
    assert "residuals=osqp_relative_residuals(qp)" in line(out, "method") and " at 0x" not in out
    data = json.loads(j.read_text())
    res = data["result"]
    assert res["preset"] == "osqp" and res["termination"] == "solved" and res["status"] == "converged"
    assert res["settings"]["scaling"] == 10 and res["settings"]["alpha"] == 1.6 and res["certificate"] is None
    assert data["provenance"]["stopping_rule"].startswith("osqp_termination(eps_abs=0.001, eps_rel=0.001")
    assert " at 0x" not in data["provenance"]["policy_parameters"] and " at 0x" not in res["policy"]
    # the same run as solve_qp with OSQP's settings, and the neutral criteria recomputed from the written x, y
    qp = random_qp(30, 40, seed=0)
    direct = solve_qp(qp, osqp_settings())
    x, y = np.array(data["arrays"]["x"]), np.array(data["arrays"]["lam"])
    assert res["iterations"] == direct.iterations and np.allclose(x, direct.x, rtol=0, atol=1e-12)
    again = neutral_residuals(qp, x, y)
    assert all(np.isclose(res["neutral"][k], again[k], rtol=1e-9, atol=1e-15) for k in ("primal", "dual", "gap"))


@pytest.mark.parametrize("seed, kind", [(0, "mixed"), (1, "inequality"), (2, "equality"), (3, "lp"), (4, "psd")])
def test_random_qps_at_eps_1e_7_with_polish_agree_with_clarabel(seed, kind, tmp_path, capsys):
    j = tmp_path / "r.json"
    code, out, _ = run(["solve", "qp", "--random", "25", "35", "--kind", kind, "--seed", str(seed),
                        "--eps", "1e-7", "--polish", "--max-iter", "20000", "--json", str(j), "-q"], capsys)
    data = json.loads(j.read_text())
    assert code == 0 and data["result"]["termination"] == "solved", out
    qp = random_qp(25, 35, kind=kind, seed=seed)
    _, _, f_ref = solve_with_cvxpy(qp, **TIGHT)
    assert abs(data["result"]["objective"] - f_ref) <= 1e-5 * max(1.0, abs(f_ref))
    assert data["result"]["polish"]["status"] in ("succeeded", "failed")
    n = line(out, "neutral").split()
    assert n[1] == "primal" and n[3] == "dual" and n[5] == "gap"


def test_maros_meszaros_hs21_solves_and_matches_clarabel(capsys):
    """../shared beside the clone holds the Maros-Meszaros set (as in CI)."""
    assert HS21.exists(), f"{HS21} missing: the Maros-Meszaros data must sit in ../shared beside the clone"
    code, out, _ = run(["solve", "qp", "--mat", str(HS21), "--eps", "1e-8", "--polish", "-q"], capsys)
    assert code == 0 and "termination  solved" in out
    f = float(line(out, "objective").split()[1])
    _, _, f_ref = solve_with_cvxpy(load_mat(HS21), **TIGHT)
    assert abs(f - f_ref) <= 1e-6 * max(1.0, abs(f_ref))


# ---------------------------------------------------------------- infeasible and unbounded QPs: exit 1 and a certificate
def test_an_infeasible_qp_ends_with_exit_1_and_a_certificate(tmp_path, capsys):
    j, c = tmp_path / "r.json", tmp_path / "r.csv"
    argv = ["solve", "qp", "--random", "20", "30", "--kind", "infeasible", "--json", str(j), "--csv", str(c), "-q"]
    code, out, _ = run(argv, capsys)
    assert code == 1 and "status       primal_infeasible" in out
    assert line(out, "certificate").startswith("certificate  primal infeasibility")
    data = json.loads(j.read_text())
    assert data["result"]["termination"] == "primal_infeasible" and data["result"]["certificate"]["kind"] == "primal"
    # the certificate checked from scratch: A'y ~ 0 and S(y) = u'max(y,0) + l'min(y,0) < 0 (I1)
    qp = infeasible_qp(20, 30, seed=0)
    y = np.array(data["arrays"]["certificate"], dtype=float)
    assert y.shape == (qp.m,) and np.max(np.abs(y)) == pytest.approx(1.0)
    pos, neg = np.maximum(y, 0), np.minimum(y, 0)
    assert np.all(np.isfinite(qp.u[pos > 0])) and np.all(np.isfinite(qp.l[neg < 0]))
    support = qp.u[pos > 0] @ pos[pos > 0] + qp.l[neg < 0] @ neg[neg < 0]
    assert support < -0.1 and np.max(np.abs(qp.A.T @ y)) < 1e-4
    rows = list(csv.DictReader(c.open()))
    assert len(rows) == qp.n + qp.m and {r["status"] for r in rows} == {"primal_infeasible"}
    cert_rows = np.array([float(r["certificate"]) for r in rows if r["kind"] == "row"])
    assert np.allclose(cert_rows, y) and all(r["certificate"] == "nan" for r in rows if r["kind"] == "x")


def test_an_unbounded_qp_ends_with_exit_1_and_a_dual_certificate(tmp_path, capsys):
    j = tmp_path / "r.json"
    code, out, _ = run(["solve", "qp", "--random", "20", "30", "--kind", "unbounded", "--json", str(j), "-q"], capsys)
    assert code == 1 and "status       dual_infeasible" in out and "certificate  dual infeasibility" in out
    qp = unbounded_qp(20, 30, seed=0)
    dx = np.array(json.loads(j.read_text())["arrays"]["certificate"], dtype=float)
    assert dx.shape == (qp.n,) and qp.q @ dx < -0.5 and np.max(np.abs(qp.P @ dx)) < 1e-4   # (I2)


def test_a_feasible_qp_has_no_certificate_and_the_cap_exits_1(tmp_path, capsys):
    code, out, _ = run([*QP, "--eps", "1e-10", "--max-iter", "30", "-q"], capsys)
    assert code == 1 and "certificate" not in out and "status       max_iter" in out
    assert line(out, "termination").startswith("termination  none fired")


def test_solved_at_10x_the_tolerances_is_inaccurate_and_exits_1(tmp_path, capsys):
    """OSQP's second look at the cap: the test at 10x eps fires -> solved_inaccurate, status converged_inaccurate."""
    j = tmp_path / "r.json"
    code, out, _ = run([*QP, "--eps", "1e-5", "--max-iter", "75", "--json", str(j), "-q"], capsys)
    res = json.loads(j.read_text())["result"]
    assert code == 1 and res["termination"] == "solved_inaccurate" and res["status"] == "converged_inaccurate"
    assert line(out, "termination").startswith("termination  solved_inaccurate")
    r = res["residuals"]                      # (R1)-(R3) fail at eps = 1e-5 and hold at 10x (eps_abs = eps_rel)
    ratios = [abs(r[k]) / (1.0 + r[k + "_scale"]) for k in ("primal", "dual", "gap")]
    assert max(ratios) > 1e-5 and max(ratios) <= 1e-4


def test_eps_inf_reaches_the_infeasibility_tolerances(tmp_path, capsys):
    j = tmp_path / "r.json"
    code, _, _ = run(["solve", "qp", "--random", "20", "30", "--kind", "infeasible", "--eps-inf", "1e-6",
                      "--json", str(j), "-q"], capsys)
    s = json.loads(j.read_text())["result"]["settings"]
    assert code == 1 and s["eps_prim_inf"] == s["eps_dual_inf"] == 1e-6


# ---------------------------------------------------------------- the common options in the osqp preset
def test_eps_abs_and_eps_rel_map_onto_osqps_tolerances(tmp_path, capsys):
    j = tmp_path / "r.json"
    run([*QP, "--eps-abs", "1e-6", "--eps-rel", "1e-5", "--json", str(j), "-q"], capsys)
    s = json.loads(j.read_text())["result"]["settings"]
    assert (s["eps_abs"], s["eps_rel"]) == (1e-6, 1e-5)
    run([*QP, "--eps-abs", "1e-6", "--json", str(j), "-q"], capsys)                 # --eps-rel defaults to 0
    s = json.loads(j.read_text())["result"]["settings"]
    assert (s["eps_abs"], s["eps_rel"]) == (1e-6, 0.0)


def test_policy_order_rho_and_max_iter_reach_the_settings(tmp_path, capsys):
    j, h = tmp_path / "r.json", tmp_path / "h.csv"
    code, out, _ = run([*QP, "--policy", "sadmm", "--rho", "2", "--max-iter", "3000", "--json", str(j),
                        "--history", str(h), "-q"], capsys)
    data = json.loads(j.read_text())
    s = data["result"]["settings"]
    assert (s["order"], s["rho"], s["max_iter"]) == ("zx", 2.0, 3000)                  # sadmm runs in order zx
    assert "sadmm: order=zx  policy=Summable" in out and data["provenance"]["policy"] == "sadmm"
    rows = list(csv.DictReader(h.open()))                 # --history: the tested iterations (every 25th), complete
    n = data["result"]["iterations"]
    assert [int(r["k"]) for r in rows] == [k for k in range(n) if (k + 1) % 25 == 0 or k == n - 1]
    assert not any(v == "nan" for r in rows for v in r.values())
    code, out, _ = run([*QP, "--policy", "residual_balancing", "--order", "zx", "-q"], capsys)
    assert code in (0, 1) and "residual_balancing: order=zx" in out


# ---------------------------------------------------------------- the textbook preset is the old command
def test_textbook_preset_reproduces_the_old_loop(tmp_path, capsys):
    j = tmp_path / "r.json"
    code, out, _ = run([*QP, "--preset", "textbook", "--tol", "1e-6", "--json", str(j), "-q"], capsys)
    data = json.loads(j.read_text())
    qp = random_qp(30, 40, seed=0)
    from admmkit.policies import ResidualBalancing
    old = admmkit.solve(qp, rho=1.0, policy=ResidualBalancing(), order="xz", stop=RelativeChange(1e-6), max_iter=10_000)
    # the relative-change stop at 1e-6 leaves a relative duality gap of 2.4e-5 (QP.kkt_relative): converged_inaccurate
    assert old.status.value == data["result"]["status"] == "converged_inaccurate" and code == 1
    assert "residual_balancing: order=xz" in out and "rho_0 = 1" in out
    assert data["result"]["iterations"] == old.iterations and data["result"]["stopped_by"] == old.stopped_by
    assert np.array_equal(np.array(data["arrays"]["x"]), old.x)
    assert data["provenance"]["stopping_rule"] == "relative_change(tol=1e-06)" and data["provenance"]["max_iter"] == 10_000
    assert line(out, "termination").startswith("termination  relative_change(tol=1e-06)  (textbook loop")
    assert data["result"]["neutral"]["primal"] == pytest.approx(neutral_residuals(qp, old.x, old.lam)["primal"])


def test_textbook_preset_never_declares_infeasibility(capsys):
    code, out, _ = run(["solve", "qp", "--random", "20", "30", "--kind", "infeasible", "--preset", "textbook",
                        "--max-iter", "300", "-q"], capsys)
    assert code == 1 and "certificate" not in out and "infeasible" not in line(out, "status")   # max_iter or inaccurate


# ---------------------------------------------------------------- bad input: one line, exit 2, nothing solved
BAD = [
    (QP + ["--tol", "1e-6"], "--tol is the textbook loop's relative-change rule"),
    (QP + ["--eps", "1e-6", "--eps-abs", "1e-6"], "give either --eps or --eps-abs"),
    (QP + ["--preset", "textbook", "--eps", "1e-6"], "--eps belong(s) to --preset osqp"),
    (QP + ["--preset", "textbook", "--polish"], "--polish belong(s) to --preset osqp"),
    (QP + ["--preset", "textbook", "--eps-inf", "1e-6"], "--eps-inf belong(s) to --preset osqp"),
    (QP + ["--preset", "fast"], "--preset"),
    (QP + ["--eps", "0"], "--eps"),
    (QP + ["--eps", "-1e-3"], "--eps"),
    (QP + ["--eps-inf", "nan"], "--eps-inf"),
    (QP + ["--kind", "weird"], "--kind"),
    (QP + ["--seed", "-1"], "--seed must be an integer >= 0"),
    (QP + ["--rho", "0"], "--rho"),
    (QP + ["--eps-rel", "1e-3"], "--eps-rel needs --eps-abs"),
    (QP + ["--policy", "nope"], "--policy: unknown name 'nope'"),
    (["solve", "qp", "--random", "0", "3", "--kind", "infeasible"], "--random"),
    (["solve", "qp", "--mat", "/nonexistent/HS21.mat"], "HS21.mat"),
]


@pytest.mark.parametrize("argv, needle", BAD)
def test_bad_input_is_one_line_and_exit_2(argv, needle, tmp_path, capsys):
    j = tmp_path / "r.json"
    code, out, err = run([*argv, "--json", str(j)], capsys)
    assert code == 2 and needle in err and "Traceback" not in err, err
    assert "status" not in out and not j.exists()


def test_help_names_the_presets_and_the_osqp_options(capsys):
    code, out, _ = run(["solve", "qp", "--help"], capsys)
    for flag in ("--preset {osqp,textbook}", "--eps EPS", "--eps-inf EPS", "--polish", "infeasible", "unbounded"):
        assert flag in out
    assert "default 4000 osqp preset, 10000 textbook" in " ".join(out.split())


def test_documented_solve_qp_commands_parse():
    """The `admmkit solve qp` lines of docs/cli.md and docs/qp.md parse with the real parser."""
    import re
    root = Path(__file__).resolve().parents[2]
    parser = build_parser()
    found = 0
    for doc in ("docs/cli.md", "docs/qp.md"):
        for cmd in re.findall(r"^    admmkit (solve qp --(?:mat|random) .*)$", (root / doc).read_text(), flags=re.M):
            assert parser.parse_args(cmd.split("#")[0].split()).func
            found += 1
    assert found >= 4
