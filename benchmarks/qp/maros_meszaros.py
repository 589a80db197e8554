"""The QP study on a folder of QPs (the Maros-Meszaros set): every penalty rule, both orders, with and without
OSQP's machinery, and OSQP 1.x itself, in one run.

    admmkit bench qp --data ../shared/data/maros_meszaros --out docs/results/maros_meszaros --workers 2

Configurations (:func:`default_configs`), each from rho_0 = 0.1:

- ``preset``: every registered rule, orders xz and zx, inside OSQP's
  machinery (:func:`admmkit.problems.qp.osqp_settings`: Ruiz scaling, a penalty per
  row, over-relaxation 1.6, sigma 1e-6, the test every 25 iterations); rule
  "osqp" is OSQP's rule as OSQP runs it (every 50 iterations, OSQP's
  normalisation), so preset/osqp/xz is OSQP's algorithm;
- ``textbook``: the same rules and orders in admmkit's textbook loop
  (:func:`admmkit.problems.qp.textbook_settings`: no scaling, one rho for every row,
  alpha = 1, the test every iteration);
- one-off ablations of the preset with OSQP's rule in order xz:
  ``no-scaling``, ``uniform-rho`` (no penalty per row), ``alpha-1`` (no
  over-relaxation), and ``polish`` (with polishing); and ``admmkit``,
  admmkit's own preset (:func:`admmkit.problems.qp.admmkit_settings`, with
  its own iteration cap);
- ``OSQP``: the osqp package with its defaults, and with polishing.

Every run asks for the absolute accuracy eps (eps_abs = eps, eps_rel = 0)
and is judged by its own test (``solved``) and by the neutral criteria
(``neutral``: qpbenchmark's infinity-norm primal and dual residuals and
duality gap, each <= eps); :mod:`admmkit.benchmarks.qp.maros_meszaros_runs` has the
details (one admmkit run gives every accuracy).  Iteration cap (default
OSQP's 4000) and CPU-time limit per run are the same for every solver.

Reported per configuration and accuracy: successes under each judgement,
shifted geometric means of iterations and time (a failure counts as the cap
and the limit), factorisations, failure counts, and performance profiles
(Dolan & More 2002) over the neutral successes.  The runs go through the
sweep runner (:mod:`admmkit.benchmarks.runner.sweep`): one case per (problem,
configuration), a problem's cases in one task, every finished case kept in
``results.jsonl`` (``--resume`` continues an interrupted run), on local
processes or Dask.  The report is :mod:`admmkit.benchmarks.qp.maros_meszaros_report`.
"""
from __future__ import annotations

import datetime
import math
import time
from pathlib import Path

import numpy as np
import scipy.io
import scipy.sparse as sp

import admmkit

from admmkit.benchmarks.runner.machine import machine_info
from admmkit.benchmarks.qp.maros_meszaros_report import FIELDS, plot_profiles, read_rows, write_report, write_rows  # noqa: F401
from admmkit.benchmarks.qp.maros_meszaros_stats import (OSQP_DIRECT, RHO0, SHIFT, performance_profile,  # noqa: F401
                                                       shifted_geometric_mean, summarize)
from admmkit.benchmarks.qp.maros_meszaros_runs import (DATA_ENV, VARIANTS, case_qp, run_admmkit, run_osqp,
                                                       warm_qp_kernels)
from admmkit.benchmarks.runner.harness import check_harness, without_harness_failures
from admmkit.benchmarks.runner.sweep import Executor, case_id, finished, run_sweep

from admmkit.problems.qp.convexity import check_convex
from admmkit.problems.qp.mat import list_problems, read_matrices
from admmkit.problems.qp.xstep_forms import REDUCED_MAX_NNZ, reduced_nnz_bound

EPS = (1e-3, 1e-6)
ORDERS = ("xz", "zx")
#: OSQP's default iteration cap
MAX_ITER = 4000
#: CPU seconds per run
TIME_LIMIT = 5.0
#: skip a problem whose x-step matrix would have more nonzeros than this in both forms (reduced: at most
#: nnz(P) + sum_i nnz(row_i)^2; KKT: nnz(P) + 2 nnz(A) + n + m)
NNZ_LIMIT = 2e7
#: the one-off ablations of the preset (OSQP's rule, order xz), and admmkit's own preset (its own iteration cap)
ABLATIONS = ("no-scaling", "uniform-rho", "alpha-1", "polish", "admmkit")
#: the variants that run with their own iteration cap instead of the study's
OWN_CAP = ("admmkit",)


def default_policies() -> list[str]:
    """Every registered rule."""
    return admmkit.policy_names()


# ---------------------------------------------------------------- problems
def x_step_sizes(path: Path) -> tuple[float, float, str, str | None]:
    """Entries of the x-step matrix of a MAT file in the reduced form (a bound) and the KKT form, a note, and why
    the problem cannot run (P not convex, or the file unreadable; None if it can)."""
    try:
        P, A = read_matrices(path)
    except ValueError as err:
        return math.inf, math.inf, "unreadable", str(err)
    A = sp.csr_matrix(A)
    rows = np.diff(A.indptr)
    kkt = float(P.nnz + 2 * A.nnz + A.shape[0] + A.shape[1])
    note = f"densest row of A has {int(rows.max(initial=0))} of {A.shape[1]} entries"
    try:
        check_convex(P)
        nonconvex = None
    except ValueError as err:
        nonconvex = f"not a convex QP: {err}"
    return reduced_nnz_bound(P, A), kkt, note, nonconvex


def skip_reason(path: Path, nnz_limit: float = NNZ_LIMIT, sizes: tuple | None = None) -> str | None:
    """Why a MAT file is not run (None if it is): P is not convex (``load_mat`` refuses it), or the x-step matrix
    would be too large in both forms.

    ``sizes``: :func:`x_step_sizes` of the file, if already read.
    """
    reduced, kkt, note, nonconvex = sizes or x_step_sizes(path)
    if nonconvex:
        return nonconvex
    if min(reduced, kkt) > nnz_limit:
        return (f"x-step matrix: up to {reduced:.2g} nonzeros reduced (P + rho A'A), {kkt:.2g} in KKT form "
                f"(> {nnz_limit:.0g}; {note})")
    return None


def kkt_form_reason(path: Path, sizes: tuple | None = None) -> str | None:
    """Why QP(xstep="auto") solves this problem's x-step in KKT form (None if it uses the reduced form)."""
    reduced, kkt, note, _ = sizes or x_step_sizes(path)
    if reduced > REDUCED_MAX_NNZ:
        return f"P + rho A'A could have {reduced:.2g} nonzeros (> {REDUCED_MAX_NNZ:.0g}), the KKT matrix {kkt:.2g}; {note}"
    return None


# ---------------------------------------------------------------- the sweep's cases
def default_configs(policy_names=None, orders=ORDERS) -> list[tuple[str, str, str]]:
    """(variant, rule, order): every rule in both orders with OSQP's machinery (the preset) and in the textbook
    loop, then OSQP's rule in order xz with one piece of the preset removed at a time, and with polishing."""
    names = list(policy_names) if policy_names else default_policies()
    configs = [(v, n, o) for v in ("preset", "textbook") for n in names for o in orders]
    configs += [(v, "osqp", "xz") for v in ABLATIONS]
    return configs


def build_cases(paths, configs, eps, max_iter: int, time_limit: float, osqp_direct: bool) -> list[dict]:
    """One case per (problem, variant, rule, order) and per (problem, OSQP variant, accuracy); a problem's cases
    are a group."""
    cases = []
    for path in paths:
        base = {"target": "maros_meszaros", "problem": path.stem, "file": path.name, "max_iter": max_iter,
                "time_limit": time_limit, "group": path.stem}
        for variant, policy, order in configs:
            cases.append(base | {"variant": variant, "solver": policy, "order": order, "eps": list(eps)}
                         | ({"max_iter": None} if variant in OWN_CAP else {}))
        if osqp_direct:
            cases += [base | {"variant": v, "solver": OSQP_DIRECT, "order": "-", "eps": e}
                      for v in ("default", "polish") for e in sorted(eps)]
    return cases


_WARM: list = []


def warm_worker() -> None:
    """Before this process's first timed case: admmkit's QP kernels compiled or loaded from numba's cache
    (``admmkit warm-up``'s QP group, admmkit's preset and Anderson among them), so that no case's time holds them, as
    no OSQP case's holds the load of OSQP's
    library; and with them loaded, ``compiled="auto"`` runs the compiled path on every problem (a fresh process takes
    the Python path on a small QP, docs/qp.md "First call"), the path a solver that has run once takes."""
    if not _WARM:
        import osqp  # noqa: F401   (first: a module imported after the kernels' warm-up made the first timed solve
        #                             enumerate the BLAS libraries again, admmkit.loop.blas, 4 ms)
        from admmkit.problems.qp.generate import random_qp
        warm_qp_kernels()
        run_osqp(random_qp(30, 40, seed=0), 1e-3, 4000, 5.0)     # and one OSQP solve: both sides have run once
        _WARM.append(True)


def run_case(case: dict) -> dict:
    """Worker entry point: one configuration on one QP; {"rows": one row per accuracy}."""
    warm_worker()
    qp = case_qp(case["file"])
    if case["solver"] == OSQP_DIRECT:
        return {"rows": [run_osqp(qp, case["eps"], case["max_iter"], case["time_limit"],
                                  polish=case["variant"] == "polish")]}
    return {"rows": run_admmkit(qp, case["variant"], case["solver"], case["order"], tuple(case["eps"]),
                                case["max_iter"], case["time_limit"])}


def case_rows(record: dict) -> list[dict]:
    """The per-run rows of a record; a case that raised, timed out or lost its worker fails at every accuracy."""
    result = record.get("result")
    if result is not None:
        return [dict(r) for r in result["rows"]]
    case = record["case"]
    error = (record.get("error") or "error").split(":")[0]
    eps = case["eps"] if isinstance(case["eps"], list) else [case["eps"]]
    cap = case["max_iter"] or VARIANTS[case["variant"]]().max_iter
    return [{"problem": case["problem"], "n": -1, "m": -1, "variant": case["variant"], "solver": case["solver"],
             "order": case["order"], "eps": e, "solved": False, "neutral": False, "status": error,
             "iterations": cap, "time": case["time_limit"], "setup_time": math.nan, "loop_time": math.nan,
             "factorizations": 0, "rho_changes": 0, "rho_final": math.nan, "rho_max": math.nan,
             "neutral_primal": math.nan, "neutral_dual": math.nan, "neutral_gap": math.nan} for e in eps]


# ---------------------------------------------------------------- the benchmark
def run_benchmark(folder, out, *, policy_names=None, orders=ORDERS, eps=EPS, max_iter: int = MAX_ITER,
                  time_limit: float = TIME_LIMIT, workers: int = 1, only=None, osqp_direct: bool = True,
                  resume: bool = False, nnz_limit: float = NNZ_LIMIT, command: str = "", progress: bool = True,
                  variants=None,
                  executor: Executor | None = None) -> dict:
    """Run the benchmark on every MAT file of ``folder``; write results.csv, README.md and profiles to ``out``.

    ``resume``: keep the cases already in ``out/results.jsonl`` (else start
    afresh); ``executor``: where the cases run (default ``workers`` local processes).
    """
    if isinstance(max_iter, bool) or not isinstance(max_iter, int) or max_iter < 1:
        raise ValueError(f"max_iter must be an integer >= 1, got {max_iter!r}")
    if not (math.isfinite(time_limit) and time_limit > 0):
        raise ValueError(f"time_limit must be a finite number > 0 seconds, got {time_limit!r}")
    if executor is None:
        if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= 2:
            raise ValueError(f"workers must be 1 or 2 (a shared 2-core machine), got {workers!r}")
        executor = Executor(workers=workers)
    elif not executor.dask and not 1 <= executor.workers <= 2:
        raise ValueError(f"workers must be 1 or 2 (a shared 2-core machine), got {executor.workers!r}")
    eps = tuple(sorted({float(e) for e in eps}, reverse=True))
    if not eps or not all(0 < e < 1 for e in eps):
        raise ValueError(f"eps must be numbers in (0, 1), got {eps!r}")
    for order in orders:
        if order not in ORDERS:
            raise ValueError(f"orders must be among {ORDERS}, got {order!r}")
    names = list(policy_names) if policy_names else default_policies()
    unknown = [n for n in names if n not in admmkit.policy_names()]
    if unknown:
        raise ValueError(f"unknown policies {unknown}; known: {', '.join(admmkit.policy_names())}")
    variants = tuple(variants) if variants else tuple(VARIANTS)
    unknown = [v for v in variants if v not in VARIANTS]
    if unknown:
        raise ValueError(f"variants must be among {', '.join(VARIANTS)}, got {unknown}")
    paths = list_problems(folder)
    if only:
        wanted = set(only)
        missing = wanted - {p.stem for p in paths}
        if missing:
            raise ValueError(f"problems not in {folder}: {', '.join(sorted(missing))}")
        paths = [p for p in paths if p.stem in wanted]
    if not paths:
        raise ValueError(f"no MAT files in {folder}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    results = out / "results.jsonl"
    configs = [c for c in default_configs(names, orders) if c[0] in variants]

    started = datetime.datetime.now().isoformat(timespec="seconds")
    t_start = time.perf_counter()
    skipped, kkt_form, costs = {}, {}, {}
    todo = []
    for p in paths:
        sizes = x_step_sizes(p)   # one read of P and A per file
        why = skip_reason(p, nnz_limit, sizes)
        if why:
            skipped[p.stem] = why
        else:
            todo.append(p)
            costs[p.stem] = float(min(sizes[0], sizes[1]))
            kkt_why = kkt_form_reason(p, sizes)
            if kkt_why:
                kkt_form[p.stem] = kkt_why
    if not resume:
        results.unlink(missing_ok=True)
    cases = build_cases(todo, configs, eps, max_iter, time_limit, osqp_direct)
    reused = len(finished(cases, results)) if resume else 0     # a fresh run deleted the file above
    if progress:
        print(f"{len(todo)} problems to run, {len(skipped)} skipped; {len(configs)} admmkit configurations"
              f"{' + OSQP' if osqp_direct else ''}, cap {max_iter} iterations / {time_limit:g} s", flush=True)
    records = run_sweep(cases, "admmkit.benchmarks.qp.maros_meszaros:run_case", results, executor=executor,
                        env={DATA_ENV: str(Path(folder).resolve())}, progress=progress, cost=lambda c: costs[c["problem"]],
                        label=lambda c: f"{c['problem']} {c['variant']}/{c['solver']}/{c['order']}",
                        table=lambda rec: [{"id": rec["id"], **r} for r in case_rows(rec)])
    records, failed = without_harness_failures(records)      # a harness failure is no run of a solver
    rows = [r for c in cases if case_id(c) in records for r in case_rows(records[case_id(c)])]
    meta = {"max_iter": max_iter, "time_limit": time_limit, "machine": machine_info(), "started": started,
            "wall": time.perf_counter() - t_start,
            "workers": executor.describe(len(todo)), "reused": reused, "cases": len(cases)}
    report = write_report(rows, out, skipped=skipped, kkt_form=kkt_form, meta=meta, command=command)
    if progress:
        print(report["text"])
    check_harness(failed, len(cases), [out / "results.csv", out / "summary.csv", out / "README.md"],
                  left_out="left out of the tables and profiles")
    return {"rows": rows, "summary": report["summary"], "skipped": skipped, "kkt_form": kkt_form,
            "figures": report["figures"], "out": out}
