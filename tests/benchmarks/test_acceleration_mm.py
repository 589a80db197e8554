"""``python -m admmkit.benchmarks.qp.acceleration_mm``: plain ADMM against accelerators on Maros-Meszaros problems,
solved counts and problems gained and lost."""
import csv
from pathlib import Path

import pytest

from admmkit.benchmarks.qp import acceleration_mm

MM = Path(__file__).resolve().parents[3] / "shared" / "data" / "maros_meszaros"


@pytest.mark.skipif(not MM.is_dir(), reason=f"Maros-Meszaros data not found at {MM}")
def test_the_table_counts_solved_gained_and_lost(tmp_path):
    pytest.importorskip("numba")
    assert acceleration_mm.main(["--data", str(MM), "--problems", "HS21,HS268", "--out", str(tmp_path),
                                 "--configs", "fast", "fast:patience=0"]) == 0
    rows = list(csv.DictReader((tmp_path / "maros_meszaros.csv").open()))
    assert len(rows) == 2 * 2 * 3                                   # problems x accuracies x (plain + 2)
    by = {(r["problem"], r["eps"], r["config"]): r for r in rows}
    assert by[("HS268", "1e-06", "plain")]["status"] == "solved"
    assert by[("HS268", "1e-06", "fast")]["status"] == "solved"
    assert int(by[("HS268", "1e-06", "fast")]["rejected"]) > 0 == int(by[("HS268", "1e-06", "fast:patience=0")]["rejected"])
    text = (tmp_path / "maros_meszaros.md").read_text()
    assert "| eps 1e-06 | 2 | 2 | 2 |" in text and "| fast | 1e-06 | none | none |" in text


@pytest.mark.parametrize("config", ["nesterov", "fast:patience", "fast:patience=-1", "fast:give_up=-1", "fast:speed=2",
                                    "fast:eta=x"])
def test_bad_configurations_are_named(config, capsys):
    with pytest.raises(SystemExit) as exit_:
        acceleration_mm.main(["--configs", config])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and err.startswith("admmkit: error: ") and f"configuration {config!r}" in err
    assert len(err.strip().splitlines()) == 1
