"""The ADMM loop: one function, both orders, any policy, composable stopping rules.

One iteration is the steps of :mod:`admmkit.steps` (the equations are there):
the z-step (11), the x-step (12), the dual update (13) -- in order "xz" the
x-step comes first --, then the record of the iteration, the stopping test,
and the policy's rho_{k+1} (17).  The record is lazy: a norm is computed only
when the stopping rule, the policy, the callback or the history reads it.
"""
from __future__ import annotations

import math
import time
from contextlib import ExitStack
from typing import Callable

import numpy as np

from . import checks
from .blas import limit_blas
from .history import History
from .policy import Policy
from .problem import Problem
from .record import LAZY_FIELDS, IterationRecord, RunContext, loop_record
from .result import Result, Status
from .steps import dual_update, dual_update_and_residual, policy_step, relax_Ax, relax_z, x_step, z_step
from .stopping import StoppingRule, default_stop

#: a run that a stopping rule ended is ``converged_inaccurate`` when a relative KKT measure
#: exceeds INACCURATE_FACTOR * max(the rule's tolerance, INACCURATE_FLOOR) (OSQP's "solved
#: inaccurate" uses 10x too); the floor keeps round-off (relative KKT residuals of 1e-11 at a
#: requested 1e-12) from counting as inaccurate
INACCURATE_FACTOR = 10.0
INACCURATE_FLOOR = 1e-9
ORDERS = checks.ORDERS


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
) -> Result:
    """Run ADMM on ``problem`` and return a :class:`Result`.

    Parameters
    ----------
    problem : Problem
        The plug-in.
    rho : float or None
        Initial penalty rho_0, finite and > 0 (default 1, or the final rho
        of ``warm_start``).
    policy : Policy, str or None
        A :class:`Policy` (reset at the start of the run), a registered
        name such as ``"summable"`` (found by entry point: no import needed), or None to
        keep rho fixed.
    order : str
        ``"xz"`` (ADMM1: x-step first) or ``"zx"`` (ADMM2: z-step first).
    stop : StoppingRule or None
        A stopping rule; default :func:`admmkit.default_stop`,
        Boyd's residuals ``ResidualTolerance(1e-6, 1e-5)``.  The paper's
        methods pass ``RelativeChange(1e-5)``.
    max_iter : int
        Iteration cap, an integer >= 1.
    callback : callable or None
        Called with every :class:`IterationRecord`, the last one included;
        returning True stops the run with status ``stopped`` (unless it
        has already ended for another reason at that iteration).
    x0, z0, lam0 : numpy.ndarray or None
        Starting point (default ``problem.initial_point()``, or the final
        iterate of ``warm_start``).
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
    """
    order_key = checks.check_order(order)
    if warm_start is not None:
        if not isinstance(warm_start, Result) or warm_start.x_iterate is None:
            raise TypeError(f"warm_start must be an admmkit.Result of solve(), got {type(warm_start).__name__}")
        x0 = warm_start.x_iterate if x0 is None else x0
        z0 = warm_start.z if z0 is None else z0
        lam0 = warm_start.lam if lam0 is None else lam0
        rho = warm_start.rho if rho is None else rho
    rho = checks.check_rho(1.0 if rho is None else rho, "rho")
    alpha = checks.check_alpha(alpha)
    max_iter = checks.check_int("max_iter", max_iter, 1)
    check_every = checks.check_int("check_every", check_every, 1)
    history_log = History(history)
    if time_limit is not None and not (isinstance(time_limit, (int, float, np.integer, np.floating))
                                       and not isinstance(time_limit, bool)
                                       and math.isfinite(time_limit) and time_limit > 0):
        raise ValueError(f"time_limit must be a finite number > 0 seconds or None, got {time_limit!r}")
    if blas_threads is not None and (isinstance(blas_threads, bool) or not isinstance(blas_threads, int) or blas_threads < 1):
        raise ValueError(f"blas_threads must be an integer >= 1 or None, got {blas_threads!r}")
    if callback is not None and not callable(callback):
        raise TypeError(f"callback must be callable or None, got {type(callback).__name__}")
    stop = default_stop() if stop is None else stop
    if not isinstance(stop, StoppingRule):
        raise TypeError(f"stop must be a StoppingRule (e.g. RelativeChange(1e-5)), got {type(stop).__name__}")
    for name in ("x_step", "z_step", "apply_A"):
        if not callable(getattr(problem, name, None)):
            raise TypeError(f"problem must implement {name}() (see admmkit.Problem), got {type(problem).__name__}")
    policy = checks.make(policy)

    x, z, lam = checks.starting_point(problem, x0, z0, lam0)
    Ax = np.asarray(problem.apply_A(x), dtype=float)
    if Ax.shape != z.shape or lam.shape != z.shape:
        raise ValueError(f"shapes do not match: A x0 has shape {Ax.shape}, z0 {z.shape}, lam0 {lam.shape}")
    c = problem.c
    adjoint = order_key == "xz" and checks.has_adjoint(problem, z)   # only order xz uses adjoint_norm
    checks.check_requirements(problem, order_key, adjoint, (("policy", policy), ("stop", stop)))
    primal_unit = problem.norm(np.ones_like(z))
    dual_unit = math.sqrt(getattr(problem, "n", x.size)) if order_key == "xz" else primal_unit
    c_norm = problem.norm(np.broadcast_to(np.asarray(c, dtype=float), z.shape))
    ctx = RunContext(problem, order_key, alpha, c, c_norm, adjoint, primal_unit, dual_unit)
    c_zero, relaxed = ctx.c_is_zero, alpha != 1.0
    # the lazy fields whose non-finite value means divergence (a missing adjoint gives NaN legitimately)
    watched = tuple(i for i, name in enumerate(LAZY_FIELDS) if adjoint or order_key == "zx" or name not in ("dual_residual", "dual_scale"))

    begin_run = getattr(problem, "begin_run", None)
    if callable(begin_run):
        begin_run()                  # building blocks count this run's work from here
    policy.reset(rho)
    counters_before = dict(problem.counters())
    tx = tz = t_policy = t_check = 0.0
    status, message, stopped_by = Status.MAX_ITER, f"reached max_iter={max_iter}", None
    rho_changes = 0
    rec = None
    perf = time.perf_counter
    # take ||r|| (r = Ax - z - c) with the dual update, whose r's memory then holds lam^{k+1}, when the last
    # iteration of the same kind (plain, tested) read it; r is never kept: fewer arrays to allocate and write
    # (the numbers never depend on this; a record recomputes r if ||r|| is read unexpectedly)
    take_r = [True, True]
    norm_M = ctx.norm
    limits = ExitStack()
    if blas_threads is not None:
        limits.enter_context(limit_blas(blas_threads))   # a cached controller: ~15 us, not 0.5 ms
    try:   # the BLAS thread count is restored however the loop ends (an exception, Ctrl-C)
        start = perf()
        for k in range(max_iter):
            rec = hat = Ax_dual = z_dual = None   # drop the last record and its vectors now: fewer arrays alive
            check = (k + 1) % check_every == 0 or k == max_iter - 1
            take = take_r[check] and not relaxed    # with alpha != 1 the record's r is not the dual update's
            r_norm = None
            t0 = perf()
            try:
                if order_key == "xz":
                    x_new, Ax_new = x_step(problem, z, lam, rho, x)
                    t1 = perf()
                    hat = relax_Ax(alpha, Ax_new, z, c, c_zero) if relaxed else Ax_new
                    z_new = z_step(problem, hat, lam, rho, z)
                    t2 = perf()
                    tx += t1 - t0
                    tz += t2 - t1
                    Ax_dual, z_dual = hat, z_new                 # the dual update's "A x" and "z" in order xz
                else:
                    z_new = z_step(problem, Ax, lam, rho, z)                            # eq. (11)
                    t1 = perf()
                    hat = relax_z(alpha, z_new, Ax, c, c_zero) if relaxed else z_new
                    x_new, Ax_new = x_step(problem, hat, lam, rho, x)                   # eq. (12)
                    t2 = perf()
                    tz += t1 - t0
                    tx += t2 - t1
                    Ax_dual, z_dual = Ax_new, hat                # ... and in order zx
                if k == 0:       # a step of the wrong shape would broadcast silently: stop at once
                    _check_steps(problem, x, z, x_new, z_new, Ax_new)
                if take:                                                                # eq. (13)
                    lam_new, r_norm = dual_update_and_residual(lam, rho, Ax_dual, z_dual, c, c_zero, norm_M)
                else:
                    lam_new = dual_update(lam, rho, Ax_dual, z_dual, c, c_zero)
            except (np.linalg.LinAlgError, ArithmeticError) as err:
                status, message = Status.DIVERGED, f"a step failed at iteration {k + 1}: {err}"
                break
            # lam^k only when alpha != 1 (with alpha = 1, ||lam^{k+1} - lam^k|| = rho ||r||): freed here otherwise
            rec = loop_record(ctx, (k, rho, t2 - start, x_new, z_new, lam_new, Ax_new, x, z, lam if relaxed else None,
                                    Ax, hat if relaxed else None), r_norm)
            x, z, lam, Ax = x_new, z_new, lam_new, Ax_new

            final = None
            if check:
                t3 = perf()
                fired = stop.fired(rec)
                if not _finite(rec._vals, watched) or not _finite_check(rec):
                    final = Status.DIVERGED, f"non-finite iterate at iteration {k + 1}"
                elif fired:                  # a name (converged) or a Stop with its own status and certificate
                    stopped_by = fired
                    final = getattr(fired, "status", Status.CONVERGED), f"{fired} fired at iteration {k + 1}"
                elif _stalled(rec):
                    final = Status.STALLED, f"iterates stopped changing at iteration {k + 1} before {stop.name} fired"
                t_check += perf() - t3
            rho_next = rho
            if final is None:
                t3 = perf()
                rho_next = policy_step(policy, rec)                                      # eq. (17)
                t_policy += perf() - t3
                if rho_next is not rho and not checks.rho_in_range(rho_next):   # the same object: checked already
                    final = Status.DIVERGED, (f"policy {policy!r} returned rho={rho_next!r} at iteration {k + 1}, "
                                              f"outside admmkit's rho range [{checks.RHO_RANGE[0]:g}, "
                                              f"{checks.RHO_RANGE[1]:g}]")
            history_log.append(rec, rho_next)
            if callback is not None and callback(rec) and final is None:
                final = Status.STOPPED, f"callback stopped the run at iteration {k + 1}"
            take_r[check] = rec._vals[0] is not None         # ||r|| read (not merely taken) in this iteration
            if final is None and time_limit is not None and perf() - start > time_limit:
                final = Status.TIME_LIMIT, f"time_limit={time_limit:g} s reached at iteration {k + 1}"
            if final is not None:
                status, message = final
                break
            if rho_next != rho:
                rho_changes += 1
                rho = float(rho_next)

        total = perf() - start
    finally:
        limits.close()
    if rec is not None:
        history_log.replace_last(rec.complete())
    return _result(problem, stop, x, z, lam, rec, status, message, stopped_by, history_log, rho, rho_changes,
                   counters_before, dict(x_step=tx, z_step=tz, policy=t_policy, residuals=t_check, total=total),
                   order_key, policy, alpha)


def _check_steps(problem, x, z, x_new, z_new, Ax_new) -> None:
    """Refuse, at the first iteration, a step that returns something other than an array of the iterate's shape."""
    name = type(problem).__name__
    for step, got, want in (("x_step", x_new, x.shape), ("z_step", z_new, z.shape), ("apply_A", Ax_new, z.shape)):
        if not isinstance(got, np.ndarray):
            raise TypeError(f"{name}.{step}() returned {type(got).__name__}; it must return a numpy array "
                            f"of shape {want}")
        if got.shape != want:
            raise ValueError(f"{name}.{step}() returned an array of shape {got.shape}; it must have shape {want} "
                             f"(the shape of {'x' if step == 'x_step' else 'z'})")


def _finite_check(rec: IterationRecord) -> bool:
    """If no norm has been computed, compute one (||r||_M) so that a blow-up is seen."""
    return any(v is not None for v in rec._vals) or math.isfinite(rec.primal_residual)


def _finite(vals: list, watched: tuple) -> bool:
    """No computed norm among ``watched`` is inf or NaN."""
    isfinite = math.isfinite
    for i in watched:
        v = vals[i]
        if v is not None and not isfinite(v):
            return False
    return True


_STALL = (4, 6, 0)     # x_change, z_change, primal_residual in LAZY_FIELDS


def _stalled(rec: IterationRecord) -> bool:
    """x, z and lam stopped changing; the norms already computed are looked at first."""
    vals = rec._vals
    for i in _STALL:
        if vals[i] is not None and vals[i] != 0:
            return False
    return rec.x_change == 0 and rec.z_change == 0 and rec.primal_residual == 0


def _result(problem, stop, x, z, lam, rec, status, message, stopped_by, history_log, rho, rho_changes,
            counters_before, timings, order_key, policy, alpha) -> Result:
    x_final = problem.finalize(x)
    counters_after = problem.counters()
    counters = {key: counters_after[key] - counters_before.get(key, 0) for key in counters_after}
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
        iterations=len(history_log), rho=rho, history=history_log, timings=timings, rho_changes=rho_changes,
        counters=counters, kkt=problem.kkt(x_final, z, lam) if finite else None, objective=objective,
        order=order_key, policy=repr(policy), x_iterate=x, accuracy=accuracy, alpha=alpha,
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
