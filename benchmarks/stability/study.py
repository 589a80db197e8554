"""Stability: where each method converges, and how it fails, on the paper's contact examples.

    admmkit bench stability [--out docs/results/bench/stability] [--quick] [--workers 2]

Two sweeps, every ADMM method (:mod:`admmkit.benchmarks.fixtures.methods`), each run
stopped by the paper's rule ||u^{k+1} - u^k||_K <= 1e-5 ||u^{k+1}||_K or the cap
of 20000 iterations:

1. ``rho``: rho_0 = s E for s = 1e-6 ... 1e6 (13 decades), Examples 1 and 2, h = 1/40, P1.
2. ``mesh``: rho_0 = E, h = 1/10 ... 1/160, nu in {0.3, 0.49, 0.499}, P1 and P2, both examples.

Each run ends as one *outcome*: ``converged`` (the rule fired and the true
error is at most 1e-3), ``false_convergence`` (the rule fired while the true
error ||u - u*||_K / ||u*||_K was still above 1e-3), ``max_iter``,
``diverged``, ``stalled`` or ``time_limit``.  u* is the reference solution of
the same discrete problem (:mod:`admmkit.benchmarks.fixtures.families`).

Written to ``out``: ``results.jsonl`` (resumable raw records),
``stability.csv``, ``failures.md`` (which methods failed where),
``rho_sweep.{png,svg}`` and ``mesh_sweep.{png,svg}`` (iterations as heat-maps
with the failures marked), ``mesh_error.{png,svg}`` (error at the stop) and
``README.md``.
"""
from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

from admmkit.benchmarks.fixtures import methods as methods_mod
from admmkit.benchmarks.fixtures.families import CACHE_ENV, discrete, problem_key
from admmkit.benchmarks.runner.harness import check_harness, check_something_left, without_harness_failures
from admmkit.benchmarks.runner.sweep import Executor, clean_float, run_or_report
from admmkit.benchmarks.stability.report import FALSE_CONVERGENCE_ERROR, MAX_ITER, OUTCOMES, _h_label, summarise

RHO_SCALES = tuple(10.0 ** k for k in range(-6, 7))
RHO_H = 1 / 40
MESH_HS = (1 / 10, 1 / 20, 1 / 40, 1 / 80, 1 / 160)
NUS = (0.3, 0.49, 0.499)
ORDERS_P = (1, 2)
TOL = 1e-5
#: the PDAS reference is cross-checked by Clarabel up to this many unknowns (stability runs only)
CROSS_CHECK_MAX = 50_000


def build_cases(admm: list[str], *, examples=("ex1", "ex2"), rho_scales=RHO_SCALES, rho_h=RHO_H, mesh_hs=MESH_HS,
                nus=NUS, orders=ORDERS_P, max_iter: int = MAX_ITER, time_limit: float = 60.0) -> list[dict]:
    """The cases of both sweeps."""
    cases = []
    versions = {m: methods_mod.policy_version(m) for m in admm}
    common = {"target": "stability", "tol": TOL, "max_iter": max_iter, "time_limit": time_limit}
    for ex in examples:
        base = {"scene": ex, "h": rho_h, "nu": None, "p": None}
        for s in rho_scales:
            for m in admm:
                cases.append(common | base | {"sweep": "rho", "method": m, "rho_scale": s,
                                              "policy_version": versions[m],
                                              "group": problem_key(base)})
    for ex in examples:
        for p in orders:
            for nu in nus:
                for h in mesh_hs:
                    base = {"scene": ex, "h": h, "nu": nu, "p": p}
                    for m in admm:
                        cases.append(common | base | {"sweep": "mesh", "method": m, "rho_scale": 1.0,
                                                      "policy_version": versions[m],
                                                      "group": problem_key(base)})
    return cases


def case_cost(case: dict) -> float:
    """Rough relative cost of a case's group share (P2 has four times the unknowns; a rho-sweep problem
    is shared by 13 rho_0 values, so it is counted once per rho_0 and runs early)."""
    share = len(RHO_SCALES) if case.get("sweep") == "rho" else 1
    return (4.0 if case.get("p") == 2 else 1.0) / case["h"] ** 2 / share


_PROBLEMS: dict[str, object] = {}


def run_case(case: dict) -> dict:
    """Worker entry point: one method, one rho_0, one discrete problem, the paper's stopping rule."""
    from admmkit.benchmarks.fixtures.admm_runs import paper_rule_run
    d = discrete(case, cache_dir=os.environ.get(CACHE_ENV), cross_check_max=CROSS_CHECK_MAX)
    if d.key not in _PROBLEMS:
        _PROBLEMS.clear()
        _PROBLEMS[d.key] = d.make_admm()
    problem = _PROBLEMS[d.key]
    factors = getattr(problem, "factors", None)     # the condensed mode's dense factors per rho (public)
    if factors is not None:
        factors.clear()    # each case counts its own factorisations, from an empty cache (iterates are unchanged)
    rho0 = case["rho_scale"] * d.rho_unit
    t0 = time.perf_counter()
    res = paper_rule_run(problem, case["method"], rho0, tol=case["tol"], max_iter=case["max_iter"],
                         time_limit=case["time_limit"], acceleration=case.get("acceleration"))
    seconds = time.perf_counter() - t0
    out = {"status": res.status.value, "iterations": res.iterations, "stopped_by": res.stopped_by,
           "final_rho": clean_float(res.rho), "rho_changes": res.rho_changes, "seconds": seconds,
           "rho0": rho0, "n_free": d.n, "n_c": d.info.get("n_c"), "E": d.rho_unit, "reference": d.ref_info}
    if res.status.value != "diverged" and np.all(np.isfinite(res.x)):
        errs = d.errors(res.x, res.lam)
        out["err"] = clean_float(errs["err"])
        out["err_lam"] = clean_float(errs.get("err_lam"))
    out["outcome"] = outcome(out)
    return out


def outcome(result: dict) -> str:
    """converged / false_convergence / the failing status (see the module docstring)."""
    status = result["status"]
    if status == "converged":
        err = result.get("err")
        return "false_convergence" if err is None or err > FALSE_CONVERGENCE_ERROR else "converged"
    return status if status in OUTCOMES else "diverged"


def run(out="out/stability", *, quick: bool = False, workers: int = 2, methods=None,
        progress: bool = True, command: str = "admmkit bench stability", report_only: bool = False,
        executor: Executor | None = None, **grid) -> list[Path]:
    """Build the cases, run (or resume) the sweep, write the summaries (``executor``: where the cases run)."""
    out = Path(out)
    admm = list(methods) if methods is not None else methods_mod.admm_methods()
    if quick:
        grid = {"rho_scales": (1e-3, 1.0, 1e3), "rho_h": 1 / 10, "mesh_hs": (1 / 10,), "nus": (0.3,),
                "orders": (1,), "max_iter": 2000} | grid
    cases = build_cases(admm, **grid)
    records, wall = run_or_report(cases, "admmkit.benchmarks.stability.study:run_case", out, report_only=report_only,
                                  env={CACHE_ENV: str(out / "cache")}, workers=workers, executor=executor,
                                  progress=progress, cost=case_cost,
                                  label=lambda c: (f"{c['sweep']} {c['scene']} h={_h_label(c['h'])} nu={c['nu']} "
                                                   f"P{c['p']} s={c['rho_scale']:g} {c['method']}"))
    kept, failed = without_harness_failures(records)      # a harness failure is no outcome of a method
    check_something_left(kept, failed, len(cases), out / "results.jsonl", report_only)
    files = summarise(kept, out, command=command, wall=wall,
                      skipped=methods_mod.skipped_policies(), missing=len(cases) - len(kept))
    check_harness(failed, len(cases), files, left_out="left out of the summary, counted as not run")
    return files
