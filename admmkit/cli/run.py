"""A ``solve`` command's run: the progress display, the solve with the common options, the summary and the history."""
from __future__ import annotations

import contextlib
import sys

from ..loop.result import Result
from ..loop.solver import solve
from ..loop.stopping import StoppingRule
from .options import resolve_policy, stop_rule
from .output import Progress, print_summary


def progress_callback(every: int | None):
    """A callback that prints one line every ``every`` iterations (None if ``every`` is None or <= 0)."""
    if not every or every <= 0:
        return None

    def show(rec) -> None:
        if (rec.k + 1) % every == 0:
            print(f"  iteration {rec.k + 1:6d}  rho={rec.rho:.3e}  primal={rec.primal_residual:.3e}  "
                  f"dual={rec.dual_residual:.3e}  rel.change={rec.rel_change:.3e}", file=sys.stderr)
    return show


class CompleteTested:
    """A callback that computes every norm of the tested iterations' records (iteration k with
    (k + 1) % ``every`` == 0), then calls ``inner`` (the progress display, or None).

    The history keeps the record's norms, so those rows become complete (``--history`` writes them,
    ``History.to_csv(rows="complete")``); the loop completes the last record itself.  It reads the records the
    loop computed anyway and returns what ``inner`` returns, so it changes no iterate and stops no run.
    """

    def __init__(self, every: int, inner=None) -> None:
        self.every, self.inner = int(every), inner
        self.every_record = getattr(inner, "every_record", True) if inner is not None else False

    def __call__(self, rec):
        if (rec.k + 1) % self.every == 0:
            rec.complete()
        return None if self.inner is None else self.inner(rec)


@contextlib.contextmanager
def progress(args, total: int, every: int = 1):
    """A ``Progress`` context (admmkit/cli/output.py) as the options ask, yielding the callback for the solve.

    ``--progress N``: a line every N iterations; otherwise a bar after 2 s; nothing with ``-q``.  With
    ``--history`` the callback also completes the records of the tested iterations (every ``every``-th:
    the solve's check_every), :class:`CompleteTested`.
    """
    quiet = getattr(args, "quiet", False)
    lines = None if quiet else getattr(args, "progress", None)
    with Progress(total, enabled=not quiet, lines=progress_callback(lines)) as show:
        yield CompleteTested(every, show) if getattr(args, "history", None) else show


def write_history(history, args) -> None:
    """``--history``: the complete rows of ``history`` as CSV (``History.to_csv(path, rows="complete")``), and a
    line saying where."""
    if getattr(args, "history", None):
        print(f"history      {history.to_csv(args.history, rows='complete')}")


def run_solve(problem, args, stop: StoppingRule | None = None) -> Result:
    """Solve with the common options, print the summary, write the history if asked.

    ``stop``: a plug-in's own stopping rule (e.g. one balanced with its error estimate) in place of the
    one the common options ask for.
    """
    order, policy, name = resolve_policy(args)
    stop = stop if stop is not None else stop_rule(args)
    with progress(args, args.max_iter) as show:
        result = solve(problem, rho=args.rho, policy=policy, order=order, stop=stop,
                       max_iter=args.max_iter, callback=show)
    args.resolved = {"policy": name, "order": order, "policy_repr": repr(policy), "stop": stop.name}
    print_summary(result, name, args.rho)
    write_history(result.history, args)
    return result


