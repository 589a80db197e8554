"""A resumable sweep runner: cases in, one JSON line per finished case out, on local processes or Dask.

A *case* is a small JSON-serialisable dict (e.g. ``{"scene": "ex1", "h": 0.025,
"method": "sadmm"}``); its id is a hash of its sorted JSON, so the same case
always has the same id.  :func:`run_sweep`

- skips the cases whose id is already in the results file (resume after an
  interruption without redoing finished cases);
- runs the rest on an :class:`Executor`: ``workers`` local processes (spawned,
  BLAS pinned to one thread each, :mod:`admmkit.benchmarks.runner.sweep_local`; the
  default) or Dask (a ``LocalCluster`` of single-threaded workers, or a
  running cluster at a scheduler address, :mod:`admmkit.benchmarks.runner.sweep_dask`);
- keeps the cases of one *group* (``case["group"]``, e.g. one discrete
  problem) together in one task, so a worker assembles a problem and its
  reference solution once for all the solvers run on it, and starts the
  cheapest groups first;
- has the workers return a record per case and appends it *in the driver
  alone*, as one line ``{"id": ..., "case": ..., "result": ..., "seconds": ...}``
  with a single ``write`` on a file opened with O_APPEND, then fsync; an id
  already in the file is never written again, and a torn last line (a power
  cut) is ended before the next append, so it costs only itself;
- records a case that raises, overruns ``Executor.timeout`` or keeps killing
  its worker as that case's outcome (``record["error"]``) and goes on, with
  whose failure it is (``record["fault"]``: ``"case"`` for a timeout or an
  exception inside a rule's own code, ``"harness"`` for a missing package,
  an exception elsewhere or a dead worker:
  :mod:`admmkit.benchmarks.runner.harness`); a harness failure is no result,
  so a resumed sweep runs its case again;
- prints a progress line (done / total, elapsed, estimated time left, the last case);
- writes the records as one flat table at the end, ``results.parquet`` (or
  ``results.csv`` without pyarrow) beside the results file
  (:mod:`admmkit.benchmarks.runner.sweep_table`), atomically.

``pandas.read_json(results_path, lines=True)`` loads the results file as it is.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable

from admmkit.benchmarks.runner.sweep_worker import THREAD_ENV  # noqa: F401  (the workers' environment; re-exported)
from admmkit.benchmarks.runner.harness import is_harness_failure
from admmkit.benchmarks.runner.jsonable import json_default
from admmkit.benchmarks.runner.lock import hold
from admmkit.io import named_os_error
from admmkit.benchmarks.runner.progress import Progress


def case_id(case: dict) -> str:
    """A stable id of a case: the first 16 hex digits of the SHA-1 of its sorted JSON."""
    text = json.dumps(case, sort_keys=True, separators=(",", ":"), default=json_default)
    return hashlib.sha1(text.encode()).hexdigest()[:16]


def load_results(path: str | Path) -> dict[str, dict]:
    """{id: record} of the finished cases in a JSONL results file (missing file: {}).

    Lines that do not parse (a torn last line) are skipped; a later line with
    the same id wins.
    """
    path = Path(path)
    out: dict[str, dict] = {}
    if not path.exists():
        return out
    with path.open() as fh:
        for line in fh:
            line = line.strip()
            if not line:
                continue
            try:
                rec = json.loads(line)
            except json.JSONDecodeError:
                continue
            if isinstance(rec, dict) and "id" in rec:
                out[rec["id"]] = rec
    return out


def append_result(path: str | Path, record: dict) -> None:
    """Append one record as one JSON line: a single write, then fsync.

    If the file does not end with a newline (a torn last line), the line
    starts with one, so the torn fragment stays a line of its own (skipped
    on reading) instead of swallowing this record.
    """
    data = (json.dumps(record, sort_keys=True, default=json_default) + "\n").encode()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_RDWR | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        size = os.fstat(fd).st_size
        if size and os.pread(fd, 1, size - 1) != b"\n":
            data = b"\n" + data
        written = os.write(fd, data)
        if written != len(data):  # a regular file takes the whole write; be loud if not
            raise OSError(f"short write to {path}: {written} of {len(data)} bytes")
        os.fsync(fd)
    except OSError as err:        # a full disk: the message names the results file
        raise named_os_error(err, path) from err
    finally:
        os.close(fd)


def clean_float(v):
    """A float for JSON: inf/nan become None."""
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None


def finished(cases: Iterable[dict], results_path: str | Path) -> dict[str, dict]:
    """{id: record} of the given cases that are already in the results file (no case is run)."""
    done = load_results(results_path)
    return {cid: done[cid] for cid in map(case_id, cases) if cid in done}


#: cases per task on Dask unless Executor.chunk says otherwise
DASK_CHUNK = 8


@dataclass(frozen=True)
class Executor:
    """Where a sweep's cases run.

    - ``workers``: local worker processes (spawned, one BLAS thread each; 1 =
      in this process), used when neither of the next two is given;
    - ``dask_workers``: start a Dask ``LocalCluster`` of this many
      single-threaded worker processes for the sweep;
    - ``scheduler``: the address of a running Dask scheduler ("tcp://host:8786");
    - ``timeout``: seconds per case; a case that runs longer is recorded as a
      ``CaseTimeout`` error (None: no limit);
    - ``retries``: how often a case whose worker died is run again before it
      is recorded as a ``WorkerDied`` error;
    - ``chunk``: at most this many cases per task; a larger group is split
      (a worker that already holds the group's problem does not build it
      again).  Default: a whole group per task on local processes (their
      records stream back case by case), ``DASK_CHUNK`` on Dask (a task's
      records arrive when it ends: smaller tasks give a finer progress line
      and resume point and spread a large group over the workers).
    """

    workers: int = 2
    dask_workers: int | None = None
    scheduler: str | None = None
    timeout: float | None = None
    retries: int = 1
    chunk: int | None = None

    def __post_init__(self):
        for name in ("workers", "dask_workers", "retries", "chunk"):
            v = getattr(self, name)
            low = 0 if name == "retries" else 1
            if (v is not None or name in ("workers", "retries")) and (isinstance(v, bool) or not isinstance(v, int)
                                                                      or v < low):
                raise ValueError(f"{name} must be an integer >= {low}, got {v!r}")
        if self.dask_workers is not None and self.scheduler:
            raise ValueError("give either dask_workers (start a LocalCluster) or scheduler (connect to one), not both")
        if self.scheduler is not None and (not isinstance(self.scheduler, str) or not self.scheduler.strip()):
            raise ValueError(f"scheduler must be an address such as 'tcp://host:8786', got {self.scheduler!r}")
        if self.timeout is not None and not (isinstance(self.timeout, (int, float)) and 0 < self.timeout < math.inf):
            raise ValueError(f"timeout must be a number of seconds > 0 or None, got {self.timeout!r}")

    @property
    def task_size(self) -> int | None:
        """At most this many cases per task (None: a whole group)."""
        return self.chunk if self.chunk is not None else (DASK_CHUNK if self.dask else None)

    @property
    def dask(self) -> bool:
        """True if the cases run on Dask."""
        return self.dask_workers is not None or bool(self.scheduler)

    def describe(self, tasks: int) -> str:
        """"2 local worker(s)", "a Dask LocalCluster of 2 workers", "Dask at tcp://..."."""
        if self.scheduler:
            return f"the Dask cluster at {self.scheduler}"
        if self.dask_workers is not None:
            return f"a Dask LocalCluster of {self.dask_workers} worker(s)"
        return f"{min(self.workers, max(tasks, 1))} local worker(s)"


def run_sweep(cases: Iterable[dict], func: str, results_path: str | Path, *, workers: int = 2,
              executor: Executor | None = None, progress: bool = True, label: Callable[[dict], str] | None = None,
              cost: Callable[[dict], float] | None = None, env: dict | None = None,
              table: bool | Callable[[dict], list[dict]] = True) -> dict[str, dict]:
    """Run every case not yet in ``results_path`` and return {id: record} of all cases.

    ``func`` is "module:function" (importable by the workers); it takes a
    case and returns a JSON-serialisable dict.  Cases with the same
    ``case["group"]`` run in one task, in the given order; groups are started
    cheapest first (``cost(case)`` summed over the group), so that an
    interrupted sweep has covered the most problems.  ``executor`` says where
    (default: ``Executor(workers=workers)``; ``workers=1`` runs in this
    process).  ``env``: environment variables set in every worker before its
    cases run.  A case that raises, times out or kills its worker is recorded
    with its error (``record["error"]``) and whose failure it is
    (``record["fault"]``); a resumed sweep runs the harness failures again,
    not the cases' own failures (delete such a line to retry it).  ``table``: write ``results.parquet`` (or .csv)
    beside the results file at the end, one row per record (a function of a
    record returning rows replaces the default flattening; False: no table).
    """
    if executor is None:
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
        executor = Executor(workers=workers)
    elif not isinstance(executor, Executor):
        raise TypeError(f"executor must be a admmkit.benchmarks.runner.sweep.Executor, got {type(executor).__name__}")
    cases = list(cases)
    results_path = Path(results_path)
    with hold(results_path.parent):          # one run per output folder (a second one refuses)
        done = load_results(results_path)
        ids = [case_id(c) for c in cases]
        if len(set(ids)) != len(ids):
            raise ValueError("two cases are identical (same id); cases must differ")
        todo = [(cid, c) for cid, c in zip(ids, cases) if cid not in done or is_harness_failure(done[cid])]
        groups: dict[str, list] = {}
        for cid, c in todo:
            groups.setdefault(str(c.get("group", cid)), []).append((cid, c))
        # cheapest groups first: a sweep that is interrupted (or time-boxed) has covered the most problems
        tasks = sorted(groups.values(), key=lambda g: sum((cost or (lambda _c: 1.0))(c) for _, c in g))
        size = executor.task_size
        if size:
            tasks = [g[i:i + size] for g in tasks for i in range(0, len(g), size)]
        bar = Progress(len(cases), len(cases) - len(todo), enabled=progress)
        name = label or (lambda c: " ".join(f"{k}={v}" for k, v in c.items() if k != "group"))
        by_id = dict(todo)
        written: set[str] = set()

        def emit(rec: dict) -> None:
            """In the driver: append a finished case's record (once) and redraw the progress line."""
            cid = rec["id"]
            if cid in written or cid not in by_id:
                return                      # never a duplicated line
            append_result(results_path, rec)
            written.add(cid)
            failed = bool(rec.get("error"))
            bar.update(name(by_id[cid]) + (" FAILED" if failed else ""), failed=failed)

        if progress:
            print(f"sweep: {len(cases)} cases, {len(cases) - len(todo)} already in {results_path}, {len(todo)} to run "
                  f"in {len(groups)} groups ({len(tasks)} tasks) on {executor.describe(len(tasks))}; a line per finished case",
                  file=sys.stderr, flush=True)
        if tasks:
            results_path.parent.mkdir(parents=True, exist_ok=True)
            if executor.dask:
                from admmkit.benchmarks.runner.sweep_dask import run_dask
                run_dask(tasks, func, emit, scheduler=executor.scheduler, n_workers=executor.dask_workers, env=env,
                         timeout=executor.timeout, retries=executor.retries)
            else:
                from admmkit.benchmarks.runner.sweep_local import run_local
                run_local(tasks, func, emit, workers=executor.workers, env=env, timeout=executor.timeout,
                          retries=executor.retries)
        bar.close()
        done = load_results(results_path)
        records = {cid: done[cid] for cid in ids if cid in done}
        if table and records:
            from admmkit.benchmarks.runner.sweep_table import write_table
            write_table(records.values(), results_path.with_suffix(""), rows=table if callable(table) else None)
        return records


def run_or_report(cases: list[dict], func: str, out: Path, *, report_only: bool = False, env: dict | None = None,
                  **options) -> tuple[dict[str, dict], float | None]:
    """A study's sweep in ``out/results.jsonl``: (records, wall seconds of this invocation).

    ``report_only`` runs nothing and returns the cases already finished (wall None);
    otherwise :func:`run_sweep` with ``env`` set in every worker (an in-process
    one too) and ``options`` (workers, executor, progress, cost, label).
    """
    if report_only:
        return finished(cases, out / "results.jsonl"), None
    t0 = time.perf_counter()
    records = run_sweep(cases, func, out / "results.jsonl", env=env, **options)
    return records, time.perf_counter() - t0
