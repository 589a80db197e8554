"""The ADMM loop: one function, both orders, any policy, composable stopping rules.

``solve`` checks its arguments and starts the run (:func:`admmkit.loop.checks.prepare`),
then each iteration is, line by line:

- the iteration of the run's order (:mod:`admmkit.loop.steps`, the equations are
  there): the z-step (11), the x-step (12), the dual update (13) -- in order
  "xz" the x-step comes first;
- its record (:func:`admmkit.loop.record.loop_record`), lazy: a norm is computed
  only when the stopping rule, the policy, the callback or the history reads it;
- on a tested iteration, the tests (:mod:`admmkit.loop.termination`): divergence,
  the stopping rule, stalling;
- the policy's rho_{k+1} (17) (:class:`admmkit.loop.steps.PolicyStep`), and where
  it differs from rho_k the one event of a change of rho
  (:class:`admmkit.loop.steps.RhoEvent`: ``problem.update_rho``, the accelerator's restart;
  for a rule's :class:`admmkit.RowPenalties`, ``problem.update_row_weights`` and lam rescaled so that M lam is kept);
- the bookkeeping (:mod:`admmkit.loop.ledger`): the history, the callback, the
  time limit, and whether the next dual update takes ||r||.
"""
from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Callable

import numpy as np

from . import checks
from .ledger import Ledger
from ..policy import Policy, RowPenalties
from ..problem import Problem
from .record import IterationRecord, loop_record
from .result import Result, Status
from .segments import FastForward
from .steps import ITERATIONS, PolicyStep, RhoEvent
from .stopping import StoppingRule
from .termination import Termination

if TYPE_CHECKING:
    from .acceleration import Accelerator

#: a run that a stopping rule ended is ``converged_inaccurate`` when a relative KKT measure
#: exceeds INACCURATE_FACTOR * max(the rule's tolerance, INACCURATE_FLOOR) (OSQP's "solved
#: inaccurate" uses 10x too); the floor keeps round-off (relative KKT residuals of 1e-11 at a
#: requested 1e-12) from counting as inaccurate
INACCURATE_FACTOR = 10.0
INACCURATE_FLOOR = 1e-9
ORDERS = checks.ORDERS
perf = time.perf_counter


@np.errstate(over="ignore", invalid="ignore")  # a blow-up ends as status 'diverged'
def solve(
    problem: Problem,
    *,
    rho: float | None = None,
    policy: Policy | str | None = None,
    order: str = "xz",
    stop: StoppingRule | None = None,
    max_iter: int = 10_000,
    callback: Callable[[IterationRecord], bool | None] | None = None,
    x0: np.ndarray | None = None,
    z0: np.ndarray | None = None,
    lam0: np.ndarray | None = None,
    time_limit: float | None = None,
    blas_threads: int | None = 1,
    alpha: float = 1.0,
    check_every: int = 1,
    history: str = "lean",
    warm_start: Result | None = None,
    acceleration: Accelerator | str | None = None,
    compiled: bool = True,
) -> Result:
    """Run ADMM on ``problem`` and return a :class:`Result`.

    Parameters
    ----------
    problem : Problem
        The plug-in.
    rho : float or None
        Initial penalty rho_0, a number (not text), finite and > 0 (default 1,
        or the final rho of ``warm_start``).
    policy : Policy, str or None
        A :class:`Policy` (reset at the start of the run), a registered
        name such as ``"summable"`` (found by entry point: no import needed), or None to
        keep rho fixed.  Its ``update`` must return one number in (0, inf)
        (else a TypeError or ValueError naming it, ``admmkit.loop.checks.policy_answer``),
        or, for a rule with ``per_row = True`` on a problem with
        ``update_row_weights``, :class:`admmkit.RowPenalties` (a penalty per row).
    order : str
        ``"xz"`` (ADMM1: x-step first) or ``"zx"`` (ADMM2: z-step first).
    stop : StoppingRule or None
        A stopping rule (its ``fired`` returns its name, a :class:`admmkit.Stop`
        or None; else a TypeError naming it); default :func:`admmkit.default_stop`,
        Boyd's residuals ``ResidualTolerance(1e-6, 1e-5)``.  The paper's
        methods pass ``RelativeChange(1e-5)``.
    max_iter : int
        Iteration cap, an integer >= 1.
    callback : callable or None
        Called with every :class:`IterationRecord`, the last one included;
        it returns None or a bool (anything else is a TypeError naming it):
        True stops the run with status ``stopped`` (unless it
        has already ended for another reason at that iteration).  A callback
        with the attribute ``every_record = False`` (a progress display, a
        watcher of the tested iterations) is called only with the records
        of the iterations that run in Python, every tested one among them,
        so that the others may run in a compiled segment
        (:mod:`admmkit.loop.segments`); its True still stops the run there.
    x0, z0, lam0 : numpy.ndarray or None
        Starting point, finite (default ``problem.initial_point()``, or the
        final iterate of ``warm_start``).
    time_limit : float or None
        Optional wall-time limit in seconds (for benchmarks; it makes
        a run machine-dependent, so it never steers rho).
    blas_threads : int or None
        BLAS threads during the run (default 1; None leaves them alone).
    alpha : float
        Over-relaxation in (0, 2) (Eckstein & Bertsekas 1992; OSQP uses
        1.6).  1 (the default, and the paper's methods) is plain ADMM.
    check_every : int
        Test the stopping rule (and for divergence and stalling) every
        ``check_every`` iterations and at the last one; the iterates do
        not depend on it.  OSQP checks every 25.
    history : str
        ``"lean"`` (default): keep the norms something read, NaN for the
        others, the last row complete; ``"full"``: compute every norm
        of every iteration (about nine extra vector norms per iteration).
    warm_start : admmkit.Result or None
        A previous result: start from its ``x_iterate``, ``z``, ``lam``
        and rho (each overridden by x0, z0, lam0, rho if given).
    acceleration : Accelerator, str or None
        ``"anderson"`` (safeguarded type-II Anderson, memory 10),
        ``"fast"`` (restarted fast ADMM, Goldstein et al. 2014) or an
        :class:`admmkit.loop.acceleration.Accelerator`; None (default): plain
        ADMM.  Each iteration then starts from the accelerator's state
        (:mod:`admmkit.loop.acceleration`); a change of rho resets it.
    compiled : bool
        True (default): the iterations whose records nobody reads run in
        the problem's compiled segment when it has one (:mod:`admmkit.loop.segments`;
        the same iterates bit for bit); False: every iteration in Python.
    """
    accelerator = None if acceleration is None else _accelerator(acceleration)
    run = checks.prepare(problem, rho=rho, policy=policy, order=order, stop=stop, max_iter=max_iter,
                         callback=callback, x0=x0, z0=z0, lam0=lam0, time_limit=time_limit, blas_threads=blas_threads,
                         alpha=alpha, check_every=check_every, history=history, warm_start=warm_start,
                         compiled=compiled)
    iterate = ITERATIONS[run.order](problem, run.ctx)      # eqs. (11), (12), (13) in the run's order
    rho_step = PolicyStep(run.policy, problem)              # eq. (17)
    watch, ledger = Termination(run), Ledger(run)           # the tests; the history, the callback, the taken ||r||
    ctx, rho, rho_changes, every, last = run.ctx, run.rho, 0, run.check_every, run.max_iter - 1
    x, z, lam, Ax = run.x, run.z, run.lam, run.Ax
    accel = None if accelerator is None else _acceleration(accelerator, run.order, checks.inner_of(problem),
                                                           *_inner_weights(problem, run.z))
    rho_event = RhoEvent(problem, accel)                    # a change of rho, eq. (17) taking effect: one call
    fast = FastForward(run, enabled=run.compiled, accel=accel)    # unread iterations, compiled (segments)
    iterate = fast.serve(iterate)                    # ... and a read one the segment ran: its numbers, not a rerun
    rec = final = old = None
    k = 0
    with run.blas_limit():       # the BLAS thread count is restored however the loop ends (an exception, Ctrl-C)
        start = ctx.start = perf()
        while k < run.max_iter:
            x, z, lam, Ax, k = fast(k, x, z, lam, Ax, rho)      # (11)-(13) up to the next record read, if it can
            rec = hat = None                        # drop the last record and its vectors now: fewer arrays alive
            check = (k + 1) % every == 0 or k == last       # a tested iteration: every check_every-th, and the last
            try:
                x1, z1, lam1, Ax1, hat, r_norm, t = iterate(x, z, lam, Ax, rho, ledger.take_r[check])  # (11)-(13)
            except (np.linalg.LinAlgError, ArithmeticError) as err:
                final = Status.DIVERGED, f"a step failed at iteration {k + 1}: {err}"
                break
            rec = loop_record(ctx, k, rho, t, x1, z1, lam1, Ax1, x, z, lam, Ax, hat, r_norm)   # iteration k (lazy)
            if accel is not None:
                old = z, lam, Ax                                        # the state iteration k started from
            x, z, lam, Ax = x1, z1, lam1, Ax1                                                  # k <- k + 1
            final = watch.check(rec) if check else None          # divergence, the stopping rule, stalling
            rho_next, final = rho_step.update(rec, rho) if final is None else (rho, final)  # rho_{k+1}, eq. (17)
            final = ledger.close(rec, rho_next, check, final)     # the history, the callback, the time limit
            if final is not None:
                break
            if rho_next != rho:         # the rho event: the problem's refresh, the accelerator's restart (steps)
                if type(rho_next) is RowPenalties:      # a penalty per row: M changes, M lam is kept
                    rho, lam = rho_event.change_rows(rho_next, lam, follows=k + 1 < run.max_iter)
                else:
                    rho = rho_event.change(rho_next, follows=k + 1 < run.max_iter)
                rho_changes += 1
            elif accel is not None:                      # the state iteration k + 1 starts from, (A2)-(A5)
                z, lam, Ax = accel.step(old, (z, lam, Ax), rho)
            k += 1
        total = perf() - start
    ledger.finish(rec)
    x_seconds, z_seconds = iterate.seconds()
    timings = dict(x_step=x_seconds, z_step=z_seconds, policy=rho_step.seconds,
                   residuals=watch.seconds, total=total, rho_update=rho_event.seconds)
    result = _result(run, x, z, lam, rec, final, watch.stopped_by, rho, rho_changes, timings)
    if fast.segments:       # the iterations run in compiled segments, and their seconds (in no step's time)
        result.timings["segments"] = fast.seconds
        result.counters["compiled_iterations"] = fast.iterations
        result.counters["segments"] = fast.segments
    result.acceleration = None if accel is None else accel.summary()
    result.last_record = rec
    return result


def _accelerator(acceleration):
    """:func:`admmkit.loop.acceleration.make_accelerator`, its module imported now: a plain run imports none of
    it (5-15 ms of a fresh ``solve contact`` process)."""
    from .acceleration import make_accelerator
    return make_accelerator(acceleration)


def _acceleration(accelerator, order, inner, weights, size):
    """The loop's side of ``accelerator`` (:class:`admmkit.loop.acceleration.Acceleration`)."""
    from .acceleration import Acceleration
    return Acceleration(accelerator, order, inner, weights, size)


def _inner_weights(problem, z) -> tuple:
    """(w, len(z)) when the problem's inner product is the weighted dot product sum_i w_i a_i b_i
    (``problem.inner_weights()``), else (None, None): an accelerator's steps then use ``problem.inner``."""
    weights = getattr(problem, "inner_weights", None)
    w = weights() if callable(weights) else None
    if w is None or np.shape(w) != np.shape(z):
        return None, None
    return w, z.shape[0]


def _result(run, x, z, lam, rec, final, stopped_by, rho, rho_changes, timings) -> Result:
    """The Result of a run that ended with ``final`` = (status, message) (None: max_iter reached)."""
    problem, stop = run.problem, run.stop
    status, message = final or (Status.MAX_ITER, f"reached max_iter={run.max_iter}")
    x_final = problem.finalize(x)
    counters_after = problem.counters()
    counters = {key: counters_after[key] - run.counters_before.get(key, 0) for key in counters_after}
    finite = status is not Status.DIVERGED
    accuracy = None
    if status is Status.CONVERGED and stop.tolerance is not None:
        with np.errstate(over="ignore", invalid="ignore"):
            accuracy = kkt_measures(problem, x_final, z, lam, rec)   # the user's solution, as kkt() sees it
        worst = max(accuracy.items(), key=lambda kv: kv[1], default=None)
        if worst is not None and worst[1] > INACCURATE_FACTOR * max(stop.tolerance, INACCURATE_FLOOR):
            status = Status.CONVERGED_INACCURATE
            message += (f", but the relative KKT measure {worst[0]} = {worst[1]:.2e} is more than "
                        f"{INACCURATE_FACTOR:g} x max(the rule's tolerance {stop.tolerance:g}, {INACCURATE_FLOOR:g})")
    objective = problem.objective(x_final, z) if finite else None
    if status in (Status.PRIMAL_INFEASIBLE, Status.PRIMAL_INFEASIBLE_INACCURATE):
        objective = math.inf                                  # no feasible point: inf, as OSQP reports
    elif status in (Status.DUAL_INFEASIBLE, Status.DUAL_INFEASIBLE_INACCURATE):
        objective = -math.inf                                 # unbounded below
    return Result(
        x=x_final, z=z, lam=lam, status=status, message=message, stopped_by=stopped_by,
        iterations=len(run.history), rho=rho, history=run.history, timings=timings, rho_changes=rho_changes,
        counters=counters, kkt=problem.kkt(x_final, z, lam) if finite else None, objective=objective,
        order=run.order, policy=repr(run.policy), x_iterate=x, accuracy=accuracy, alpha=run.alpha,
        certificate=getattr(stopped_by, "certificate", None),
    )


def kkt_measures(problem, x, z, lam, rec: IterationRecord | None) -> dict[str, float]:
    """The relative KKT measures a stop is checked against (finite values only).

    ``problem.kkt_relative(x, z, lam)`` if the problem has it (the building
    blocks' :class:`admmkit.SplitProblem` does: OSQP-style relative
    residuals of the three optimality conditions); otherwise Boyd's residuals
    of the last record relative to unit + scale: ||r||_M / (primal_unit +
    primal_scale) and ||s|| / (dual_unit + dual_scale), which are at most the
    rule's tolerance whenever ``ResidualTolerance`` fired.
    """
    relative = getattr(problem, "kkt_relative", None)
    out = relative(x, z, lam) if callable(relative) else None
    if out is None and rec is not None:
        out = {"primal_residual": rec.primal_residual / (rec.primal_unit + rec.primal_scale),
               "dual_residual": rec.dual_residual / (rec.dual_unit + rec.dual_scale)}
    return {k: float(v) for k, v in (out or {}).items() if math.isfinite(v)}
