"""What the command line shows and writes: the progress bar, the summary, JSON and CSV results.

Kept apart from :mod:`admmkit.cli` (the parser and the exit codes) so that each
module has one job.  Every file is written whole or not at all
(:mod:`admmkit.io`); every JSON carries its provenance (:func:`provenance`).
"""
from __future__ import annotations

import csv
import json
import math
import os
import sys
import time
from pathlib import Path

from .. import __version__
from ..io import atomic_open, write_text

#: a progress bar appears once a run has taken this many seconds of wall time
PROGRESS_DELAY = 2.0
#: and is refreshed every this many seconds
PROGRESS_INTERVAL = 0.5
#: seconds between the plain lines that replace the bar on a stream that is not a terminal (a log, a pipe)
PROGRESS_LOG_INTERVAL = 10.0


def is_terminal(stream) -> bool:
    """Whether ``stream`` is a terminal (``isatty()``); a file, a pipe or a StringIO is not."""
    isatty = getattr(stream, "isatty", None)
    try:
        return bool(callable(isatty) and isatty())
    except (ValueError, OSError):          # a closed stream
        return False


class Progress:
    """Progress of one solve on stderr, as a context manager that yields the ``callback`` to pass to solve.

    Nothing is shown for runs shorter than ``delay`` seconds (default :data:`PROGRESS_DELAY`).  After that,
    on a terminal, a tqdm bar (iterations of the ``total`` cap, rate, rho) is refreshed every ``interval``
    seconds (default :data:`PROGRESS_INTERVAL`).  On a stream that is not a terminal (a log: a file, a pipe)
    no bar is drawn: one plain line ``ADMM: iteration k (cap N), t s, r it/s, rho=...`` is written once the run
    has taken ``delay`` seconds (its iterations at least ``interval``) and then every ``log_interval`` seconds (default :data:`PROGRESS_LOG_INTERVAL`),
    so a log holds no carriage return and a few lines at most per minute.  ``lines`` (a callback printing every
    N iterations, ``--progress N``) replaces both.  The callback reads only ``rec.k`` and ``rec.rho`` (no norm is
    computed for it) and always returns None, so it never steers or stops a run.  ``enabled=False``
    (``--quiet``) yields None.
    """

    #: the bar needs no record of every iteration (it reads k and rho of those it is given): the loop may run the
    #: iterations between its tests in a compiled segment (``admmkit.loop.segments``), and the bar sees the tested ones
    every_record = False
    #: nor of every tested iteration: a segment that makes the loop's decisions itself (SADMM's rule and the paper's
    #: stop in the condensed contact mode, OSQP's test and rule in the QP's) runs on past them, the bar sees the rest
    every_tested = False

    def __init__(self, total: int, *, enabled: bool = True, lines=None, delay: float | None = None,
                 interval: float | None = None, file=None, log_interval: float | None = None) -> None:
        self.total, self.enabled, self.lines = int(total), enabled, lines
        self.delay = float(PROGRESS_DELAY if delay is None else delay)
        self.interval = float(PROGRESS_INTERVAL if interval is None else interval)
        self.log_interval = float(PROGRESS_LOG_INTERVAL if log_interval is None else log_interval)
        self.file = file
        self.bar = None
        self._first, self._next, self._terminal = None, math.inf, True

    def __enter__(self):
        if not self.enabled:
            return None
        if self.lines is not None:
            return self.lines
        self._first = None
        self._next = time.perf_counter() + self.delay
        self._terminal = is_terminal(self.file or sys.stderr)
        return self

    def __call__(self, rec) -> None:
        now = time.perf_counter()
        if self._first is None:
            self._first = now                             # the iterations start here (after the set-up)
        if not self._terminal:                            # a log: a plain line once the iterations have a rate
            if now >= self._next and now - self._first >= self.interval:
                self._next = now + self.log_interval
                self._log_line(rec, now - self._first)
            return None
        if now < self._next or (self.bar is None and now - self._first < self.interval):
            return None                                   # (a rate needs some iterations behind it)
        self._next = now + self.interval
        if self.bar is None:
            from tqdm import tqdm
            self.bar = tqdm(total=self.total, desc="ADMM", unit="it", file=self.file or sys.stderr, leave=False,
                            dynamic_ncols=True, mininterval=0, smoothing=0, delay=1e-3,
                            bar_format="{desc}: {n}/{total} iterations (cap) [{elapsed}, {rate_fmt}{postfix}]")
            self.bar.start_t -= now - self._first       # elapsed and rate count from the first iteration
        self.bar.n = rec.k + 1
        self.bar.set_postfix_str(f"rho={rec.rho:.3g}", refresh=False)
        self.bar.refresh()
        return None

    def _log_line(self, rec, seconds: float) -> None:
        """One plain line for a log: the iteration, the cap, the time since the first iteration, the rate, rho."""
        done = rec.k + 1
        rate = f", {done / seconds:.3g} it/s" if seconds > 0 else ""
        stream = self.file or sys.stderr
        stream.write(f"ADMM: iteration {done} (cap {self.total}), {seconds:.1f} s{rate}, rho={rec.rho:.3g}\n")
        stream.flush()

    def __exit__(self, *exc) -> None:
        if self.bar is not None:
            self.bar.close()                 # leave=False: on a terminal the line is cleared
            self.bar = None


def exit_code(result: Result) -> int:
    """0 if the run converged, 1 for any other status (max_iter, diverged, converged_inaccurate, ...)."""
    from ..loop.result import Status
    return 0 if result.status is Status.CONVERGED else 1


def number(value) -> str:
    """A number for people: integers as integers, others with 4 significant digits in e-notation."""
    import numpy as np
    if isinstance(value, (bool, np.bool_)):
        return str(bool(value))
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    return f"{float(value):.3e}"


def summary_lines(result: Result, name: str | None = None, rho0: float | None = None) -> list[str]:
    """:meth:`admmkit.Result.summary` with the method line naming ``name`` and rho_0, and integers printed as integers."""
    lines = []
    for line in result.summary().splitlines():
        label = line[:12].strip()
        if label == "method" and name is not None:
            line = f"method       {name}: order={result.order}  policy={result.policy}" + \
                   (f"  rho_0 = {rho0:g}" if rho0 is not None else "")
        elif label == "KKT" and result.kkt:
            line = "KKT          " + "   ".join(f"{k} {number(v)}" for k, v in result.kkt.items())
        lines.append(line)
    return lines


def print_summary(result: Result, name: str | None = None, rho0: float | None = None) -> None:
    """Print :func:`summary_lines`."""
    print("\n".join(summary_lines(result, name, rho0)))


def check_output_folder(value: str | Path, flag: str = "--out") -> Path:
    """An output folder that exists as a writable folder or can be created; ValueError naming ``flag`` otherwise."""
    path = Path(value)
    if path.exists() and not path.is_dir():
        raise ValueError(f"{flag} {str(path)!r} is a file, not a folder")
    parent = path
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise ValueError(f"{flag} {str(path)!r}: {str(parent)!r} is a file, not a folder")
    if not os.access(parent, os.W_OK):
        raise ValueError(f"{flag} {str(path)!r}: the folder {str(parent)!r} is not writable")
    return path


def jsonable(value):
    """``value`` with numpy scalars and arrays, paths, enums and tuples turned into JSON types."""
    from ..loop.result import Status
    import numpy as np
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return v if math.isfinite(v) else str(v)           # JSON has no inf/nan: "inf", "nan"
    if isinstance(value, Status):
        return value.value
    if value is None or isinstance(value, str):
        return value
    if callable(value):                                     # a scene's expression keeps its text
        return getattr(value, "expression", None) or f"<callable {getattr(value, '__name__', type(value).__name__)}>"
    return str(value)


def provenance(args=None, **extra) -> dict:
    """Who wrote a result and how: admmkit version, UTC date, command line, Python, policy and stopping rule."""
    import datetime as _dt          # (imported here: a run that writes no file imports neither, 6 ms)
    import platform

    import numpy as np
    out = {"admmkit_version": __version__,
           "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
           "command_line": getattr(args, "command_line", None) or " ".join(sys.argv),
           "python": platform.python_version(), "numpy": np.__version__, "platform": platform.platform()}
    resolved = getattr(args, "resolved", None) or {}
    if args is not None:
        out |= {"policy": resolved.get("policy", getattr(args, "policy", None)), "order": resolved.get("order"),
                "policy_parameters": resolved.get("policy_repr"), "rho0": getattr(args, "rho", None),
                "stopping_rule": resolved.get("stop"), "max_iter": getattr(args, "max_iter", None)}
    return jsonable(out | extra)


def result_record(result: Result) -> dict:
    """The scalars of a :class:`admmkit.Result` (status, iterations, rho, work, times, KKT) as a JSON-ready dict."""
    return jsonable({"status": result.status.value, "converged": result.converged, "message": result.message,
                     "stopped_by": result.stopped_by, "iterations": result.iterations, "rho_final": result.rho,
                     "rho_changes": result.rho_changes, "order": result.order, "policy": result.policy,
                     "alpha": result.alpha, "objective": result.objective, "kkt": result.kkt,
                     "accuracy": result.accuracy, "counters": result.counters, "time": result.timings})


def write_result_json(path: str | Path, result: Result, args=None, *, problem: dict | None = None,
                      arrays: dict | None = None) -> Path:
    """JSON of a run: ``provenance``, ``problem`` (the plug-in's parameters), ``result`` and ``arrays``."""
    data = {"provenance": provenance(args), "problem": jsonable(problem or {}), "result": result_record(result),
            "arrays": jsonable(arrays or {})}
    return write_text(path, json.dumps(data, indent=1) + "\n")


def write_result_csv(path: str | Path, columns: dict) -> Path:
    """CSV with one column per entry of ``columns`` (equal lengths), full precision, written whole or not at all."""
    import numpy as np
    names = list(columns)
    values = [np.asarray(columns[n]) for n in names]
    lengths = {len(v) for v in values}
    if len(lengths) > 1:
        raise ValueError(f"CSV columns must have equal lengths, got {dict(zip(names, map(len, values)))}")
    with atomic_open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(names)
        for row in zip(*values):
            writer.writerow([_cell(v) for v in row])
    return Path(path)


def _cell(v) -> str:
    import numpy as np
    if isinstance(v, (bool, np.bool_)):
        return str(int(v))
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    return str(v)
