"""A resumable, parallel sweep runner: cases in, one JSON line per finished case out.

A *case* is a small JSON-serialisable dict (e.g. ``{"scene": "ex1", "h": 0.025,
"method": "sadmm"}``); its id is a hash of its sorted JSON, so the same case
always has the same id.  :func:`run_sweep`

- skips the cases whose id is already in the results file (resume after an
  interruption without redoing finished cases);
- runs the rest on ``workers`` processes (spawned, BLAS pinned to one thread
  each, so two workers use the two cores without oversubscription);
- starts the cheapest groups first;
- keeps the cases of one *group* (``case["group"]``, e.g. one discrete
  problem) together in one task, so a worker assembles a problem and its
  reference solution once for all the solvers run on it;
- appends each finished case, from the worker that ran it and as soon as it
  is done, as one line ``{"id": ..., "case": ..., "result": ...}`` with a
  single ``write`` on a file opened with O_APPEND, then fsync, so an
  interrupted sweep leaves whole lines only (a torn last line, e.g. from a
  power cut, is ignored on reading);
- prints a progress line (done / total, elapsed, estimated time left, the last case).
"""
from __future__ import annotations

import hashlib
import json
import math
import multiprocessing as mp
import os
import sys
import time
import traceback
from pathlib import Path
from typing import Callable, Iterable

#: environment of the worker processes: one BLAS / OpenMP thread each
THREAD_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "MPLBACKEND": "Agg"}


def case_id(case: dict) -> str:
    """A stable id of a case: the first 16 hex digits of the SHA-1 of its sorted JSON."""
    text = json.dumps(case, sort_keys=True, separators=(",", ":"), default=_json_default)
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
    """Append one record as one JSON line: a single write, then flush and fsync."""
    line = json.dumps(record, sort_keys=True, default=_json_default) + "\n"
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        data = line.encode()
        written = os.write(fd, data)
        if written != len(data):  # a regular file takes the whole write; be loud if not
            raise OSError(f"short write to {path}: {written} of {len(data)} bytes")
        os.fsync(fd)
    finally:
        os.close(fd)


def _json_default(value):
    """numpy scalars and arrays, paths -> JSON."""
    import numpy as np
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def clean_float(v):
    """A float for JSON: inf/nan become None."""
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None


# ---------------------------------------------------------------- workers
_QUEUE = None   # in a worker: where finished case ids are announced to the parent


def _init_worker(queue=None) -> None:
    global _QUEUE
    _QUEUE = queue
    os.environ.update(THREAD_ENV)
    try:
        from threadpoolctl import threadpool_limits
        threadpool_limits(1)
    except Exception:  # pragma: no cover - threadpoolctl is a dependency
        pass


def _run_group(args, notify=None) -> int:
    """Run the cases of one group in this process, appending each result as soon as it is done."""
    func_path, results_path, cases = args
    module_name, func_name = func_path.split(":")
    import importlib
    func = getattr(importlib.import_module(module_name), func_name)
    for cid, case in cases:
        t0 = time.perf_counter()
        try:
            result, error = func(case), None
        except Exception as err:  # a failing case is recorded, the sweep goes on
            result, error = None, f"{type(err).__name__}: {err}\n{traceback.format_exc(limit=4)}"
        rec = {"id": cid, "case": case, "result": result, "seconds": time.perf_counter() - t0}
        if error:
            rec["error"] = error
        append_result(results_path, rec)
        message = (cid, bool(error))
        if notify is not None:
            notify(message)
        elif _QUEUE is not None:
            _QUEUE.put(message)
    return len(cases)


def _fmt_seconds(s: float) -> str:
    s = max(0.0, s)
    if s < 60:
        return f"{s:4.0f}s"
    if s < 3600:
        return f"{int(s // 60)}m{int(s % 60):02d}s"
    return f"{int(s // 3600)}h{int((s % 3600) // 60):02d}m"


class Progress:
    """A one-line progress bar on stderr: [#####-----] done/total, elapsed, eta, last case."""

    def __init__(self, total: int, skipped: int, enabled: bool = True, stream=None):
        self.total, self.skipped, self.enabled = total, skipped, enabled
        self.done, self.failed = 0, 0
        self.start = time.perf_counter()
        self.stream = stream or sys.stderr
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()

    def update(self, label: str, failed: bool = False) -> None:
        """Count one finished case and redraw the line."""
        self.done += 1
        self.failed += int(failed)
        if not self.enabled:
            return
        elapsed = time.perf_counter() - self.start
        todo = self.total - self.skipped
        eta = elapsed / self.done * (todo - self.done) if self.done else float("nan")
        width = 24
        frac = (self.skipped + self.done) / max(self.total, 1)
        bar = "#" * int(round(width * frac)) + "-" * (width - int(round(width * frac)))
        line = (f"[{bar}] {self.skipped + self.done}/{self.total} ({100 * frac:5.1f}%)  "
                f"elapsed {_fmt_seconds(elapsed)}  eta {_fmt_seconds(eta) if self.done else '   ?'}"
                f"{'  failed ' + str(self.failed) if self.failed else ''}  {label[:60]}")
        if self.tty:
            self.stream.write("\r" + line.ljust(150))
        else:
            self.stream.write(line + "\n")
        self.stream.flush()

    def close(self) -> None:
        """End the line."""
        if self.enabled and self.tty:
            self.stream.write("\n")
            self.stream.flush()


def finished(cases: Iterable[dict], results_path: str | Path) -> dict[str, dict]:
    """{id: record} of the given cases that are already in the results file (no case is run)."""
    done = load_results(results_path)
    return {cid: done[cid] for cid in map(case_id, cases) if cid in done}


def run_sweep(cases: Iterable[dict], func: str, results_path: str | Path, *, workers: int = 2,
              progress: bool = True, label: Callable[[dict], str] | None = None,
              cost: Callable[[dict], float] | None = None) -> dict[str, dict]:
    """Run every case not yet in ``results_path`` and return {id: record} of all cases.

    ``func`` is "module:function" (importable by the spawned workers); it takes
    a case and returns a JSON-serialisable dict.  Cases with the same
    ``case["group"]`` run in one task, in the given order; groups are started
    cheapest first (``cost(case)`` summed over the group), so that an
    interrupted sweep has covered the most problems.  ``workers=1``
    runs in this process (no spawning).  A case that raises is recorded with
    its error (``record["error"]``) and not retried on resume; delete its line
    to retry it.
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    cases = list(cases)
    results_path = Path(results_path)
    done = load_results(results_path)
    ids = [case_id(c) for c in cases]
    if len(set(ids)) != len(ids):
        raise ValueError("two cases are identical (same id); cases must differ")
    todo = [(cid, c) for cid, c in zip(ids, cases) if cid not in done]
    groups: dict[str, list] = {}
    for cid, c in todo:
        groups.setdefault(str(c.get("group", cid)), []).append((cid, c))
    # cheapest groups first: a sweep that is interrupted (or time-boxed) has covered the most problems
    order = sorted(groups.values(), key=lambda g: sum((cost or (lambda _c: 1.0))(c) for _, c in g))
    bar = Progress(len(cases), len(cases) - len(todo), enabled=progress)
    name = label or (lambda c: " ".join(f"{k}={v}" for k, v in c.items() if k != "group"))
    by_id = dict(todo)

    def announce(message):
        cid, failed = message
        bar.update(name(by_id.get(cid, {})) + (" FAILED" if failed else ""), failed=failed)

    tasks = [(func, str(results_path), g) for g in order]
    if progress:
        print(f"sweep: {len(cases)} cases, {len(cases) - len(todo)} already in {results_path}, {len(todo)} to run "
              f"in {len(tasks)} groups on {min(workers, max(len(tasks), 1))} worker(s); a line per finished case",
              file=sys.stderr, flush=True)
    if tasks and workers == 1:
        _init_worker()
        for task in tasks:
            _run_group(task, notify=announce)
    elif tasks:
        env_before = {k: os.environ.get(k) for k in THREAD_ENV}
        os.environ.update(THREAD_ENV)      # inherited by the spawned workers from the start
        try:
            ctx = mp.get_context("spawn")
            queue = ctx.Queue()
            with ctx.Pool(min(workers, len(tasks)), initializer=_init_worker, initargs=(queue,)) as pool:
                pending = pool.map_async(_run_group, tasks, chunksize=1)
                import queue as queue_module
                while True:
                    try:
                        announce(queue.get(timeout=0.5))
                    except queue_module.Empty:
                        if pending.ready():
                            break
                pending.get()          # re-raise a worker crash
                while True:
                    try:
                        announce(queue.get_nowait())
                    except queue_module.Empty:
                        break
        finally:
            for k, v in env_before.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v
    bar.close()
    done = load_results(results_path)
    return {cid: done[cid] for cid in ids if cid in done}
