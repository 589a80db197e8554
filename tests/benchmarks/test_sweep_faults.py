"""Fault injection on the sweep runner (issue #16): torn lines, kills during a rewrite, dead workers and drivers.

Every case function here is tiny (a sleep, a square); the workers import this
module by the name pytest gave it, from the parent's sys.path.
"""
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from admmkit.benchmarks.runner.sweep import Executor, append_result, case_id, load_results, run_sweep
from admmkit.benchmarks.runner.sweep_table import write_table

FUNC = f"{__name__}:fault_case"


def fault_case(case):
    """{"value": v} -> its square, after ``pause`` seconds; ``die``: kill this process (once if a marker is given);
    ``spin``: a Python loop of that many seconds (for the time limit)."""
    if case.get("pid_dir"):
        Path(case["pid_dir"], str(os.getpid())).touch()
    time.sleep(case.get("pause", 0.0))
    if case.get("die"):
        marker = case.get("marker")
        if marker is None or not os.path.exists(marker):
            if marker:
                Path(marker).touch()
            os.kill(os.getpid(), signal.SIGKILL)
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < case.get("spin", 0.0):
        pass
    return {"square": case["value"] ** 2, "pid": os.getpid()}




# ---------------------------------------------------------------- torn lines and resume
def test_append_after_a_torn_last_line_keeps_the_new_record(tmp_path):
    path = tmp_path / "r.jsonl"
    append_result(path, {"id": "a", "result": 1})
    with path.open("a") as fh:
        fh.write('{"id": "b", "resu')                  # killed in the middle of a line (a power cut)
    append_result(path, {"id": "c", "result": 3})    # must not be glued to the fragment
    assert set(load_results(path)) == {"a", "c"}
    assert path.read_text().endswith('"result": 3}\n')


def test_resume_after_torn_lines_reruns_only_the_torn_case(tmp_path, ids_in_file):
    path = tmp_path / "r.jsonl"
    cases = [{"value": v} for v in range(5)]
    run_sweep(cases[:3], FUNC, path, workers=1, progress=False, table=False)
    text = path.read_text()
    torn = text[: len(text) - 25]                     # the last record loses its end
    path.write_text(torn.replace("\n", "\n{garbage\n", 1))   # and a torn line in the middle
    records = run_sweep(cases, FUNC, path, workers=1, progress=False)
    assert {r["result"]["square"] for r in records.values()} == {0, 1, 4, 9, 16}
    ids = ids_in_file(path)
    assert sorted(ids) == sorted(case_id(c) for c in cases)        # every case exactly once
    assert len(load_results(path)) == 5


# ---------------------------------------------------------------- atomic rewrites
def test_a_failing_table_rewrite_leaves_the_old_table(tmp_path, monkeypatch):
    import pandas as pd
    stem = tmp_path / "results"
    first = write_table([{"id": "a", "case": {"v": 1}, "result": {"x": 1.0}, "seconds": 0.1}], stem)
    before = first.read_bytes()

    def crash(self, path, *args, **kwargs):
        Path(path).write_bytes(b"PAR1 half a file")      # a partial write, then the kill
        raise KeyboardInterrupt
    monkeypatch.setattr(pd.DataFrame, "to_parquet", crash)
    monkeypatch.setattr(pd.DataFrame, "to_csv", crash)
    with pytest.raises(KeyboardInterrupt):
        write_table([{"id": "b", "case": {"v": 2}, "result": {"x": 2.0}, "seconds": 0.1}] * 84, stem)
    assert first.read_bytes() == before                          # the old table, whole
    assert [p.name for p in tmp_path.iterdir()] == [first.name]  # no temporary file left behind
    assert first.suffix == ".parquet" and pd.read_parquet(first)["result.x"].tolist() == [1.0]


def test_qp_results_csv_survives_a_kill_during_its_rewrite(tmp_path, monkeypatch):
    import csv

    from admmkit.benchmarks.qp import maros_meszaros_report as report
    rows = [{"problem": f"P{i}", "n": 2, "m": 1, "variant": "preset", "solver": "osqp", "order": "zx", "eps": 1e-3,
             "solved": True, "neutral": True, "status": "solved", "iterations": 10 + i, "time": 0.1, "setup_time": 0.0,
             "loop_time": 0.05, "factorizations": 1, "rho_changes": 0, "rho_final": 0.1, "rho_max": 0.1,
             "neutral_primal": 0.0, "neutral_dual": 0.0, "neutral_gap": 0.0}
            for i in range(84)]
    path = tmp_path / "results.csv"
    report.write_rows(rows, path)
    before = path.read_text()
    real = csv.DictWriter.writerow
    calls = {"n": 0}

    def dying_writerow(self, row):
        calls["n"] += 1
        if calls["n"] > 4:
            raise KeyboardInterrupt          # killed after 4 rows of the rewrite
        return real(self, row)
    monkeypatch.setattr(csv.DictWriter, "writerow", dying_writerow)
    with pytest.raises(KeyboardInterrupt):
        report.write_rows(rows[::-1], path)
    monkeypatch.undo()
    assert path.read_text() == before and len(report.read_rows(path)) == 84


# ---------------------------------------------------------------- dead workers, time limits, a dead driver
def test_a_dead_worker_is_retried_then_recorded_and_the_sweep_goes_on(tmp_path, ids_in_file):
    path = tmp_path / "r.jsonl"
    cases = [{"value": 1, "die": True, "marker": str(tmp_path / "once")},   # dies once: retried
             {"value": 2, "die": True},                                     # always dies: recorded
             {"value": 3}, {"value": 4}]
    records = run_sweep(cases, FUNC, path, executor=Executor(workers=2, retries=1), progress=False)
    by_value = {r["case"]["value"]: r for r in records.values()}
    assert by_value[1]["result"]["square"] == 1 and "error" not in by_value[1]
    assert by_value[2]["error"].startswith("WorkerDied") and "2 time(s)" in by_value[2]["error"]
    assert by_value[3]["result"]["square"] == 9 and by_value[4]["result"]["square"] == 16
    assert sorted(ids_in_file(path)) == sorted(case_id(c) for c in cases)


def test_a_case_over_the_time_limit_is_recorded_as_a_timeout(tmp_path):
    path = tmp_path / "r.jsonl"
    cases = [{"value": 1, "spin": 30.0}, {"value": 2}]
    for executor in (Executor(workers=1, timeout=0.5), Executor(workers=2, timeout=0.5)):
        path.unlink(missing_ok=True)
        t0 = time.perf_counter()
        records = run_sweep(cases, FUNC, path, executor=executor, progress=False, table=False)
        assert time.perf_counter() - t0 < 20
        by_value = {r["case"]["value"]: r for r in records.values()}
        assert by_value[1]["error"].startswith("CaseTimeout") and by_value[2]["result"]["square"] == 4


def test_workers_stop_when_the_driver_is_killed(tmp_path):
    path, pids = tmp_path / "r.jsonl", tmp_path / "pids"
    pids.mkdir()
    script = textwrap.dedent(f"""
        import sys
        sys.path[:0] = {sys.path!r}
        from admmkit.benchmarks.runner.sweep import run_sweep
        cases = [{{"value": v, "pause": 0.4, "pid_dir": {str(pids)!r}}} for v in range(40)]
        run_sweep(cases, {FUNC!r}, {str(path)!r}, workers=2, progress=False)
    """)
    driver = subprocess.Popen([sys.executable, "-c", script], cwd=os.getcwd())
    deadline = time.time() + 60
    while (not path.exists() or len(path.read_text().splitlines()) < 3) and time.time() < deadline:
        time.sleep(0.1)
    assert driver.poll() is None, "the sweep ended before it could be killed"
    driver.kill()
    driver.wait()
    lines = len(path.read_text().splitlines())
    workers = [int(p.name) for p in pids.iterdir()]
    assert len(workers) == 2
    time.sleep(2.0)
    assert [pid for pid in workers if _alive(pid)] == []        # the workers ended with their driver
    assert len(path.read_text().splitlines()) == lines            # and nothing was appended after it
    assert 3 <= lines < 40


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/status") as fh:
            return "\nState:\tZ" not in fh.read()      # a zombie has ended
    except FileNotFoundError:
        return False
    except OSError:  # pragma: no cover - no /proc
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        return True


# ---------------------------------------------------------------- bench policies resumes
def test_bench_policies_resumes(tmp_path, ids_in_file):
    from admmkit.benchmarks.policies.study import run
    kwargs = dict(rules=("quantized",), quick=True, progress=False, max_iter=3000, workers=1,
                  problems=("obstacle",))
    run(tmp_path, **kwargs)
    path = tmp_path / "results.jsonl"
    lines = path.read_text().splitlines()
    assert len(lines) == 2 * 3                             # orders x rho_0
    path.write_text("\n".join(lines[:3]) + "\n" + lines[3][:30])   # interrupted: 3 whole lines and a torn one
    table_before = _without_times(tmp_path / "sweep.csv")
    run(tmp_path, **kwargs)
    assert sorted(ids_in_file(path)) == sorted(json.loads(x)["id"] for x in lines)
    assert _without_times(tmp_path / "sweep.csv") == table_before    # the same iterations, the same table


def _without_times(path: Path) -> list[dict]:
    """The table's rows without the wall-clock column (a re-run case takes another time, nothing else changes)."""
    import csv
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert rows and "iterations" in rows[0]
    return [{k: v for k, v in row.items() if k != "seconds"} for row in rows]


def test_executor_bad_input_names_the_parameter(tmp_path):
    for kwargs, message in [({"workers": 0}, "workers must be an integer >= 1"),
                            ({"dask_workers": 0}, "dask_workers must be an integer >= 1"),
                            ({"chunk": 0}, "chunk must be an integer >= 1"),
                            ({"retries": -1}, "retries must be an integer >= 0"),
                            ({"timeout": 0}, "timeout must be a number of seconds > 0"),
                            ({"scheduler": " "}, "scheduler must be an address"),
                            ({"dask_workers": 2, "scheduler": "tcp://h:8786"}, "either dask_workers")]:
        with pytest.raises(ValueError, match=message):
            Executor(**kwargs)
    with pytest.raises(TypeError, match="executor must be a admmkit.benchmarks.runner.sweep.Executor"):
        run_sweep([{"value": 1}], FUNC, tmp_path / "r.jsonl", executor={"workers": 2})
    records = run_sweep([{"value": v, "group": "g"} for v in range(5)], FUNC, tmp_path / "r.jsonl", progress=False,
                        executor=Executor(workers=2, chunk=2))       # one group split into tasks of 2 cases
    assert sorted(r["result"]["square"] for r in records.values()) == [0, 1, 4, 9, 16]


# ---------------------------------------------------------------- an unguarded script
def test_a_sweep_in_an_unguarded_script_stops_with_the_reason(tmp_path):
    """Spawned workers import the main script again; without the __main__ guard they die while starting.

    The driver must stop with a message that says so, instead of replacing dying workers case after case.
    """
    script = tmp_path / "unguarded.py"
    script.write_text(textwrap.dedent(f"""
        from pathlib import Path
        from admmkit.benchmarks.runner.sweep import run_sweep
        run_sweep([{{"value": v}} for v in range(20)], "json:dumps", Path({str(tmp_path / 'r.jsonl')!r}),
                  workers=2, progress=False, table=False)
    """))
    run = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert run.returncode != 0
    assert "if __name__ ==" in run.stderr and "unguarded.py" in run.stderr, run.stderr[-2000:]
    assert len((tmp_path / "r.jsonl").read_text().splitlines()) < 20      # it stopped before working through them
