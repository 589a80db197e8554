"""One run of the QP study (:mod:`admmkit.benchmarks.qp.maros_meszaros`): a configuration on one QP, judged at every accuracy.

A configuration is admmkit's QP plug-in (:func:`admmkit.problems.qp.solve_qp`) with a
settings *variant*, a penalty rule and an order, or OSQP 1.x itself.  Every
run asks for the absolute accuracy eps (eps_abs = eps, eps_rel = 0, as the
neutral harness qpbenchmark asks its solvers) and is judged twice:

- ``solved``: the solver's own test said solved (OSQP's residuals and duality
  gap in the user's problem; for OSQP its status "solved");
- ``neutral``: the returned (x, y) meets the neutral criteria (qpbenchmark's:
  infinity-norm primal residual, dual residual and duality gap, each <= eps;
  :func:`admmkit.problems.qp.residuals.neutral_residuals`).

An admmkit run goes to the tightest eps; the looser accuracies are tested
every ``check_every`` iterations by a callback with the same test
(:class:`admmkit.problems.qp.termination.QPTermination` at that eps), which is what a
run at that eps would have stopped on: the rules never look at the clock or
at eps, so the iterates are the same.  The callback judges the iterate where
the looser test first fired by the neutral criteria.  Only the ``polish``
variant runs once per accuracy (polishing follows the stop).  Times are CPU
seconds of the process (setup, scaling and the first factorisation
included), and so is the time limit: the machine is shared.
"""
from __future__ import annotations

import math
import os
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from admmkit.problems.qp.problem import QP
from admmkit.problems.qp.residuals import neutral_residuals, neutral_satisfied
from admmkit.problems.qp.settings import QPSettings, admmkit_settings, osqp_settings, textbook_settings
from admmkit.problems.qp.solve import qp_for, solve_qp
from admmkit.problems.qp.termination import SOLVED, QPTermination

#: the settings variants: OSQP's machinery (the preset), admmkit's textbook loop, and the preset without one
#: piece at a time (or with polishing)
VARIANTS = {
    "preset": lambda: osqp_settings(),
    "textbook": lambda: textbook_settings(),
    "no-scaling": lambda: osqp_settings(scaling=0),
    "uniform-rho": lambda: osqp_settings(row_weights="uniform"),
    "alpha-1": lambda: osqp_settings(alpha=1.0),
    "polish": lambda: osqp_settings(polish=True),
    "admmkit": lambda: admmkit_settings(),
}
#: the label of OSQP called directly (variants "default" and "polish")
OSQP_DIRECT = "OSQP"
#: a wall-time cap of WALL_FACTOR x the (CPU) time limit, against a stalled machine
WALL_FACTOR = 20.0
#: the folder of the MAT files, for the workers (a driver sets it through the sweep's env)
DATA_ENV = "ADMMKIT_QP_DATA"

_CASE_QP: dict = {}
_WARM: list = []


def case_qp(file: str) -> QP:
    """A worker's QP of the MAT file ``file`` in the folder ``$ADMMKIT_QP_DATA``, read once for the cases of one
    problem in a row (the last one read is held)."""
    from admmkit.problems.qp.mat import load_mat
    path = Path(os.environ.get(DATA_ENV, ".")) / file
    if _CASE_QP.get("path") != path:
        _CASE_QP.clear()
        _CASE_QP.update(path=path, qp=load_mat(path))
    return _CASE_QP["qp"]


def warm_qp_kernels() -> None:
    """Once per process, before its first timed QP case: the QP kernels compiled or loaded from numba's cache
    (``admmkit warm-up``'s QP group).  Otherwise the first QP case of a worker holds the compilation (4 s on a cold
    cache) in its time and against its CPU-time limit, and is ranked on it."""
    if not _WARM:
        from admmkit.benchmarks.framework.warm_up import qp_kernels
        qp_kernels()
        _WARM.append(True)


def settings_for(variant: str, order: str, eps: float, max_iter: int | None, time_limit: float) -> QPSettings:
    """The variant's settings at absolute accuracy eps (eps_rel = 0), with the study's cap (None: the variant's own)
    and limit."""
    if variant not in VARIANTS:
        raise ValueError(f"variant must be one of {', '.join(VARIANTS)}, got {variant!r}")
    cap = {} if max_iter is None else {"max_iter": max_iter}
    return VARIANTS[variant]().replace(order=order, eps_abs=float(eps), eps_rel=0.0,
                                       time_limit=WALL_FACTOR * time_limit, **cap)


def _row(qp: QP, label: dict, eps: float, **fields) -> dict:
    return {"problem": qp.name, "n": qp.n, "m": qp.m, **label, "eps": eps, **fields}


def _neutral_fields(neutral: dict | None, eps: float) -> dict:
    if neutral is None:
        return {"neutral": False, "neutral_primal": math.nan, "neutral_dual": math.nan, "neutral_gap": math.nan}
    return {"neutral": neutral_satisfied(neutral, eps), "neutral_primal": neutral["primal"],
            "neutral_dual": neutral["dual"], "neutral_gap": neutral["gap"]}


def polishes(settings: QPSettings) -> bool:
    """The settings polish (after the stop, or during the run): a run at one eps says nothing of another."""
    return settings.polish or settings.early_polish


def run_admmkit(qp: QP, variant: str, rule: str, order: str, eps, max_iter: int, time_limit: float,
                acceleration: str | None = None) -> list[dict]:
    """One admmkit run to the tightest eps (the polish variant: one run per eps); one row per eps.

    ``rule``: a name ``solve_qp`` takes ("osqp": OSQP's rule as OSQP runs it; "fixed": no rule), or a builder
    ``rule(run_qp, settings) -> Policy`` with a ``name`` (the rows' ``solver``), called for every run with the QP the
    run iterates on (scaled): how a rule gets OSQP's normalisation of that very QP
    (``termination.osqp_relative_residuals(run_qp)``), as "osqp" and "rowwise" have it.
    ``acceleration``: None (plain ADMM), "anderson" or "fast" (:mod:`admmkit.loop.acceleration`).
    """
    eps = sorted({float(e) for e in eps}, reverse=True)
    if variant in VARIANTS and polishes(VARIANTS[variant]()):       # a polished stop: one run per eps
        return [row for e in eps for row in run_admmkit_at(qp, variant, rule, order, [e], max_iter, time_limit,
                                                           acceleration)]
    return run_admmkit_at(qp, variant, rule, order, eps, max_iter, time_limit, acceleration)


def run_admmkit_at(qp: QP, variant: str, rule: str, order: str, eps: list[float], max_iter: int,
                   time_limit: float, acceleration: str | None = None) -> list[dict]:
    """A run to min(eps) that also records where the test at each looser eps first held."""
    clock = time.process_time
    t0 = clock()
    settings = settings_for(variant, order, eps[-1], max_iter, time_limit)
    run_qp = qp_for(qp, settings)
    if run_qp is qp:
        run_qp = qp.with_options()                 # its own factorisations, whatever an earlier run cached
    looser = {e: QPTermination(run_qp, e, 0.0, gap=settings.gap, infeasibility=settings.infeasibility,
                               eps_prim_inf=settings.eps_prim_inf, eps_dual_inf=settings.eps_dual_inf)
              for e in eps[:-1]}
    hits: dict[float, dict] = {}
    deadline = t0 + time_limit
    rho_max = [settings.rho]

    def watch(rec):
        rho_max[0] = max(rho_max[0], rec.rho)
        if (rec.k + 1) % settings.check_every == 0 or rec.k + 1 == settings.max_iter:
            for e, test in looser.items():
                if e not in hits and test.fired(rec):
                    neutral = None
                    if test.outcome == SOLVED:
                        x, _, y = run_qp.unscaled(rec.x, rec.z, rec.lam_z)
                        neutral = neutral_residuals(run_qp, x, y)
                    hits[e] = {"status": test.outcome, "solved": test.outcome == SOLVED, "iterations": rec.k + 1,
                               "time": clock() - t0, "loop_time": rec.time, "neutral": neutral,
                               "factorizations": run_qp.counters()["factorizations"]}
        return clock() > deadline

    watch.every_record = False      # it reads tested iterations (and rho, fixed in between): segments may run
    watch.every_tested = bool(looser)   # only the deadline and rho's largest value: the segment may test too
    # (rho_max then sees the rho of the records the loop reads, the final one included)
    if isinstance(rule, str):
        policy = None if rule == "fixed" else rule     # "osqp": OSQP's rule as OSQP runs it (solve_qp's default)
    else:
        policy = rule(run_qp, settings)                # a builder: the rule made for this run's QP
    res = solve_qp(run_qp, settings, policy=policy, callback=watch, acceleration=acceleration)
    total = clock() - t0
    label = {"variant": variant, "solver": rule if isinstance(rule, str) else rule.name, "order": order}
    common = {"rho_changes": res.rho_changes, "rho_final": res.rho, "rho_max": max(rho_max[0], res.rho),
              "setup_time": res.timings.get("setup", math.nan)}
    status = "time_limit" if res.status.value in ("stopped", "time_limit") else (res.termination or res.status.value)
    final_neutral = res.neutral if res.termination in (SOLVED, SOLVED + "_inaccurate", None) else None
    rows = []
    for e in eps[:-1]:
        hit = hits.get(e)
        if hit is None or hit["time"] > time_limit:     # never met in time: the run's end, judged at this eps
            fields = {"status": "time_limit" if hit else status, "solved": False, "iterations": res.iterations,
                      "time": total, "factorizations": res.counters.get("factorizations", 0),
                      "loop_time": res.timings.get("total", math.nan), "neutral": final_neutral}
        else:
            fields = hit
        neutral = fields.pop("neutral")
        rows.append(_row(qp, label, e, **fields, **_neutral_fields(neutral, e), **common))
    solved = res.termination == SOLVED and total <= time_limit
    rows.append(_row(qp, label, eps[-1], status=status if total <= time_limit or res.termination != SOLVED
                     else "time_limit", solved=solved, iterations=res.iterations, time=total,
                     loop_time=res.timings.get("total", math.nan),
                     factorizations=res.counters.get("factorizations", 0),
                     **_neutral_fields(final_neutral, eps[-1]),
                     **common))
    for row in rows:
        row["neutral"] = bool(row["neutral"]) and row["status"] != "time_limit"
    return rows


def run_osqp(qp: QP, eps: float, max_iter: int, time_limit: float, polish: bool = False) -> dict:
    """OSQP 1.x with its defaults (check_termination 25, duality gap, adaptive rho every 50 iterations) at absolute
    accuracy eps (eps_rel = 0), the study's cap and CPU-time limit; polishing as asked."""
    import osqp
    clock = time.process_time
    t0 = clock()
    solver = osqp.OSQP()
    l = np.where(np.isfinite(qp.l), qp.l, -1e30)
    u = np.where(np.isfinite(qp.u), qp.u, 1e30)
    solver.setup(P=sp.triu(qp.P, format="csc"), q=qp.q, A=qp.A.tocsc(), l=l, u=u, verbose=False,
                 eps_abs=eps, eps_rel=0.0, polishing=polish, max_iter=max_iter,
                 time_limit=WALL_FACTOR * time_limit)
    setup = clock() - t0
    r = solver.solve(raise_error=False)
    total = clock() - t0
    info = r.info
    status = str(info.status).replace(" ", "_")
    in_time = total <= time_limit
    neutral = None
    if status in ("solved", "solved_inaccurate", "maximum_iterations_reached", "run_time_limit_reached") \
            and r.x is not None and np.all(np.isfinite(r.x)) and np.all(np.isfinite(r.y)):
        neutral = neutral_residuals(qp, r.x, r.y)
    label = {"variant": "polish" if polish else "default", "solver": OSQP_DIRECT, "order": "-"}
    row = _row(qp, label, eps, status=status if in_time else "time_limit", solved=status == "solved" and in_time,
               iterations=int(info.iter), time=total, factorizations=1 + int(info.rho_updates),
               **_neutral_fields(neutral, eps), rho_changes=int(info.rho_updates), rho_final=float(info.rho_estimate),
               rho_max=math.nan, setup_time=setup, loop_time=float(info.solve_time))
    row["neutral"] = bool(row["neutral"]) and in_time
    return row
