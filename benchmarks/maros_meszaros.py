"""Policy benchmark on a folder of QPs (the Maros-Meszaros set): every rule, both orders, and OSQP.

    admmkit bench qp --data ../shared/data/maros_meszaros --out docs/results/maros_meszaros

For every QP in the folder and every configuration (a registered penalty rule
in order "xz" or "zx", and OSQP called directly) the benchmark runs from
rho_0 = 0.1 (OSQP's default) until OSQP's termination test holds at the
tightest accuracy, the iteration cap or the time limit (per problem and
configuration, in CPU seconds of the process: the machine is shared, and wall
time would charge a run for the other processes).  Accuracies: eps_abs = eps_rel = 1e-3 and 1e-6, with OSQP's
definitions of the residuals (:mod:`problems.qp.termination`).  admmkit's
rules never look at the clock, so one run to 1e-6 also gives the run to 1e-3
(the first iteration at which the 1e-3 test held, and its time); OSQP is run
once per accuracy.

Reported per configuration and accuracy: the success rate, the shifted
geometric means of iterations and time (shift 10; a failure counts as the
iteration cap and the time limit), the factorisations of the x-step matrix,
status counts and the performance profiles (Dolan & More 2002).  Where a
dense row of A makes A'A dense, the QP plug-in solves the x-step in OSQP's
KKT form (``QP(xstep="auto")``) and the report lists those problems; a
problem too large for this machine in either form is listed as skipped with
the reason.

Configurations beyond the registered rules: ``osqp_qp`` is OSQP's rule fed
OSQP's exact normalisation of the QP residuals
(``policies.OSQPRule(residuals=osqp_relative_residuals(qp))``); ``OSQP`` is
the osqp package itself with its defaults (Ruiz scaling, over-relaxation
alpha = 1.6, a rho per constraint type, its adaptive rho every 50 iterations)
except: no polishing, no duality-gap test, the termination checked every
iteration (so iteration counts compare), the same accuracy, iteration cap and
time limit.

The runs go through the sweep runner (:mod:`benchmarks.sweep`): one case per
(problem, configuration), the cases of one problem in one task (the MAT file
is read once per worker), every finished case kept in ``results.jsonl``
(``--resume`` continues an interrupted run), on local processes or Dask;
``results.csv`` and the report are written from those records, atomically.
The report (statistics, profiles, tables) is :mod:`benchmarks.maros_meszaros_report`.
"""
from __future__ import annotations

import datetime
import math
import os
import time
from pathlib import Path

import numpy as np
import scipy.io
import scipy.sparse as sp

import admmkit
import policies
from admmkit import Status

from .machine import machine_info
from .maros_meszaros_report import (FIELDS, OSQP_DIRECT, RHO0, SHIFT, performance_profile,  # noqa: F401
                                    plot_profiles, read_rows, shifted_geometric_mean, summarize, write_report,
                                    write_rows)
from .sweep import Executor, case_id, run_sweep

from problems.qp.mat import list_problems, load_mat
from problems.qp.problem import QP, REDUCED_MAX_NNZ, reduced_nnz_bound
from problems.qp.termination import OSQPTermination, osqp_relative_residuals, osqp_residuals

EPS = (1e-3, 1e-6)
ORDERS = ("xz", "zx")
MAX_ITER = 20_000
TIME_LIMIT = 10.0
#: a wall-time cap of WALL_FACTOR x the (CPU) time limit, against a stalled machine
WALL_FACTOR = 20.0
#: skip a problem whose x-step matrix would have more nonzeros than this in both forms (reduced: at most
#: nnz(P) + sum_i nnz(row_i)^2; KKT: nnz(P) + 2 nnz(A) + n + m)
NNZ_LIMIT = 2e7
#: the extra configuration of OSQP's rule with OSQP's exact QP normalisation
OSQP_QP = "osqp_qp"
#: the folder of the MAT files, for the workers (set by the driver through the sweep's env)
DATA_ENV = "ADMMKIT_QP_DATA"


def default_policies() -> list[str]:
    """Every registered rule, then OSQP's rule with the QP's exact normalisation."""
    return admmkit.policy_names() + [OSQP_QP]


def make_policy(name: str, qp: QP) -> admmkit.Policy:
    """A fresh policy for one run (``osqp_qp`` gets the QP's OSQP normalisation)."""
    if name == OSQP_QP:
        return policies.OSQPRule(residuals=osqp_relative_residuals(qp))
    return admmkit.make_policy(name)


# ---------------------------------------------------------------- problems
def x_step_sizes(path: Path) -> tuple[float, float, str]:
    """Entries of the x-step matrix of a MAT file in the reduced form (a bound) and the KKT form, and a note."""
    data = scipy.io.loadmat(str(path), variable_names=["P", "A"])
    P, A = sp.csc_matrix(data["P"]), sp.csr_matrix(data["A"])
    rows = np.diff(A.indptr)
    kkt = float(P.nnz + 2 * A.nnz + A.shape[0] + A.shape[1])
    note = f"densest row of A has {int(rows.max(initial=0))} of {A.shape[1]} entries"
    return reduced_nnz_bound(P, A), kkt, note


def skip_reason(path: Path, nnz_limit: float = NNZ_LIMIT, sizes: tuple | None = None) -> str | None:
    """Why a MAT file is not run (None if it is): the x-step matrix would be too large in both forms.

    ``sizes``: :func:`x_step_sizes` of the file, if already read.
    """
    reduced, kkt, note = sizes or x_step_sizes(path)
    if min(reduced, kkt) > nnz_limit:
        return (f"x-step matrix: up to {reduced:.2g} nonzeros reduced (P + rho A'A), {kkt:.2g} in KKT form "
                f"(> {nnz_limit:.0g}; {note})")
    return None


def kkt_form_reason(path: Path, sizes: tuple | None = None) -> str | None:
    """Why QP(xstep="auto") solves this problem's x-step in KKT form (None if it uses the reduced form)."""
    reduced, kkt, note = sizes or x_step_sizes(path)
    if reduced > REDUCED_MAX_NNZ:
        return f"P + rho A'A could have {reduced:.2g} nonzeros (> {REDUCED_MAX_NNZ:.0g}), the KKT matrix {kkt:.2g}; {note}"
    return None


def _fresh(qp: QP) -> QP:
    """A new QP object on the same data (an empty factorisation cache)."""
    return QP(qp.P, qp.q, qp.A, qp.l, qp.u, qp.r, sigma=qp.sigma, name=qp.name, xstep=qp.xstep)


# ---------------------------------------------------------------- one run
def run_admmkit(qp: QP, policy: str, order: str, eps=EPS, max_iter: int = MAX_ITER,
                time_limit: float = TIME_LIMIT) -> list[dict]:
    """One admmkit run to the tightest eps; one row per eps (solved or not at that accuracy).

    Times are CPU seconds of this process (setup + solve; BLAS runs on one
    thread), and so is the limit: the machine is shared, and wall time would
    charge a run for the other processes.  A wall-time cap of WALL_FACTOR x
    the limit guards against a stalled machine.
    """
    clock = time.process_time
    t0 = clock()
    fresh = _fresh(qp)
    rule = make_policy(policy, fresh)
    setup = clock() - t0
    stop = OSQPTermination(fresh, eps, clock=clock)
    deadline = t0 + time_limit
    rho_max = [RHO0]

    def watch(rec):
        rho_max[0] = max(rho_max[0], rec.rho)
        return clock() > deadline

    res = admmkit.solve(fresh, rho=RHO0, policy=rule, order=order, stop=stop, max_iter=max_iter,
                        time_limit=WALL_FACTOR * time_limit, callback=watch)
    total = clock() - t0
    status = {Status.STOPPED: "time_limit", Status.TIME_LIMIT: "wall_limit"}.get(res.status, res.status.value)
    rows = []
    for e in sorted(stop.eps):
        base = {"problem": qp.name, "n": qp.n, "m": qp.m, "solver": policy, "order": order, "eps": e,
                "setup_time": setup, "rho_changes": res.rho_changes, "rho_final": res.rho,
                "rho_max": max(rho_max[0], res.rho)}
        if e in stop.met and setup + stop.met[e][1] <= time_limit:
            its, seconds, facts = stop.met[e]
            rows.append({**base, "solved": True, "status": "solved", "iterations": its, "time": setup + seconds,
                         "factorizations": facts, "primal_res": math.nan, "dual_res": math.nan})
        else:
            last = stop.last or {}
            rows.append({**base, "solved": False, "status": "time_limit" if e in stop.met else status,
                         "iterations": res.iterations, "time": total, "factorizations": res.factorizations or 0,
                         "primal_res": last.get("primal", math.nan), "dual_res": last.get("dual", math.nan)})
    return rows


def run_osqp(qp: QP, eps: float, max_iter: int = MAX_ITER, time_limit: float = TIME_LIMIT) -> dict:
    """OSQP itself at accuracy eps (see the module docstring for its settings); CPU time as for admmkit."""
    import osqp
    clock = time.process_time
    t0 = clock()
    solver = osqp.OSQP()
    l = np.where(np.isfinite(qp.l), qp.l, -1e30)
    u = np.where(np.isfinite(qp.u), qp.u, 1e30)
    solver.setup(P=sp.triu(qp.P, format="csc"), q=qp.q, A=qp.A.tocsc(), l=l, u=u, verbose=False,
                 eps_abs=eps, eps_rel=eps, polishing=False, check_dualgap=False, check_termination=1,
                 max_iter=max_iter, time_limit=WALL_FACTOR * time_limit)
    setup = clock() - t0
    r = solver.solve(raise_error=False)
    total = clock() - t0
    info = r.info
    ok = info.status == "solved" and total <= time_limit
    status = "solved" if ok else ("time_limit" if info.status == "solved" else str(info.status).replace(" ", "_"))
    res = {"primal": math.nan, "dual": math.nan}
    if r.x is not None and np.all(np.isfinite(r.x)):
        Ax = qp.A @ r.x
        res = osqp_residuals(qp, r.x, np.clip(Ax, qp.l, qp.u), r.y, Ax)
    return {"problem": qp.name, "n": qp.n, "m": qp.m, "solver": OSQP_DIRECT, "order": "-", "eps": eps,
            "solved": ok, "status": status, "iterations": int(info.iter), "time": total, "setup_time": setup,
            "factorizations": 1 + int(info.rho_updates), "rho_changes": int(info.rho_updates),
            "rho_final": math.nan, "rho_max": math.nan, "primal_res": res["primal"], "dual_res": res["dual"]}


def run_problem(path: str, configs: list[tuple[str, str]], eps=EPS, max_iter: int = MAX_ITER,
                time_limit: float = TIME_LIMIT, osqp_direct: bool = True) -> list[dict]:
    """Every configuration on one MAT file (a worker's task)."""
    qp = load_mat(path)
    rows = []
    for policy, order in configs:
        rows += run_admmkit(qp, policy, order, eps, max_iter, time_limit)
    if osqp_direct:
        rows += [run_osqp(qp, e, max_iter, time_limit) for e in sorted(eps)]
    return rows


# ---------------------------------------------------------------- the sweep's cases
def build_cases(paths, configs, eps, max_iter: int, time_limit: float, osqp_direct: bool) -> list[dict]:
    """One case per (problem, rule, order) and per (problem, OSQP accuracy); a problem's cases are a group."""
    cases = []
    for path in paths:
        base = {"target": "maros_meszaros", "problem": path.stem, "file": path.name, "max_iter": max_iter,
                "time_limit": time_limit, "group": path.stem}
        for policy, order in configs:
            cases.append(base | {"solver": policy, "order": order, "eps": list(eps)})
        if osqp_direct:
            cases += [base | {"solver": OSQP_DIRECT, "order": "-", "eps": e} for e in sorted(eps)]
    return cases


_QP: dict = {}


def run_case(case: dict) -> dict:
    """Worker entry point: one configuration on one QP; {"rows": one row per accuracy}."""
    path = Path(os.environ.get(DATA_ENV, ".")) / case["file"]
    if _QP.get("path") != path:
        _QP.clear()
        _QP.update(path=path, qp=load_mat(path))
    qp = _QP["qp"]
    if case["solver"] == OSQP_DIRECT:
        return {"rows": [run_osqp(qp, case["eps"], case["max_iter"], case["time_limit"])]}
    return {"rows": run_admmkit(qp, case["solver"], case["order"], tuple(case["eps"]), case["max_iter"],
                                case["time_limit"])}


def case_rows(record: dict) -> list[dict]:
    """The per-run rows of a record; a case that raised, timed out or lost its worker fails at every accuracy."""
    result = record.get("result")
    if result is not None:
        return [dict(r) for r in result["rows"]]
    case = record["case"]
    error = (record.get("error") or "error").split(":")[0]
    eps = case["eps"] if isinstance(case["eps"], list) else [case["eps"]]
    return [{"problem": case["problem"], "n": -1, "m": -1, "solver": case["solver"], "order": case["order"],
             "eps": e, "solved": False, "status": error, "iterations": case["max_iter"], "time": case["time_limit"],
             "setup_time": math.nan, "factorizations": 0, "rho_changes": 0, "rho_final": math.nan,
             "rho_max": math.nan, "primal_res": math.nan, "dual_res": math.nan} for e in eps]


# ---------------------------------------------------------------- the benchmark
def run_benchmark(folder, out, *, policy_names=None, orders=ORDERS, eps=EPS, max_iter: int = MAX_ITER,
                  time_limit: float = TIME_LIMIT, workers: int = 1, only=None, osqp_direct: bool = True,
                  resume: bool = False, nnz_limit: float = NNZ_LIMIT, command: str = "", progress: bool = True,
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
    known = set(admmkit.policy_names()) | {OSQP_QP}
    unknown = [n for n in names if n not in known]
    if unknown:
        raise ValueError(f"unknown policies {unknown}; known: {', '.join(sorted(known))}")
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
    configs = [(n, o) for n in names for o in orders]

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
    if progress:
        print(f"{len(todo)} problems to run, {len(skipped)} skipped; {len(configs)} admmkit configurations"
              f"{' + OSQP' if osqp_direct else ''}, cap {max_iter} iterations / {time_limit:g} s", flush=True)
    records = run_sweep(cases, "benchmarks.maros_meszaros:run_case", results, executor=executor,
                        env={DATA_ENV: str(Path(folder).resolve())}, progress=progress, cost=lambda c: costs[c["problem"]],
                        label=lambda c: f"{c['problem']} {c['solver']}/{c['order']}",
                        table=lambda rec: [{"id": rec["id"], **r} for r in case_rows(rec)])
    rows = [r for c in cases if case_id(c) in records for r in case_rows(records[case_id(c)])]
    meta = {"max_iter": max_iter, "time_limit": time_limit, "machine": machine_info(), "started": started,
            "wall": time.perf_counter() - t_start,
            "workers": executor.describe(len(todo))}
    report = write_report(rows, out, skipped=skipped, kkt_form=kkt_form, meta=meta, command=command)
    if progress:
        print(report["text"])
    return {"rows": rows, "summary": report["summary"], "skipped": skipped, "kkt_form": kkt_form,
            "figures": report["figures"], "out": out}
