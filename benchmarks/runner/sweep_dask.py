"""The Dask executor of a sweep: the same tasks on a ``dask.distributed`` cluster.

``scheduler="tcp://host:8786"`` connects to a running cluster (started by
``dask scheduler`` / ``dask worker``, or by ``dask-jobqueue`` on SLURM or
PBS: docs/sweeps.md); ``n_workers=N`` starts a ``LocalCluster`` of N
single-threaded worker processes on this machine and closes it at the end.

Each task is one group of cases (:func:`admmkit.benchmarks.runner.sweep_worker.run_task`,
so a worker assembles a problem once for all the cases of its group); it
returns the records and the driver alone appends them to the results file,
so the workers need the installed package and nothing else (no shared disk).
Tasks carry priorities in the driver's order (cheapest group first).

A worker that dies has its task rerun by the scheduler on another worker
(Dask's ``distributed.scheduler.allowed-failures``, set here from
``retries`` for a cluster this driver starts, with ``worker-saturation``
1, so that a worker holds no queued task that would die with it).  A task the scheduler gives up
on (``KilledWorker``) is split into one task per case and resubmitted once,
so that only the case that kills its workers is recorded as an error and its
group's other cases still run.
"""
from __future__ import annotations

import logging
import time

from admmkit.benchmarks.runner.harness import HARNESS
from admmkit.benchmarks.runner.sweep_worker import THREAD_ENV, run_task


#: the scheduler's setting that lets a worker hold tasks beyond the one it runs (this driver's clusters: 1.0)
WORKER_SATURATION = "distributed.scheduler.worker-saturation"


def _error_record(cid, case, err) -> dict:
    return {"id": cid, "case": case, "result": None, "seconds": 0.0,
            "error": f"WorkerDied: {type(err).__name__}: {err}", "fault": HARNESS}


def run_dask(tasks: list[list], func_path: str, emit, *, scheduler: str | None = None, n_workers: int | None = None,
             env: dict | None = None, timeout: float | None = None, retries: int = 1,
             connect_timeout: float = 30.0) -> None:
    """Run the tasks (lists of (id, case)) on Dask; ``emit(record)`` for each finished case, in the driver."""
    try:
        import dask
        from distributed import Client, LocalCluster, as_completed
    except ImportError as err:  # pragma: no cover - depends on the installation
        raise ImportError("the Dask executor needs dask.distributed: pip install 'admmkit[sweep]' "
                          "(or pip install 'dask[distributed]')") from err
    if not tasks:
        return
    cluster = None
    # worker-saturation 1: a worker holds only the task it runs, so a worker that dies takes no queued task of
    # another group with it (with Dask's default 1.1 the next task waits on the worker and counts as suspicious)
    with dask.config.set({"distributed.scheduler.allowed-failures": retries, WORKER_SATURATION: 1.0}):
        if scheduler:
            client = Client(scheduler, timeout=connect_timeout)
        else:
            cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=logging.ERROR,
                                   env={**THREAD_ENV, **{str(k): str(v) for k, v in (env or {}).items()}})
            client = Client(cluster)
        try:
            stamp = f"{time.time_ns():x}"
            pending = {}

            def submit(i, cases, priority, split):
                fut = client.submit(run_task, func_path, cases, env, timeout, key=f"admmkit-sweep-{stamp}-{i}",
                                    priority=priority, pure=False)
                pending[fut] = (cases, split)
                return fut

            queue = as_completed([submit(i, cases, len(tasks) - i, False) for i, cases in enumerate(tasks)])
            extra = len(tasks)
            for fut in queue:
                cases, split = pending.pop(fut)
                try:
                    records = fut.result()
                except Exception as err:   # KilledWorker, a lost connection, ...
                    if not split and len(cases) > 1:
                        for c in cases:        # find the case that kills workers; run the others
                            extra += 1
                            queue.add(submit(extra, [c], len(tasks), True))
                        continue
                    records = [_error_record(cid, case, err) for cid, case in cases]
                finally:
                    fut.release()
                for rec in records:
                    emit(rec)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
