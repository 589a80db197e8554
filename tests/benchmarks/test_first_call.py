"""``admmkit bench first-call``: its refusals, its table and one real fresh-process measurement."""
import sys

import pytest

from admmkit.benchmarks.framework import first_call
from admmkit.cli import main


def test_refuses_a_data_folder_without_hs21(tmp_path, capsys):
    assert main(["bench", "first-call", "--data", str(tmp_path), "--out", str(tmp_path / "o")]) == 2
    assert "--data" in capsys.readouterr().err


def test_refuses_zero_repeats(tmp_path, capsys):
    assert main(["bench", "first-call", "--repeats", "0", "--out", str(tmp_path / "o")]) == 2
    assert "--repeats" in capsys.readouterr().err


def test_table_pairs_each_case_with_osqp_and_takes_medians():
    runs = {name: [{"wall": w, "import": 0.1, "solve": 0.01, "status": "converged"} for w in (3.0, 1.0, 2.0)]
            for row in first_call.ROWS for name in row[1:] if name}
    runs["osqp_import"] = [{"wall": 0.5}, {"wall": 0.25}, {"wall": 1.0}]
    rows = {r["case"]: r for r in first_call.table_rows(runs)}
    assert rows["import"]["admmkit_s"] == 2.0 and rows["import"]["osqp_s"] == 0.5
    assert rows["import"]["ratio"] == 4.0
    assert rows["admmkit --help"]["ratio"] != rows["admmkit --help"]["ratio"]      # NaN: no OSQP counterpart
    text = first_call.report(list(rows.values()), 3, "admmkit bench first-call")
    assert "| import | 2.000 | 0.500 | **4.00** |" in text


def test_a_fresh_import_process_reports_its_phase():
    run = first_call.run_child("admmkit_import", None, {"PATH": "", **dict(__import__("os").environ)})
    assert run["wall"] >= run["import"] > 0
    assert first_call.command("admmkit_help", None)[:3] == [sys.executable, "-m", "admmkit"]
