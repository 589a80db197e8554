"""The sweep runner on Dask (issue #17): a LocalCluster of 2 worker processes, an interrupted and resumed
sweep, a worker killed mid-sweep, a study's command with --scheduler, the pandas tables.

The cases are tiny: random QPs and contact Example 1 at h = 1/10 (:func:`admmkit.benchmarks.framework.executors.run_case`),
paced by a short sleep so that the driver can be interrupted halfway.
"""
import logging
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from admmkit.benchmarks.framework.executors import run_case, tiny_cases
from admmkit.benchmarks.runner.sweep import Executor, case_id, load_results, run_sweep

#: a LocalCluster of worker processes, killed and restarted: minutes on 2 cores, run by `-m study` (CI)
pytestmark = pytest.mark.study

FUNC = f"{__name__}:paced_case"


def paced_case(case):
    """admmkit.benchmarks.framework.executors.run_case after ``pause`` seconds; ``die``: SIGKILL this worker (once, with a marker)."""
    time.sleep(case.get("pause", 0.0))
    marker = case.get("die_once")
    if marker and not os.path.exists(marker):
        Path(marker).touch()
        os.kill(os.getpid(), signal.SIGKILL)
    return run_case({k: v for k, v in case.items() if k not in ("pause", "die_once")})


@pytest.fixture(scope="module")
def cluster():
    """A LocalCluster of 2 single-threaded worker processes (a dead task is retried once, then given up)."""
    import dask
    from distributed import LocalCluster
    from admmkit.benchmarks.runner.sweep_dask import WORKER_SATURATION
    with dask.config.set({"distributed.scheduler.allowed-failures": 1, WORKER_SATURATION: 1.0}):
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                          silence_logs=logging.ERROR) as c:
            yield c


@pytest.fixture(autouse=True)
def _full_cluster(request):
    """Each test starts with both workers up: a test that kills one leaves the nanny restarting it."""
    if "cluster" in request.fixturenames:
        from distributed import Client
        with Client(request.getfixturevalue("cluster").scheduler_address) as client:
            client.wait_for_workers(2, timeout=180)   # a restarted worker imports numpy, scipy and admmkit: over 60 s at load 10
    yield




def test_interrupted_dask_sweep_resumes_with_every_case_once_and_local_iterations(tmp_path, cluster, ids_in_file):
    cases = [c | {"pause": 0.4} for c in tiny_cases(qp=6, contact=4)]
    path = tmp_path / "dask" / "results.jsonl"
    script = textwrap.dedent(f"""
        import sys
        sys.path[:0] = {sys.path!r}
        from admmkit.benchmarks.runner.sweep import Executor, run_sweep
        run_sweep({cases!r}, {FUNC!r}, {str(path)!r}, executor=Executor(dask_workers=2), progress=False)
    """)
    driver = subprocess.Popen([sys.executable, "-c", script], stderr=subprocess.DEVNULL)
    deadline = time.time() + 90
    while (not path.exists() or len(ids_in_file(path)) < 3) and time.time() < deadline and driver.poll() is None:
        time.sleep(0.05)
    assert driver.poll() is None, "the sweep ended before it could be interrupted"
    driver.send_signal(signal.SIGINT)                   # Ctrl-C halfway
    assert driver.wait(60) != 0
    before = ids_in_file(path)
    assert 3 <= len(before) < len(cases)
    # resume on a running cluster (--scheduler): only the missing cases run
    records = run_sweep(cases, FUNC, path, executor=Executor(scheduler=cluster.scheduler_address), progress=False)
    ids = ids_in_file(path)
    assert ids[:len(before)] == before
    assert sorted(ids) == sorted(case_id(c) for c in cases)          # every case exactly once
    assert not any(r.get("error") for r in records.values())
    # the same iterations as the local executor
    local = run_sweep(cases, FUNC, tmp_path / "local" / "results.jsonl", workers=2, progress=False)
    assert {cid: r["result"]["iterations"] for cid, r in local.items()} == \
        {cid: r["result"]["iterations"] for cid, r in records.items()}
    # the results load as one table
    import pandas as pd
    table = pd.read_parquet(path.with_suffix(".parquet"))
    assert len(table) == len(cases) and sorted(table["id"]) == sorted(records)
    assert set(table["result.iterations"]) == {r["result"]["iterations"] for r in records.values()}
    assert len(pd.read_json(path, lines=True)) == len(cases)


def test_a_killed_worker_loses_no_case(tmp_path, cluster, ids_in_file):
    marker = tmp_path / "killed-once"
    cases = [c | {"pause": 0.2} for c in tiny_cases(qp=4, contact=2)]
    cases[1] = cases[1] | {"die_once": str(marker)}       # its worker dies in the middle of the sweep
    path = tmp_path / "results.jsonl"
    records = run_sweep(cases, FUNC, path, executor=Executor(scheduler=cluster.scheduler_address), progress=False)
    assert marker.exists()                                 # a worker was killed
    assert sorted(ids_in_file(path)) == sorted(case_id(c) for c in cases)
    assert all("error" not in r and r["result"]["iterations"] > 0 for r in records.values())
    assert load_results(path).keys() == records.keys()


def test_a_case_that_always_kills_its_worker_is_recorded(tmp_path, cluster):
    cases = [{"kind": "qp", "n": 10, "m": 12, "seed": 0, "policy": "osqp", "order": "zx", "rho": 0.1,
              "group": "g"}, {"kind": "qp", "n": 10, "m": 12, "seed": 1, "policy": "osqp", "order": "zx",
                              "rho": 0.1, "group": "g", "die_always": True}]
    records = run_sweep(cases, f"{__name__}:killer_case", tmp_path / "r.jsonl",
                        executor=Executor(scheduler=cluster.scheduler_address), progress=False)
    by_seed = {r["case"]["seed"]: r for r in records.values()}
    assert by_seed[1]["error"].startswith("WorkerDied") and by_seed[1]["result"] is None
    assert by_seed[0]["result"]["iterations"] > 0          # its group's other case still ran


def killer_case(case):
    """run_case, except that a case with ``die_always`` kills its worker every time."""
    if case.get("die_always"):
        os.kill(os.getpid(), signal.SIGKILL)
    return run_case(case)


def test_bench_command_runs_on_a_dask_scheduler(tmp_path, cluster, capsys):
    from admmkit.cli import main
    out = tmp_path / "paper"
    assert main(["bench", "paper-compare", "--out", str(out), "--quick", "--repeats", "1", "--no-progress",
                 "--scheduler", cluster.scheduler_address]) == 0
    import pandas as pd
    assert len(pd.read_csv(out / "times.csv")) == 2 * 3 * 2
    assert len(pd.read_parquet(out / "results.parquet")) == 2 * 3 * 2
    assert main(["bench", "paper-compare", "--dask-workers", "2", "--scheduler", "tcp://x:1"]) == 2
    assert "not allowed with argument --dask-workers" in capsys.readouterr().err     # one executor at a time


def spin_case(case):
    """A Python loop of ``spin`` seconds (for the per-case time limit on Dask)."""
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < case["spin"]:
        pass
    return {"spun": case["spin"]}


def test_a_case_over_the_time_limit_on_dask_is_recorded_and_the_worker_goes_on(tmp_path, cluster):
    cases = [{"spin": 30.0, "group": "g"}, {"spin": 0.1, "group": "g"}]
    t0 = time.perf_counter()
    records = run_sweep(cases, f"{__name__}:spin_case", tmp_path / "r.jsonl", progress=False,
                        executor=Executor(scheduler=cluster.scheduler_address, timeout=1.0))
    assert time.perf_counter() - t0 < 20
    by_spin = {r["case"]["spin"]: r for r in records.values()}
    assert by_spin[30.0]["error"].startswith("CaseTimeout") and by_spin[0.1]["result"] == {"spun": 0.1}
