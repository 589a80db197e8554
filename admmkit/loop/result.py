"""The result of a run: the solution, how and why the run stopped, and what it cost."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any
from enum import Enum

import numpy as np

from .history import History


class Status(str, Enum):
    """How a run ended."""

    CONVERGED = "converged"    # a stopping rule fired and the KKT check (if any) agreed
    CONVERGED_INACCURATE = "converged_inaccurate"  # a rule fired, but the KKT residuals are > 10x its tolerance
    MAX_ITER = "max_iter"      # the iteration cap was reached first
    DIVERGED = "diverged"      # an iterate, a norm or rho became non-finite (or a solve failed)
    STALLED = "stalled"        # the iterates stopped changing before any rule fired
    TIME_LIMIT = "time_limit"  # the wall-time limit was reached (benchmarks only)
    STOPPED = "stopped"        # the callback asked to stop
    # a stopping rule's terminal verdicts (a Stop with a certificate, e.g. the QP's infeasibility tests)
    PRIMAL_INFEASIBLE = "primal_infeasible"
    DUAL_INFEASIBLE = "dual_infeasible"
    PRIMAL_INFEASIBLE_INACCURATE = "primal_infeasible_inaccurate"
    DUAL_INFEASIBLE_INACCURATE = "dual_infeasible_inaccurate"

    def __str__(self) -> str:
        return self.value


@dataclass
class Result:
    """What :func:`admmkit.solve` returns (in the spirit of scipy's OptimizeResult).

    ``x`` is the problem's solution (after ``problem.finalize``),
    ``x_iterate`` the last ADMM iterate (what ``finalize`` was applied to;
    ``solve(problem, warm_start=result)`` restarts from it), ``z`` and ``lam``
    the last auxiliary variable and (unscaled) multiplier.  ``accuracy`` holds
    the relative KKT measures compared with the stopping rule's tolerance when
    a rule fired (see ``admmkit.loop.solver.INACCURATE_FACTOR``).  ``timings``
    splits the wall time into x_step, z_step, policy, residuals and total
    seconds.  ``kkt`` holds the problem's KKT residuals at the stop, when the
    plug-in provides them.  ``certificate`` is the vector a stopping rule
    gave with a terminal status (:class:`admmkit.loop.stopping.Stop`), such as
    a primal infeasibility certificate; then ``objective`` is +inf (primal
    infeasible) or -inf (dual infeasible), as in OSQP.  ``acceleration``
    names the accelerator of an accelerated run and counts its extrapolated,
    rejected and restarted steps (None for plain ADMM).  ``last_record`` is
    the :class:`admmkit.IterationRecord` of the last iteration, every norm
    computed (None if no iteration ran).  Iterations that ran in a compiled
    segment (:mod:`admmkit.loop.segments`) are counted in
    ``counters["compiled_iterations"]`` (in ``counters["segments"]`` calls) and timed in
    ``timings["segments"]``.
    """

    x: np.ndarray
    z: np.ndarray
    lam: np.ndarray
    status: Status
    message: str
    stopped_by: str | None
    iterations: int
    rho: float
    history: History
    timings: dict[str, float]
    rho_changes: int
    counters: dict[str, int] = field(default_factory=dict)
    kkt: dict[str, float] | None = None
    objective: float | None = None
    order: str = "xz"
    policy: str = "fixed"
    x_iterate: np.ndarray | None = None
    accuracy: dict[str, float] | None = None
    alpha: float = 1.0
    certificate: np.ndarray | None = None
    acceleration: dict | None = None     # the accelerator and its counts, when the run had one
    last_record: Any = None              # the IterationRecord of the last iteration, complete

    @property
    def converged(self) -> bool:
        """True when a stopping rule fired and the KKT check did not find the point far off (status ``converged``)."""
        return self.status is Status.CONVERGED

    @property
    def factorizations(self) -> int | None:
        """Factorisations the plug-in computed during this run (None if not counted)."""
        return self.counters.get("factorizations")

    def summary(self) -> str:
        """A few lines for people: status, iterations, rho, residuals, time."""
        h = self.history
        lines = [
            f"status       {self.status.value}  ({self.message})",
            f"method       order={self.order}  policy={self.policy}",
            f"iterations   {self.iterations}   rho: final {self.rho:.4g}, {self.rho_changes} changes",
        ]
        if len(h):
            lines.append(
                f"residuals    primal {h['primal_residual'][-1]:.3e}   dual {h['dual_residual'][-1]:.3e}"
                f"   rel. change {h['rel_change'][-1]:.3e}"
            )
        if self.objective is not None:
            lines.append(f"objective    {self.objective:.10g}")
        if self.kkt:
            lines.append("KKT          " + "   ".join(
                f"{k} {v}" if isinstance(v, (int, np.integer)) else f"{k} {v:.3e}" for k, v in self.kkt.items()))
        if self.counters:
            lines.append("work         " + "   ".join(f"{k} {v}" for k, v in self.counters.items()))
        t = self.timings
        segments = f", compiled segments {t['segments']:.4f}" if "segments" in t else ""
        lines.append(
            f"time         {t['total']:.4f} s  (x-step {t['x_step']:.4f}, z-step {t['z_step']:.4f},"
            f" policy {t['policy']:.4f}, residuals {t['residuals']:.4f}{segments})"
        )
        return "\n".join(lines)

    def __repr__(self) -> str:
        return f"Result(status={self.status.value!r}, iterations={self.iterations}, stopped_by={self.stopped_by!r})"

    def _repr_html_(self) -> str:
        """Jupyter: the summary as a two-column table (status, iterations, rho, KKT, work, time)."""
        import html
        rows = [("status", f"{self.status.value} ({self.message})"), ("method", f"order {self.order}, {self.policy}"),
                ("iterations", str(self.iterations)), ("rho", f"final {self.rho:.4g}, {self.rho_changes} changes")]
        if self.objective is not None:
            rows.append(("objective", f"{self.objective:.10g}"))
        if self.kkt:
            rows.append(("KKT", ", ".join(f"{k} {_number(v)}" for k, v in self.kkt.items())))
        if self.counters:
            rows.append(("work", ", ".join(f"{k} {v}" for k, v in self.counters.items())))
        rows.append(("time", f"{self.timings.get('total', float('nan')):.4g} s"))
        rows.append(("x", f"{self.x.shape[0]} values, z and lam {self.z.shape[0]}; history: {len(self.history)} rows "
                          "(result.history.to_pandas())"))
        body = "".join(f"<tr><th style='text-align:left'>{html.escape(k)}</th><td style='text-align:left'>"
                       f"{html.escape(v)}</td></tr>" for k, v in rows)
        return f"<div><b>admmkit.Result</b><table>{body}</table></div>"


def _number(value) -> str:
    """Integers as integers, other numbers with 4 significant digits."""
    if isinstance(value, (bool, np.bool_, int, np.integer)):
        return str(value)
    return f"{float(value):.3e}"
