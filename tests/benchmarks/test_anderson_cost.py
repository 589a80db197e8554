"""``admmkit bench anderson-cost``: both measures, the fixed work doing the same iterations with and without Anderson."""
import csv
from pathlib import Path

import pytest

MM = Path(__file__).resolve().parents[3] / "shared" / "data" / "maros_meszaros"


@pytest.mark.skipif(not MM.is_dir(), reason=f"Maros-Meszaros data not found at {MM}")
def test_the_fixed_work_runs_do_the_same_iterations(tmp_path):
    pytest.importorskip("numba")
    from admmkit.benchmarks.qp import anderson_cost
    assert anderson_cost.main(["--data", str(MM), "--problems", "HS21", "HS118", "--out", str(tmp_path),
                               "--repeat", "1", "--fixed-iter", "300", "--interval", "5"]) == 0
    rows = list(csv.DictReader((tmp_path / "anderson_cost.csv").open()))
    assert [r["problem"] for r in rows] == ["HS21", "HS118"]
    for r in rows:
        assert r["interval"] == "5" and r["fixed_iterations"] == r["fixed_anderson_iterations"] == "300"
        assert float(r["fixed_cost_ratio"]) > 0 and float(r["cost_ratio"]) > 0
    assert int(rows[1]["fixed_extrapolated"]) > 0           # HS118 extrapolates in 300 iterations
    readme = (tmp_path / "README.md").read_text()
    assert "fixed work median" in readme and "solve median" in readme and "interval 5" in readme


@pytest.mark.parametrize("bad", [["--interval", "0"], ["--fixed-iter", "0"]])
def test_bad_options_are_named(bad, capsys):
    from admmkit.benchmarks.qp import anderson_cost
    with pytest.raises(SystemExit) as exit_:
        anderson_cost.main(["--problems", "HS21", *bad])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and f"{bad[0]} must be an integer >= 1" in err


@pytest.mark.skipif(not MM.is_dir(), reason=f"Maros-Meszaros data not found at {MM}")
def test_fast_admm_too(tmp_path):
    """``--accelerator fast``: restarted fast ADMM in Anderson's place, the same fixed work, compiled."""
    pytest.importorskip("numba")
    from admmkit.benchmarks.qp import anderson_cost
    assert anderson_cost.main(["--data", str(MM), "--problems", "HS118", "--out", str(tmp_path), "--repeat", "1",
                               "--fixed-iter", "300", "--accelerator", "fast"]) == 0
    (row,) = list(csv.DictReader((tmp_path / "anderson_cost.csv").open()))
    assert row["accelerator"] == "fast" and row["fixed_iterations"] == row["fixed_anderson_iterations"] == "300"
    assert int(row["fixed_extrapolated"]) > 0 and float(row["fixed_cost_ratio"]) > 0
    readme = (tmp_path / "README.md").read_text()
    assert "# fast ADMM on the compiled QP path" in readme and "eta 0.999" in readme
