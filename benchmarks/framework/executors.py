"""The same sweep on the local executor and on a Dask LocalCluster: ``admmkit bench executors``.

    admmkit bench executors [--out docs/results/executors] [--quick]

Runs the cases of ``admmkit bench policies`` (every rule of
:data:`admmkit.benchmarks.policies.study.RULES`, both orders, contact Example 1 at
h = 1/20 and the radial obstacle at h = 1/16, rho_0 every third decade;
``--quick``: the coarse smoke grid) three times from empty results files, one
after the other in this run: on 2 local worker processes with a group per
task (the local default), the same with 8 cases per task, and on a Dask
``LocalCluster`` of 2 single-threaded workers (8 cases per task, the Dask
default).  Checks that all give the same iteration count for every case and
writes ``executors.csv`` (one row per case) and ``README.md`` with the wall
times, their ratios to the first and the start-up time of the cluster alone.

:func:`run_case` also solves the tiny cases of the executor tests (a random
QP, contact Example 1): an installed function, so that Dask workers of any
cluster can import it.
"""
from __future__ import annotations

import math
import shutil
import statistics
import time
from pathlib import Path

from admmkit.benchmarks.runner.machine import machine_info
from admmkit.benchmarks.runner.report import NOISE_NOTE, machine_markdown, md_table, write_csv, write_text
from admmkit.benchmarks.runner.sweep import Executor, case_id, run_sweep
from admmkit.benchmarks.runner.harness import check_harness, harness_failures

_OPS: dict = {}


def run_case(case: dict) -> dict:
    """A tiny case: ``{"kind": "qp", "n", "m", "seed", "policy", "order", "rho"}`` or
    ``{"kind": "contact", "h", "method", "rho"}``; returns the iterations and the status."""
    import admmkit
    if case["kind"] == "qp":
        from admmkit.problems.qp import random_qp
        qp = random_qp(case["n"], case["m"], kind="mixed", seed=case["seed"])
        res = admmkit.solve(qp, rho=case["rho"], policy=case["policy"], order=case["order"], max_iter=5000)
        return {"iterations": res.iterations, "status": res.status.value, "objective": float(res.objective)}
    if case["kind"] == "contact":
        from admmkit.problems.contact import assemble, example1, solve_scene
        if case["h"] not in _OPS:
            _OPS.clear()
            _OPS[case["h"]] = assemble(example1(h=case["h"]))
        sol = solve_scene(_OPS[case["h"]], case["method"], case["rho"])
        return {"iterations": sol.result.iterations, "status": sol.result.status.value}
    raise ValueError(f"case kind must be 'qp' or 'contact', got {case['kind']!r}")


def tiny_cases(qp: int = 4, contact: int = 4) -> list[dict]:
    """A few random QPs and contact Example 1 at h = 1/10 runs (the executor tests' sweep)."""
    cases = [{"kind": "qp", "n": 20, "m": 30, "seed": s, "policy": p, "order": "zx", "rho": 0.1}
             for s in range(qp // 2 + qp % 2) for p in ("wohlberg", "osqp")][:qp]
    cases += [{"kind": "contact", "h": 0.1, "method": m, "rho": r, "group": "ex1-h0.1"}
              for r in (1e3, 1e4) for m in ("sadmm", "admm1")][:contact]
    return cases


def policies_cases(quick: bool = False) -> list[dict]:
    """The cases of ``bench policies`` (rho_0 every third decade unless quick)."""
    from admmkit.benchmarks.policies.study import build_cases
    cases = build_cases(quick=quick, max_iter=3000 if quick else 20_000)
    if not quick:
        cases = [c for c in cases if round(math.log10(c["rho0"])) % 3 == 0]
    return cases


def _timed(cases, path: Path, executor: Executor, progress: bool) -> tuple[dict, float]:
    if path.parent.exists():
        shutil.rmtree(path.parent)
    t0 = time.perf_counter()
    records = run_sweep(cases, "admmkit.benchmarks.policies.study:run_case", path, executor=executor, progress=progress)
    return records, time.perf_counter() - t0


def cluster_startup() -> float:
    """Seconds to start and connect to a 2-worker LocalCluster (and close it), as run_sweep does."""
    import logging

    from distributed import Client, LocalCluster
    t0 = time.perf_counter()
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                      silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
        client.wait_for_workers(2)
        seconds = time.perf_counter() - t0
    return seconds


def run(out="out/executors", *, quick: bool = False, rounds: int = 2, progress: bool = True,
        command: str = "admmkit bench executors") -> list[Path]:
    """Run the comparison ``rounds`` times (executor order reversed every other round) and write
    executors.csv and README.md; return the files."""
    if isinstance(rounds, bool) or not isinstance(rounds, int) or rounds < 1:
        raise ValueError(f"rounds must be an integer >= 1, got {rounds!r}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    cases = policies_cases(quick)
    runs = {"local": ("local processes (2 workers, a group per task)", Executor(workers=2)),
            "local8": ("local processes (2 workers, 8 cases per task)", Executor(workers=2, chunk=8)),
            "dask": ("Dask LocalCluster (2 workers, 8 cases per task)", Executor(dask_workers=2))}
    done, walls, work = {}, {k: [] for k in runs}, {k: [] for k in runs}
    for r in range(rounds):
        for key in (list(runs) if r % 2 == 0 else list(runs)[::-1]):
            done[key], wall = _timed(cases, out / key / "results.jsonl", runs[key][1], progress)
            walls[key].append(wall)
            work[key].append(sum(rec.get("seconds", 0.0) for rec in done[key].values()))
            if progress:
                print(f"round {r + 1}, {key}: {wall:.1f} s", flush=True)
    startup = cluster_startup()
    rows, same = [], 0
    for c in cases:
        cid = case_id(c)
        its = {k: ((done[k].get(cid) or {}).get("result") or {}).get("iterations") for k in runs}
        ok = its["local"] is not None and len(set(its.values())) == 1
        same += ok
        rows.append({"problem": c["problem"], "rule": c["rule"], "order": c["order"], "rho0": c["rho0"],
                     **{f"iterations_{k}": v for k, v in its.items()}, "same": ok,
                     **{f"seconds_{k}": (done[k].get(cid) or {}).get("seconds") for k in runs}})
    files = [write_csv(out / "executors.csv", rows)]
    med = {k: statistics.median(v) for k, v in walls.items()}
    body = [[label, " / ".join(f"{w:.1f}" for w in walls[k]), f"{med[k]:.1f}", f"{med[k] / med['local']:.2f}",
             " / ".join(f"{w:.0f}" for w in work[k])] for k, (label, _) in runs.items()]
    text = "\n".join([
        "# The same sweep on the local executor and on Dask", "",
        f"Produced by `{command}`: the cases of `admmkit bench policies`"
        f"{' (--quick grid)' if quick else ' (rho_0 every third decade)'}, {len(cases)} cases in "
        f"{len({c['group'] for c in cases})} groups, run from empty results files on each executor, "
        f"one after the other, {rounds} round(s) (the order reversed in every second round).", "",
        f"**Identical iteration counts on the three executors: {same} of {len(cases)} cases** (last round).", "",
        md_table(["executor", "wall time per round [s]", "median [s]", "ratio to local",
                  "sum of per-case seconds [s]"], body, "lrrrr"), "",
        "The Dask wall times include starting the LocalCluster; starting and connecting to a 2-worker "
        f"LocalCluster alone took {startup:.1f} s in this run.  The last column adds the wall seconds of every "
        "case as its worker measured them: where it grows with the wall time, the cases themselves ran slower "
        "(the load of the shared machine), not the executor.  Per-case times of the last round are in "
        "executors.csv; its raw records in local/, local8/ and dask/ (results.jsonl, results.parquet).", "",
        NOISE_NOTE, "", machine_markdown(machine_info(pinned_blas=True))])
    files.append(write_text(out / "README.md", text))
    if progress:
        print(text)
    failed = [r for key in runs for r in harness_failures(done[key])]
    check_harness(failed, len(cases) * len(runs), files, left_out="no iterations to compare on them (not 'same')")
    return files
