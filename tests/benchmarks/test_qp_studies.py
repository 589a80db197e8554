"""The two QP studies run end to end on a tiny selection and write what they promise."""
import csv
from pathlib import Path

import pytest

MM = Path(__file__).resolve().parents[3] / "shared" / "data" / "maros_meszaros"


@pytest.mark.skipif(not MM.is_dir(), reason=f"Maros-Meszaros data not found at {MM}")
def test_qp_fidelity_on_two_problems(tmp_path):
    pytest.importorskip("osqp")
    from admmkit.benchmarks.qp import qp_fidelity
    assert qp_fidelity.main(["--data", str(MM), "--problems", "HS21", "HS35", "VALUES", "--out", str(tmp_path),
                             "--max-iter", "2000", "--rules", "fixed"]) == 0
    rows = list(csv.DictReader((tmp_path / "qp_fidelity.csv").open()))
    assert {r["solver"] for r in rows} == {"OSQP", "admmkit-osqp", "admmkit-fixed"} and len(rows) == 2 * 2 * 3
    for eps in ("0.001", "1e-06"):
        by = {(r["problem"], r["solver"]): r for r in rows if r["eps"] == eps}
        for p in ("HS21", "HS35"):                    # the preset takes OSQP's path: same iterations
            assert by[p, "OSQP"]["iterations"] == by[p, "admmkit-osqp"]["iterations"]
    readme = (tmp_path / "README.md").read_text()
    assert "Command: `admmkit bench qp-fidelity" in readme and "## Machine" in readme
    assert "Skipped, not a convex QP: VALUES" in readme          # load_mat refuses it; the study goes on


def test_qp_agreement_on_a_few_qps(tmp_path):
    from admmkit.benchmarks.qp import qp_agreement
    assert qp_agreement.main(["--count", "5", "--out", str(tmp_path), "--max-iter", "3000"]) == 0
    rows = list(csv.DictReader((tmp_path / "qp_agreement.csv").open()))
    assert len(rows) == 10 and {r["kind"] for r in rows} == set(qp_agreement.KINDS)
    solved = [r for r in rows if r["status"] == "solved"]
    assert solved and all(float(r["objective_error"]) < 1e-3 for r in solved)
    assert "Command: `admmkit bench qp-agreement" in (tmp_path / "README.md").read_text()


@pytest.mark.skipif(not MM.is_dir(), reason=f"Maros-Meszaros data not found at {MM}")
def test_qp_speed_on_three_problems(tmp_path):
    pytest.importorskip("osqp")
    from admmkit.benchmarks.qp import qp_speed
    assert qp_speed.main(["--data", str(MM), "--problems", "HS21", "HS35", "QPCBLEND", "--out", str(tmp_path),
                          "--repeat", "1"]) == 0
    rows = list(csv.DictReader((tmp_path / "qp_speed.csv").open()))
    assert len(rows) == 3 * 3 * 2 and {r["solver"] for r in rows} == set(qp_speed.CONFIGS)
    assert {float(r["eps"]) for r in rows} == {1e-3, 1e-6}            # both accuracies by default
    for p in ("HS21", "HS35", "QPCBLEND"):            # the same iterations in all three: the ratios compare like work
        for eps in ("0.001", "1e-06"):
            assert len({r["iterations"] for r in rows if r["problem"] == p and r["eps"] == eps}) == 1
        osqp_row = next(r for r in rows if r["problem"] == p and r["solver"] == "osqp")
        assert float(osqp_row["ratio_whole"]) == 1.0
    readme = (tmp_path / "README.md").read_text()
    assert "Command: `admmkit bench qp-speed" in readme and "same iteration count: 6 (of 6" in readme
    assert "## eps = 0.001" in readme and "## eps = 1e-06" in readme
    assert (tmp_path / "qp_speed.png").stat().st_size > 0


def test_qp_speed_rejects_bad_options(capsys):
    from admmkit.benchmarks.qp import qp_speed
    for bad in (["--repeat", "0"], ["--eps", "nan"], ["--eps", "1e-3", "0"], ["--min-size", "-1"]):
        with pytest.raises(SystemExit) as exit_:
            qp_speed.main(bad)
        assert exit_.value.code == 2 and bad[0] in capsys.readouterr().err


@pytest.mark.skipif(not MM.is_dir(), reason=f"Maros-Meszaros data not found at {MM}")
def test_anderson_cost_on_one_problem(tmp_path):
    pytest.importorskip("numba")
    from admmkit.benchmarks.qp import anderson_cost
    assert anderson_cost.main(["--data", str(MM), "--problems", "HS21", "--out", str(tmp_path), "--repeat", "1"]) == 0
    rows = list(csv.DictReader((tmp_path / "anderson_cost.csv").open()))
    assert len(rows) == 1 and rows[0]["problem"] == "HS21" and float(rows[0]["cost_ratio"]) > 0
    assert rows[0]["plain_status"] == rows[0]["anderson_status"] == "solved"
    readme = (tmp_path / "README.md").read_text()
    assert "Command: `admmkit bench anderson-cost" in readme and "## Machine" in readme
