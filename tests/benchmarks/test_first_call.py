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


def test_solve_contact_is_timed_with_an_empty_and_a_warm_operator_cache(monkeypatch, tmp_path):
    """The cold row gets a fresh empty ADMMKIT_CACHE_DIR each run (NGSolve imported, the scene assembled), the
    warm row the folder the warm-up filled; both rows and the imports' floor are in the table, with CPU time."""
    import os
    seen = []

    class Done:
        returncode, stdout, stderr = 0, "", ""

    def fake_run(argv, env, **kwargs):
        folder = env.get("ADMMKIT_CACHE_DIR")
        seen.append((argv, folder, os.path.isdir(folder) and os.listdir(folder) == []))
        return Done()
    monkeypatch.setattr(first_call.subprocess, "run", fake_run)
    env = {"ADMMKIT_CACHE_DIR": str(tmp_path)}
    (tmp_path / "entry.npz").write_text("stored by the warm-up")
    cold, warm = (first_call.run_child(name, None, env) for name in ("admmkit_contact_cold", "admmkit_contact"))
    assert cold["cpu"] >= 0 and warm["cpu"] >= 0
    (argv_cold, dir_cold, empty_cold), (argv_warm, dir_warm, empty_warm) = seen
    assert argv_cold == argv_warm and argv_cold[3:5] == ["solve", "contact"]
    assert dir_cold != str(tmp_path) and empty_cold and not os.path.exists(dir_cold)   # removed after the run
    assert dir_warm == str(tmp_path) and not empty_warm
    cases = [row[0] for row in first_call.ROWS]
    assert {"solve contact --scene ex1 --h 1/40, empty operator cache",
            "solve contact --scene ex1 --h 1/40, operator cache warm",
            "import numpy, scipy.sparse.linalg, scipy.linalg", "import numpy, scipy.sparse"} <= set(cases)


def test_a_usage_error_is_one_line(tmp_path, capsys):
    """A missing HS21.mat or a bad --repeats: one line on stderr naming the option, exit 2, no usage block."""
    from admmkit.cli import main
    assert main(["bench", "first-call", "--data", str(tmp_path), "--out", str(tmp_path / "out")]) == 2
    assert main(["bench", "first-call", "--repeats", "0"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    err = [e for e in lines if e.startswith("admmkit: error:")]        # beside the study's one-line cost note
    assert len(err) == 2 and "--data" in err[0] and "--repeats" in err[1] and not any(e.startswith("usage:") for e in lines)
