"""One ADMM run of a benchmark method on a benchmark problem, with a tolerance ladder read off its clock.

The stopping rule does not steer the iterates, so a run to the tightest
tolerance passes through the point where every looser tolerance would have
stopped it.  :func:`ladder_run` therefore makes one run and records, for each
rung eps of the ladder, the first iteration where Boyd's residual test
``ResidualTolerance(eps_abs, eps)`` holds, the time at that moment and the
iterate.  The time is CPU seconds of the process (``time.process_time``, one
BLAS thread) from the start of the problem's setup to that iteration, plus one
``finalize``: on a shared machine it is the work done, whatever the load; the
wall time (setup + the loop's own clock ``rec.time`` + finalize) is kept as ``wall``.  This is the time a run stopped by that rule
would take.  The true errors are computed after the clock stopped.
"""
from __future__ import annotations

import statistics
import time

import numpy as np

import admmkit
from admmkit import ResidualTolerance, StoppingRule

from admmkit.benchmarks.rules import methods
from admmkit.benchmarks.rules.families import Discrete

#: residual tolerances 1e-1, 10^-1.5, ..., 1e-10 (half decades)
ADMM_LADDER = tuple(10.0 ** (-k / 2) for k in range(2, 21))


class _Never(StoppingRule):
    """A rule that never fires (the ladder callback ends the run)."""

    name = "never"

    def fired(self, rec):
        """Never."""
        return None


def _rules(d: Discrete, ladder) -> list[ResidualTolerance]:
    # the PDE problems carry physical units: relative tolerances only; QPs: eps_abs = eps_rel (OSQP's habit)
    return [ResidualTolerance(eps if d.kind == "qp" else 0.0, eps) for eps in ladder]


def ladder_run(d: Discrete, label: str, rho0: float, *, ladder=ADMM_LADDER, max_iter: int = 20_000,
               time_limit: float | None = None, repeats: int = 3, long_run: float = 10.0) -> dict:
    """Run method ``label`` from rho0 on ``d``; return the ladder points, status and the medians of ``repeats``."""
    rules = _rules(d, ladder)
    runs = []
    for i in range(repeats):
        t0, cpu0 = time.perf_counter(), time.process_time()
        problem = d.make_admm()
        setup = time.perf_counter() - t0
        policy, order = methods.make(label)
        hits: list[tuple] = []

        def record(rec, hits=hits):
            while len(hits) < len(rules) and rules[len(hits)].fired(rec):
                hits.append((rec.k, rec.time, np.array(rec.x), np.array(rec.lam), time.process_time() - cpu0))
            return len(hits) == len(rules)

        res = admmkit.solve(problem, rho=rho0, policy=policy, order=order, stop=_Never(), max_iter=max_iter,
                            time_limit=time_limit, callback=record)
        t0, c0 = time.perf_counter(), time.process_time()
        problem.finalize(hits[-1][2] if hits else np.asarray(problem.initial_point()[0]))  # u from x, timed once
        finalize, finalize_cpu = time.perf_counter() - t0, time.process_time() - c0
        runs.append({"setup": setup, "finalize": finalize, "finalize_cpu": finalize_cpu, "hits": hits,
                     "result": res, "problem": problem})
        if setup + res.timings["total"] > long_run:
            break
    last = runs[-1]
    res, problem = last["result"], last["problem"]
    points = []
    for j, (k, _, x, lam, _) in enumerate(last["hits"]):
        walls = [r["setup"] + r["hits"][j][1] + r["finalize"] for r in runs if j < len(r["hits"])]
        cpus = [r["hits"][j][4] + r["finalize_cpu"] for r in runs if j < len(r["hits"])]
        point = {"tol": ladder[j], "time": statistics.median(cpus), "times": cpus, "wall": statistics.median(walls),
                 "iterations": k + 1}
        point.update(d.errors(problem.finalize(x), lam))
        points.append(point)
    status = "converged" if len(last["hits"]) == len(rules) else res.status.value
    return {"points": points, "status": status, "iterations": res.iterations, "rho0": rho0,
            "final_rho": res.rho, "rho_changes": res.rho_changes, "repeats": len(runs),
            "setup_time": statistics.median(r["setup"] for r in runs), "message": res.message}


def paper_rule_run(problem, label: str, rho0: float, *, tol: float = 1e-5, max_iter: int = 20_000,
                   time_limit: float | None = None, acceleration: str | None = None) -> admmkit.Result:
    """One run stopped by the paper's rule ||x^{k+1} - x^k|| <= tol ||x^{k+1}|| (or the cap); ``acceleration``
    as :func:`admmkit.solve` takes it."""
    policy, order = methods.make(label)
    return admmkit.solve(problem, rho=rho0, policy=policy, order=order, stop=admmkit.RelativeChange(tol),
                         max_iter=max_iter, time_limit=time_limit, acceleration=acceleration)
