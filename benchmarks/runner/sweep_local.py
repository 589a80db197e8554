"""The local executor of a sweep: spawned worker processes on this machine, one BLAS thread each.

The driver hands each idle worker one task (the cases of one group) through
a pipe; the worker sends back a record per finished case as soon as it is
done and the driver alone appends it to the results file.  So:

- a worker that dies (killed, out of memory, a crash in C) loses nothing
  already sent; the case it was running is retried on a new worker
  (``retries`` times), then recorded as that case's error, and the rest of
  its task goes on;
- a case that overruns the per-case time limit by a grace period (stuck in
  one long C call, where :func:`admmkit.benchmarks.runner.sweep_worker.deadline` cannot
  reach it) is recorded as a timeout and its worker replaced;
- a worker whose parent (the driver) dies exits at once: on Linux the kernel
  kills it (``prctl(PR_SET_PDEATHSIG)``), elsewhere a watchdog thread sees
  its parent change within half a second, and a closed pipe ends it too.
  Nothing is appended after the driver is gone, since only the driver writes.
"""
from __future__ import annotations

import collections
import multiprocessing as mp
import os
import signal
import sys
import threading
import time
from multiprocessing.connection import wait

from admmkit.benchmarks.runner.harness import CASE, HARNESS
from admmkit.benchmarks.runner.sweep_worker import THREAD_ENV, init_worker, load, run_case

#: seconds past the per-case time limit after which the driver kills the worker
GRACE = 10.0


def _watch_parent(ppid: int) -> None:
    """Exit this process as soon as the process ``ppid`` is no longer its parent."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, signal.SIGKILL)          # PR_SET_PDEATHSIG: killed when the parent dies
        except Exception:  # pragma: no cover - the watchdog below still works
            pass
    if os.getppid() != ppid:
        os._exit(1)

    def watch():
        while True:
            time.sleep(0.5)
            if os.getppid() != ppid:
                os._exit(1)
    threading.Thread(target=watch, daemon=True, name="parent-watch").start()


def _worker(conn, func_path: str, env: dict | None, timeout: float | None, ppid: int) -> None:
    """A worker's loop: receive a task, send a record per case, then ("done", task id)."""
    _watch_parent(ppid)
    init_worker(env)
    try:
        func = load(func_path)
    except Exception as err:    # every case records why (instead of workers dying one after another)
        def func(case, err=err):
            raise RuntimeError(f"cannot load {func_path}: {type(err).__name__}: {err}")
    conn.send(("ready", None, None))
    while True:
        try:
            message = conn.recv()
        except (EOFError, OSError):
            os._exit(0)
        if message is None:
            return
        task_id, cases = message
        for cid, case in cases:
            rec = run_case(func, cid, case, timeout)
            try:
                conn.send(("record", task_id, rec))
            except (BrokenPipeError, OSError):
                os._exit(0)
        conn.send(("done", task_id, None))


class _Slot:
    """One worker process and the task it is running."""

    def __init__(self, ctx, func_path, env, timeout):
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_worker, args=(child, func_path, env, timeout, os.getpid()), daemon=True)
        self.proc.start()
        child.close()
        self.task = None        # (task id, list of (cid, case) not yet recorded)
        self.ready = False      # the worker has started (imported its modules and the case runner)
        self.since = 0.0        # when the running case started (the last record or the hand-over)

    def give(self, task_id, cases) -> None:
        self.task = (task_id, list(cases))
        self.since = time.monotonic()
        try:
            self.conn.send((task_id, self.task[1]))
        except (BrokenPipeError, OSError):
            pass                # the worker died: the driver's loop sees it and requeues the task

    def stop(self, wait_s: float = 2.0) -> None:
        try:
            self.conn.send(None)
        except (BrokenPipeError, OSError):
            pass
        self.proc.join(wait_s)
        if self.proc.is_alive():
            self.proc.kill()
            self.proc.join(wait_s)
        self.conn.close()


def run_local(tasks: list[list], func_path: str, emit, *, workers: int, env: dict | None = None,
              timeout: float | None = None, retries: int = 1) -> None:
    """Run the tasks (lists of (id, case)) on ``workers`` spawned processes; ``emit(record)`` each finished case."""
    if workers == 1:
        init_worker(env)
        func = load(func_path)
        for cases in tasks:
            for cid, case in cases:
                emit(run_case(func, cid, case, timeout))
        return
    before = {k: os.environ.get(k) for k in THREAD_ENV}
    os.environ.update(THREAD_ENV)          # inherited by the spawned workers from their first import
    ctx = mp.get_context("spawn")
    queue = collections.deque(enumerate(tasks))
    deaths: dict[str, int] = collections.Counter()
    any_started, startup_deaths = False, 0
    slots: list[_Slot] = []
    try:
        while queue or any(s.task for s in slots):
            while queue and len(slots) < workers:
                slots.append(_Slot(ctx, func_path, env, timeout))
            for i, s in enumerate(slots):
                if s.task is None and queue:
                    if not s.proc.is_alive():        # died between tasks: replace it
                        s.stop(0)
                        slots[i] = s = _Slot(ctx, func_path, env, timeout)
                    s.give(*queue.popleft())
            busy = [s for s in slots if s.task]
            ready = wait([s.conn for s in busy] + [s.proc.sentinel for s in busy], timeout=0.5)
            for s in busy:
                dead = _drain(s, emit) or s.proc.sentinel in ready and not s.proc.is_alive()
                any_started = any_started or s.ready
                startup_deaths += bool(dead and not s.ready)
                if startup_deaths >= 2 * workers and not any_started:
                    raise RuntimeError(_startup_failure(func_path, startup_deaths))
                overdue = timeout and s.task and time.monotonic() - s.since > timeout + GRACE
                if s.task and (dead or overdue):
                    _lost_worker(s, emit, queue, deaths, retries, overdue=bool(overdue and not dead))
                    slots[slots.index(s)] = _Slot(ctx, func_path, env, timeout)
                elif dead:
                    slots.remove(s)
            del ready
    finally:
        for s in slots:
            s.stop()
        for k, v in before.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _startup_failure(func_path: str, deaths: int) -> str:
    """Why a sweep stops when its workers die before they start (the usual cause: an unguarded script)."""
    main = getattr(sys.modules.get("__main__"), "__file__", None)
    return (f"the sweep's worker processes died {deaths} times while starting, before loading {func_path}. "
            f"Each spawned worker imports the main script again{f' ({main})' if main else ''}: a script that runs "
            f"a sweep on local processes must start it under `if __name__ == \"__main__\":` (or use workers=1)")


def _drain(slot: _Slot, emit) -> bool:
    """Take every message the worker has sent; True if its pipe is closed (the worker is gone)."""
    try:
        while slot.conn.poll():
            kind, task_id, rec = slot.conn.recv()
            if kind == "record":
                slot.task[1][:] = [(c, x) for c, x in slot.task[1] if c != rec["id"]]
                slot.since = time.monotonic()
                emit(rec)
            elif kind == "done":
                slot.task = None
            elif kind == "ready":
                slot.ready = True
    except (EOFError, OSError):
        return True
    return False


def _lost_worker(slot: _Slot, emit, queue, deaths, retries: int, overdue: bool) -> None:
    """The worker died (or overran the time limit): retry or record the case it was running, requeue the rest."""
    task_id, remaining = slot.task
    slot.task = None
    if slot.proc.is_alive():
        slot.proc.kill()
    slot.proc.join(5)
    code = slot.proc.exitcode
    slot.conn.close()
    if not remaining:
        return
    cid, case = remaining[0]
    deaths[cid] += 1
    if overdue or deaths[cid] > retries:
        why = (f"CaseTimeout: the case overran the per-case time limit by {GRACE:g} s; its worker was killed"
               if overdue else f"WorkerDied: the worker process running this case ended (exit code {code}) "
                               f"{deaths[cid]} time(s)")
        emit({"id": cid, "case": case, "result": None, "seconds": time.monotonic() - slot.since, "error": why,
              "fault": CASE if overdue else HARNESS})
        remaining = remaining[1:]
    if remaining:
        queue.appendleft((task_id, remaining))
