"""The worker side of a sweep: one BLAS thread, one case at a time, a record per case.

Shared by both executors (:mod:`admmkit.benchmarks.runner.sweep_local`,
:mod:`admmkit.benchmarks.runner.sweep_dask`).  A worker never writes the results file: it
returns a record ``{"id", "case", "result", "seconds"}`` (plus ``"error"``
and ``"fault"`` when the case raised or ran out of time) and the driver alone appends it.

A per-case time limit (``timeout``) raises :class:`CaseTimeout` in the thread
running the case at its next Python bytecode (a watchdog timer and
``PyThreadState_SetAsyncExc``), so a long loop of iterations stops; a single
long call into C (a factorisation) finishes first.  The local executor also
kills a worker that overruns the limit by a grace period.
"""
from __future__ import annotations

import ctypes
import importlib
import os
import sys
import threading
import time
import traceback
from contextlib import contextmanager
from typing import Callable

from admmkit.benchmarks.runner.harness import CASE, fault_of

#: environment of the worker processes: one BLAS / OpenMP thread each
THREAD_ENV = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "MPLBACKEND": "Agg"}

_PINNED = False
_FUNCS: dict[str, Callable] = {}


class CaseTimeout(BaseException):
    """Raised in a case that ran longer than the sweep's per-case time limit.

    A BaseException, so that a study's ``except Exception`` (a best-effort
    cross-check, say) does not swallow it.
    """


def init_worker(env: dict | None = None) -> None:
    """Pin BLAS / OpenMP to one thread in this process and set the sweep's environment variables."""
    global _PINNED
    os.environ.update(THREAD_ENV)
    if env:
        os.environ.update({str(k): str(v) for k, v in env.items()})
    if not _PINNED:
        try:
            from threadpoolctl import threadpool_limits
            threadpool_limits(1)
        except Exception:  # pragma: no cover - threadpoolctl is a dependency
            pass
        _PINNED = True


def load(func_path: str) -> Callable:
    """The function named by "module:function" (imported once per process)."""
    if func_path not in _FUNCS:
        module_name, _, func_name = func_path.partition(":")
        if not module_name or not func_name:
            raise ValueError(f"func must be 'module:function', got {func_path!r}")
        _FUNCS[func_path] = getattr(importlib.import_module(module_name), func_name)
    return _FUNCS[func_path]


@contextmanager
def deadline(seconds: float | None):
    """Raise :class:`CaseTimeout` in this thread if the block runs longer than ``seconds`` (None: no limit)."""
    if not seconds:
        yield
        return
    lock, state = threading.Lock(), {"running": True}
    target = threading.get_ident()

    def fire():
        with lock:
            if state["running"]:
                ctypes.pythonapi.PyThreadState_SetAsyncExc(ctypes.c_ulong(target), ctypes.py_object(CaseTimeout))

    timer = threading.Timer(seconds, fire)
    timer.daemon = True
    timer.start()
    try:
        yield
    finally:
        with lock:
            state["running"] = False
        timer.cancel()


def peak_memory_mb() -> float | None:
    """The peak resident memory of this process so far, in MB (None where the OS does not say).

    Recorded with every case (``worker_peak_mb``): the largest value of a
    sweep is what one worker needs (docs/sweeps.md, sizing the workers).
    """
    try:
        import resource
    except ImportError:  # pragma: no cover - Windows
        return None
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return round(peak / (2**20 if sys.platform == "darwin" else 2**10), 1)   # bytes on macOS, KB on Linux


def run_case(func: Callable, cid: str, case: dict, timeout: float | None = None) -> dict:
    """Run one case and return its record; an exception or a timeout becomes the record's ``error``.

    A failed record also says whose failure it is (``fault``: ``"case"`` for a timeout or an exception raised
    inside a rule's own code, ``"harness"`` otherwise; :mod:`admmkit.benchmarks.runner.harness`).
    """
    t0 = time.perf_counter()
    fault = None
    try:
        with deadline(timeout):
            result, error = func(case), None
    except CaseTimeout:
        result, error = None, f"CaseTimeout: the case ran longer than {timeout:g} s (the sweep's --case-timeout)"
        fault = CASE
    except Exception as err:  # a failing case is recorded, the sweep goes on
        result, error = None, f"{type(err).__name__}: {err}\n{traceback.format_exc(limit=4)}"
        fault = fault_of(err)
    rec = {"id": cid, "case": case, "result": result, "seconds": time.perf_counter() - t0}
    peak = peak_memory_mb()
    if peak is not None:
        rec["worker_peak_mb"] = peak
    if error:
        rec["error"], rec["fault"] = error, fault
    return rec


def run_task(func_path: str, cases: list, env: dict | None = None, timeout: float | None = None) -> list[dict]:
    """One task (the cases of one group, in order) in this process: their records (a Dask task)."""
    init_worker(env)
    func = load(func_path)
    return [run_case(func, cid, case, timeout) for cid, case in cases]
