"""What a study needs installed, and which failed cases are the harness's rather than the subject's.

Two promises of every study (docs/cli.md, "Studies"):

- a study that needs a package this installation lacks refuses before any
  work, in one line naming the pip command (:func:`require`, raising
  :class:`MissingPackage`, a ``ValueError``: ``admmkit: error: ...``, exit 2);
- a case that fails for a reason other than the thing it studies (a missing
  package, an exception raised outside the rule's own code, a worker process
  that died) is a *harness failure*: it is never scored as the rule's, and
  the study says how many there were and exits 1 (:func:`check_harness`,
  raising :class:`HarnessFailed`).  A rule's own failure (an exception raised
  inside the rule's methods, a run that diverged, a case over its time limit)
  stays the rule's.

The sweep's worker marks each failed record with ``record["fault"]``:
``"harness"`` or ``"case"`` (:func:`fault_of`).
"""
from __future__ import annotations

import importlib.util
import traceback
from collections import Counter

#: the pip command that brings each optional module (the extras of pyproject.toml) or dependency back
PIP = {
    "dask": 'pip install "admmkit[sweep]"',
    "distributed": 'pip install "admmkit[sweep]"',
    "pandas": 'pip install "admmkit[sweep]"',
    "pyarrow": 'pip install "admmkit[sweep]"',
    "pyproximal": 'pip install "admmkit[prox]"',
    "cvxpy": 'pip install "cvxpy>=1.4"',
    "clarabel": 'pip install "clarabel>=0.6"',
    "osqp": 'pip install "osqp>=1.0"',
}
#: the names users know the modules by (``distributed`` comes with ``dask[distributed]``)
KNOWN_AS = {"distributed": "dask.distributed"}
#: the error types (the first word of a record's error) that are always the harness's
HARNESS_ERRORS = ("ModuleNotFoundError", "ImportError", "WorkerDied")
#: a record's ``fault`` for a harness failure, and for a failure of the case itself (the rule, the solver studied)
HARNESS, CASE = "harness", "case"


class MissingPackage(ValueError):
    """A study needs a package this installation lacks (one line, exit 2, before any work)."""


class HarnessFailed(RuntimeError):
    """Some cases of a study failed in the harness; what the study wrote leaves them out.

    ``files``: the files the study wrote from the other cases (the command prints them before the error).
    """

    def __init__(self, message: str, files=()):
        super().__init__(message)
        self.files = list(files)


def missing(module: str) -> bool:
    """True if ``module`` cannot be imported here (not installed, or blocked as ``sys.modules[name] = None``).

    Looked up without importing it (a study refuses in its first second, not after cvxpy's import).
    """
    try:
        return importlib.util.find_spec(module) is None
    except (ImportError, ValueError):
        return True


def require(command: str, *modules: str) -> None:
    """Raise :class:`MissingPackage` naming ``command``, the first missing module and its pip command.

    ``require("bench executors", "dask", "distributed")`` -> ``bench executors needs dask.distributed: pip
    install "admmkit[sweep]"``.
    """
    for module in modules:
        if missing(module):
            pip = PIP.get(module, f"pip install {module}")
            raise MissingPackage(f"{command} needs {KNOWN_AS.get(module, module)}: {pip}")


def require_executor(command: str, args) -> None:
    """Dask's packages when the options ask for Dask (``--dask-workers``, ``--scheduler``)."""
    if getattr(args, "dask_workers", None) is not None or getattr(args, "scheduler", None):
        require(command, "dask", "distributed")


def _in_a_rule(tb) -> bool:
    """Whether the traceback passes through a method of a penalty rule (an ``admmkit.Policy``), or through the
    step that calls the rule and checks what it returned (``admmkit.loop.steps.PolicyStep``)."""
    from admmkit.policy import Policy
    from admmkit.loop.steps import PolicyStep
    for frame, _ in traceback.walk_tb(tb):
        if isinstance(frame.f_locals.get("self"), (Policy, PolicyStep)):
            return True
    return False


def fault_of(err: BaseException) -> str:
    """``"case"`` if ``err`` was raised inside a rule's own code, else ``"harness"``.

    An ``ImportError`` is the harness's wherever it was raised (an install fixes it).
    """
    if isinstance(err, ImportError):
        return HARNESS
    return CASE if _in_a_rule(err.__traceback__) else HARNESS


def is_harness_failure(record: dict) -> bool:
    """Whether a finished case's record is a harness failure.

    Records written before the ``fault`` mark: an import error or a dead worker is the harness's, any
    other error the case's (as they were scored then).
    """
    if not record.get("error"):
        return False
    if "fault" in record:
        return record["fault"] == HARNESS
    return str(record["error"]).split(":", 1)[0].strip() in HARNESS_ERRORS


def first_line(error: str) -> str:
    """``ModuleNotFoundError: No module named 'cvxpy'``: the error's first line."""
    return (str(error).strip().splitlines() or ["error"])[0]


def harness_failures(records) -> list[dict]:
    """The harness failures among the records (a dict of records or an iterable)."""
    values = records.values() if isinstance(records, dict) else records
    return [r for r in values if is_harness_failure(r)]


def harness_message(failed: list[dict], total: int, left_out: str = "nothing ranked on them") -> str:
    """``576 of 960 cases failed in the harness (ModuleNotFoundError: No module named 'cvxpy'); ...``."""
    causes = Counter(first_line(r["error"]) for r in failed)
    cause, count = causes.most_common(1)[0]
    if len(causes) > 1:
        cause += f", {count} times; {len(causes) - 1} other cause(s)"
    return (f"{len(failed)} of {total} cases failed in the harness ({cause}); {left_out}; fix it and run the same "
            "command again: those cases run again")


def without_harness_failures(records: dict) -> tuple[dict, list[dict]]:
    """({id: record} of the cases that did not fail in the harness, the harness failures)."""
    kept = {cid: r for cid, r in records.items() if not is_harness_failure(r)}
    return kept, [r for r in records.values() if is_harness_failure(r)]


def check_something_left(kept, failed: list[dict], total: int, results, report_only: bool) -> None:
    """Before a summary: refuse in one line when no case is left to summarise.

    Every case failed in the harness: :class:`HarnessFailed` (no file written); ``--report-only`` on a
    folder without a finished case of the grid: a ``ValueError`` naming the flag and the results file.
    """
    if kept:
        return
    check_harness(failed, total, left_out="no file written")
    if report_only:
        raise ValueError(f"--report-only: {results} holds no finished case of this grid; run the same command "
                         "without --report-only first")


def check_harness(records, total: int, files=(), left_out: str = "nothing ranked on them") -> None:
    """Raise :class:`HarnessFailed` (with ``files`` written) if any record is a harness failure."""
    failed = harness_failures(records)
    if failed:
        raise HarnessFailed(harness_message(failed, total, left_out), files)
