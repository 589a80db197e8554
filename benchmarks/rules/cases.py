"""How one case of ``admmkit bench rules`` runs, per family; each returns the same *runs*.

A run is ``{"solved", "status", "iterations", "seconds"}`` (plus ``"eps"``
for a QP, whose one solve is judged at every accuracy), judged by the
family's own truthful measure:

- ``qp``: a Maros-Meszaros problem under OSQP's machinery (the preset,
  order xz, rho_0 = 0.1; ``admmkit.benchmarks.qp.maros_meszaros_runs``), or
  under admmkit's preset (``case["preset"] = "admmkit"``, its own cap):
  solved when the solver's own test said solved *and* the returned point
  meets the neutral criteria at that eps (a ``solved`` that misses them is
  the failure ``solved_not_neutral``);
- ``contact``, ``obstacle``, ``friction``: contact Examples 1 and 2, the
  radial obstacle and Example 1 with Tresca friction from rho_0 over the
  decades (``admmkit.benchmarks.policies.study``): solved when the
  relative error against an independent reference reaches 1e-6 before the cap;
- ``framework``: the four problems written with the building blocks
  (``admmkit.benchmarks.framework.four_problems``) with the same stop
  against their cvxpy references;
- ``stability``: the paper's contact examples with the paper's stop
  (``admmkit.benchmarks.stability.study``): solved when the stop fired
  with a true error of at most 1e-3 (a false convergence is a failure).
"""
from __future__ import annotations

import time

import numpy as np

import admmkit
from admmkit.benchmarks.qp.maros_meszaros_runs import DATA_ENV  # noqa: F401  (the study sets it for its workers)

#: the stop of the framework family (relative error against the cvxpy reference)
ORACLE = 1e-6
_CACHE: dict = {}


def run_fe(case: dict) -> list[dict]:
    """contact / obstacle / friction: one policies_fe case, solved at the oracle's 1e-6."""
    from admmkit.benchmarks.policies.study import run_case
    r = run_case(case)
    status = "solved" if r["reached"] else ("max_iter" if r["status"] == "max_iter" else r["status"])
    return [{"solved": bool(r["reached"]), "status": status, "iterations": r["iterations"],
             "seconds": r["seconds"]}]


def run_stability(case: dict) -> list[dict]:
    """stability: one run of the stability grid, solved when the paper's stop fired at a true error <= 1e-3."""
    from admmkit.benchmarks.stability.study import run_case
    r = run_case(case)
    return [{"solved": r["outcome"] == "converged", "status": r["outcome"], "iterations": r["iterations"],
             "seconds": r["seconds"]}]


def run_qp(case: dict) -> list[dict]:
    """qp: one rule on one Maros-Meszaros problem under OSQP's machinery, judged at every eps."""
    from admmkit.benchmarks.qp.maros_meszaros_runs import case_qp, run_admmkit, warm_qp_kernels
    warm_qp_kernels()
    qp = case_qp(case["file"])
    variant = {"osqp": "preset", "admmkit": "admmkit"}[case.get("preset", "osqp")]
    rows = run_admmkit(qp, variant, case["rule"], case["order"], tuple(case["eps"]), case["max_iter"],
                       case["time_limit"], acceleration=case.get("acceleration"))
    runs = []
    for row in rows:
        solved, neutral = bool(row["solved"]), bool(row["neutral"])
        status = "solved" if solved and neutral else ("solved_not_neutral" if solved else str(row["status"]))
        runs.append({"eps": row["eps"], "solved": solved and neutral, "status": status,
                     "iterations": row["iterations"], "seconds": row["time"]})
    return runs


def run_framework(case: dict) -> list[dict]:
    """framework: one of the four problems from rho_0, stopped at relative error 1e-6 against cvxpy.

    The reference is computed once per worker; the problem is built anew for every case, so that no
    case finds factorisations an earlier one left in the x-step's cache (the times compare cold runs).
    """
    from admmkit.benchmarks.framework.four_problems import PROBLEMS, build
    key = ("framework", case["problem"])
    if key not in _CACHE:
        _CACHE.clear()
        _CACHE[key] = build(case["problem"])[1]
    ref = _CACHE[key]
    problem = PROBLEMS[case["problem"]]()[0]
    scale = float(np.linalg.norm(ref))

    def reached(rec):
        return float(np.linalg.norm(rec.x - ref)) <= ORACLE * scale
    start = time.perf_counter()
    res = admmkit.solve(problem, rho=case["rho0"], policy=case["rule"], order=case["order"],
                        stop=admmkit.RelativeChange(1e-300), max_iter=case["max_iter"], callback=reached,
                        acceleration=case.get("acceleration"))
    seconds = time.perf_counter() - start
    solved = res.status.value == "stopped"
    return [{"solved": solved, "status": "solved" if solved else res.status.value, "iterations": res.iterations,
             "seconds": seconds}]


#: the case runner of each family
RUNNERS = {"qp": run_qp, "contact": run_fe, "obstacle": run_fe, "friction": run_fe, "framework": run_framework,
           "stability": run_stability}


def run_case(case: dict) -> dict:
    """Worker entry point: the case's runs (``{"runs": [...]}``)."""
    return {"runs": RUNNERS[case["family"]](case)}
