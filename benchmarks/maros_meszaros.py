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
"""
from __future__ import annotations

import csv
import datetime
import math
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np
import scipy.io
import scipy.sparse as sp

import admmkit
import policies
from admmkit import Status

from .machine import machine_info

from problems.qp.mat import list_problems, load_mat
from problems.qp.problem import QP, REDUCED_MAX_NNZ, reduced_nnz_bound
from problems.qp.termination import OSQPTermination, osqp_relative_residuals, osqp_residuals

RHO0 = 0.1
EPS = (1e-3, 1e-6)
ORDERS = ("xz", "zx")
MAX_ITER = 20_000
TIME_LIMIT = 10.0
SHIFT = 10.0
#: a wall-time cap of WALL_FACTOR x the (CPU) time limit, against a stalled machine
WALL_FACTOR = 20.0
#: skip a problem whose x-step matrix would have more nonzeros than this in both forms (reduced: at most
#: nnz(P) + sum_i nnz(row_i)^2; KKT: nnz(P) + 2 nnz(A) + n + m)
NNZ_LIMIT = 2e7
#: the extra configuration of OSQP's rule with OSQP's exact QP normalisation
OSQP_QP = "osqp_qp"
#: the label of OSQP called directly
OSQP_DIRECT = "OSQP"

FIELDS = ("problem", "n", "m", "solver", "order", "eps", "solved", "status", "iterations", "time", "setup_time",
          "factorizations", "rho_changes", "rho_final", "rho_max", "primal_res", "dual_res")


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


# ---------------------------------------------------------------- statistics
def shifted_geometric_mean(values, shift: float = SHIFT) -> float:
    """exp(mean(log(v + shift))) - shift (Mittelmann's shifted geometric mean)."""
    v = np.asarray(list(values), dtype=float)
    if v.size == 0:
        return math.nan
    return float(np.exp(np.mean(np.log(v + shift))) - shift)


def solver_keys(rows: list[dict]) -> list[tuple[str, str]]:
    """(solver, order) pairs in first-seen order."""
    return list(dict.fromkeys((r["solver"], r["order"]) for r in rows))


def summarize(rows: list[dict], max_iter: int, time_limit: float) -> list[dict]:
    """One line per (solver, order, eps): successes, shifted geometric means, factorisations, statuses."""
    out = []
    for eps in sorted({r["eps"] for r in rows}, reverse=True):
        for solver, order in solver_keys(rows):
            sel = [r for r in rows if r["solver"] == solver and r["order"] == order and r["eps"] == eps]
            if not sel:
                continue
            solved = [r for r in sel if _true(r["solved"])]
            statuses: dict[str, int] = {}
            for r in sel:
                if not _true(r["solved"]):
                    statuses[r["status"]] = statuses.get(r["status"], 0) + 1
            facts = [float(r["factorizations"]) for r in sel]
            out.append({
                "eps": eps, "solver": solver, "order": order, "problems": len(sel), "solved": len(solved),
                "rate": len(solved) / len(sel),
                "sgm_iterations": shifted_geometric_mean(
                    float(r["iterations"]) if _true(r["solved"]) else max_iter for r in sel),
                "sgm_time": shifted_geometric_mean(
                    float(r["time"]) if _true(r["solved"]) else time_limit for r in sel),
                "factorizations_mean": float(np.mean(facts)), "factorizations_max": int(max(facts)),
                "failures": statuses,
                "runaway": sum(1 for r in sel if _finite(r["rho_max"]) and float(r["rho_max"]) > 1e20 * RHO0),
            })
    return out


def performance_profile(rows: list[dict], metric: str, eps: float):
    """Dolan-More profile: {(solver, order): (taus, fraction of problems solved within tau x the best)}."""
    sel = [r for r in rows if r["eps"] == eps]
    problems = sorted({r["problem"] for r in sel})
    keys = solver_keys(sel)
    table = np.full((len(problems), len(keys)), np.inf)
    index = {p: i for i, p in enumerate(problems)}
    for r in sel:
        if _true(r["solved"]):
            table[index[r["problem"]], keys.index((r["solver"], r["order"]))] = max(float(r[metric]), 1e-9)
    best = table.min(axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(np.isfinite(best), table / best, np.inf)
    finite = ratio[np.isfinite(ratio)]
    top = max(float(finite.max()) if finite.size else 2.0, 2.0)
    taus = np.logspace(0, math.log10(top) + 0.05, 400)
    return {key: (taus, (ratio[:, j][:, None] <= taus[None, :]).mean(axis=0)) for j, key in enumerate(keys)}


def _true(v) -> bool:
    return v is True or str(v) == "True"


def _finite(v) -> bool:
    try:
        return math.isfinite(float(v))
    except (TypeError, ValueError):
        return False


# ---------------------------------------------------------------- output
def plot_profiles(rows: list[dict], path_stem: Path) -> list[Path]:
    """Performance profiles (rows: accuracies, columns: iterations and time) as PNG and SVG."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    epss = sorted({r["eps"] for r in rows}, reverse=True)
    names = list(dict.fromkeys(r["solver"] for r in rows))
    colors = {name: plt.cm.tab10(i % 10) for i, name in enumerate(n for n in names if n != OSQP_DIRECT)}
    colors[OSQP_DIRECT] = "black"
    styles = {"xz": "-", "zx": "--", "-": "-"}
    fig, axes = plt.subplots(len(epss), 2, figsize=(13, 4.6 * len(epss)), squeeze=False)
    for i, eps in enumerate(epss):
        for j, (metric, label) in enumerate([("iterations", "iterations"), ("time", "time")]):
            ax = axes[i][j]
            for (solver, order), (taus, frac) in performance_profile(rows, metric, eps).items():
                ax.step(taus, frac, where="post", color=colors[solver], linestyle=styles.get(order, "-"),
                        linewidth=2.2 if solver == OSQP_DIRECT else 1.4,
                        label=solver if order == "-" else f"{solver} ({order})")
            ax.set_xscale("log", base=2)
            ax.set_ylim(0, 1.02)
            ax.grid(True, which="both", alpha=0.3)
            ax.set_xlabel(f"tau: within tau x the best {label}")
            ax.set_ylabel("fraction of problems")
            ax.set_title(f"{label}, eps_abs = eps_rel = {eps:g}")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="center right", fontsize=8, frameon=False)
    fig.suptitle("Performance profiles on the Maros-Meszaros QPs (solid: order xz, dashed: zx)")
    fig.tight_layout(rect=(0, 0, 0.83, 0.97))
    paths = []
    for ext in ("png", "svg"):
        p = path_stem.with_suffix(f".{ext}")
        fig.savefig(p, dpi=110)
        paths.append(p)
    plt.close(fig)
    return paths


def _fmt_failures(failures: dict) -> str:
    return ", ".join(f"{k} {v}" for k, v in sorted(failures.items())) or "-"


def markdown(summary: list[dict], skipped: dict[str, str], meta: dict, command: str, n_run: int,
             figure: str, kkt_form: dict[str, str] | None = None) -> str:
    """The report: settings, one table per accuracy, the KKT-form and the skipped problems, the machine."""
    lines = [
        "# Penalty rules on the Maros-Meszaros QPs",
        "",
        f"Command (from the repository root): `{command}`",
        "",
        f"{n_run} problems run, {len(skipped)} skipped (listed below).  Every admmkit rule starts from "
        f"rho_0 = {RHO0:g}; iteration cap {meta['max_iter']}, time limit {meta['time_limit']:g} s per problem and "
        f"configuration.  Times are CPU seconds of the process (setup + solve, BLAS on one thread): the 2-core "
        f"machine was shared ({meta['workers']} worker process(es) here and other jobs), and wall time would "
        "charge a run for the other processes.  "
        "Solved means OSQP's test with eps_abs = eps_rel = eps on the unscaled QP (docs/policies.md).  "
        f"Shifted geometric means use shift {SHIFT:g} and count a failure as the cap / the limit.  "
        "Factorisations: of the x-step matrix during the run up to that accuracy (OSQP: 1 + rho updates).  "
        "'runaway': runs where rho exceeded 1e20 rho_0.  Per-run data: `results.csv`.",
        "",
        f"![performance profiles]({figure})",
        "",
    ]
    for eps in sorted({s["eps"] for s in summary}, reverse=True):
        lines += [f"## eps = {eps:g}", "",
                  "| rule | order | solved | rate | SGM iterations | SGM time [s] | factorisations mean / max "
                  "| failures | runaway |",
                  "|---|---|---|---|---|---|---|---|---|"]
        rows = sorted((s for s in summary if s["eps"] == eps), key=lambda s: (-s["rate"], s["sgm_time"]))
        for s in rows:
            lines.append(f"| {s['solver']} | {s['order']} | {s['solved']}/{s['problems']} | {100 * s['rate']:.1f}% "
                         f"| {s['sgm_iterations']:.1f} | {s['sgm_time']:.3f} | {s['factorizations_mean']:.1f} / "
                         f"{s['factorizations_max']} | {_fmt_failures(s['failures'])} | {s['runaway']} |")
        lines.append("")
    lines += ["## x-step in KKT form", "",
              "A dense row of A makes A'A dense; these problems ran with OSQP's KKT form of the x-step "
              "(`QP(xstep=\"auto\")`, factorised by qdldl or SuperLU):", ""]
    lines += [f"- {name}: {why}" for name, why in sorted((kkt_form or {}).items())] or ["- none"]
    lines += ["", "## Skipped", ""]
    lines += [f"- {name}: {why}" for name, why in sorted(skipped.items())] or ["- none"]
    lines += ["", "## Machine", ""] + [f"- {k}: {v}" for k, v in meta["machine"].items()]
    lines += [f"- started {meta['started']}, wall time {meta['wall']:.0f} s", ""]
    return "\n".join(lines)


def write_rows(rows: list[dict], path: Path, append: bool = False) -> None:
    """Write (or append) per-run rows as CSV."""
    new = not (append and path.exists())
    with path.open("a" if append else "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=FIELDS)
        if new:
            w.writeheader()
        for r in rows:
            w.writerow({k: (f"{r[k]:.6g}" if isinstance(r[k], float) else r[k]) for k in FIELDS})


def read_rows(path: Path) -> list[dict]:
    """Rows written by :func:`write_rows`, numbers parsed."""
    rows = []
    with path.open(newline="") as fh:
        for r in csv.DictReader(fh):
            for k in ("n", "m", "iterations", "factorizations", "rho_changes"):
                r[k] = int(r[k])
            for k in ("eps", "time", "setup_time", "rho_final", "rho_max", "primal_res", "dual_res"):
                r[k] = float(r[k])
            r["solved"] = _true(r["solved"])
            rows.append(r)
    return rows


# ---------------------------------------------------------------- the benchmark
def run_benchmark(folder, out, *, policy_names=None, orders=ORDERS, eps=EPS, max_iter: int = MAX_ITER,
                  time_limit: float = TIME_LIMIT, workers: int = 1, only=None, osqp_direct: bool = True,
                  resume: bool = False, nnz_limit: float = NNZ_LIMIT, command: str = "", progress: bool = True
                  ) -> dict:
    """Run the benchmark on every MAT file of ``folder``; write results.csv, README.md and profiles to ``out``."""
    if isinstance(max_iter, bool) or not isinstance(max_iter, int) or max_iter < 1:
        raise ValueError(f"max_iter must be an integer >= 1, got {max_iter!r}")
    if not (math.isfinite(time_limit) and time_limit > 0):
        raise ValueError(f"time_limit must be a finite number > 0 seconds, got {time_limit!r}")
    if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= 2:
        raise ValueError(f"workers must be 1 or 2 (a shared 2-core machine), got {workers!r}")
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
    csv_path = out / "results.csv"
    configs = [(n, o) for n in names for o in orders]

    started = datetime.datetime.now().isoformat(timespec="seconds")
    t_start = time.perf_counter()
    skipped, kkt_form = {}, {}
    todo = []
    for p in paths:
        sizes = x_step_sizes(p)   # one read of P and A per file
        why = skip_reason(p, nnz_limit, sizes)
        if why:
            skipped[p.stem] = why
        else:
            todo.append(p)
            kkt_why = kkt_form_reason(p, sizes)
            if kkt_why:
                kkt_form[p.stem] = kkt_why
    done = set()
    if resume and csv_path.exists():
        done = {r["problem"] for r in read_rows(csv_path)}
    elif csv_path.exists():
        csv_path.unlink()
    pending = [p for p in todo if p.stem not in done]
    if progress:
        print(f"{len(todo)} problems to run ({len(done)} already in {csv_path}), {len(skipped)} skipped; "
              f"{len(configs)} admmkit configurations{' + OSQP' if osqp_direct else ''}, "
              f"cap {max_iter} iterations / {time_limit:g} s, {workers} worker(s)", flush=True)
    args = dict(eps=eps, max_iter=max_iter, time_limit=time_limit, osqp_direct=osqp_direct)

    def report(i, path, rows):
        write_rows(rows, csv_path, append=True)
        if progress:
            elapsed = time.perf_counter() - t_start
            solved = sum(1 for r in rows if r["solved"] and r["eps"] == min(eps))
            total = sum(1 for r in rows if r["eps"] == min(eps))
            eta = elapsed / i * (len(pending) - i)
            print(f"[{i:3d}/{len(pending)}] {path.stem:12s} solved {solved:2d}/{total} at eps={min(eps):g}  "
                  f"elapsed {elapsed:6.0f} s, ETA {eta:6.0f} s", flush=True)

    if workers == 1:
        for i, p in enumerate(pending, 1):
            report(i, p, run_problem(str(p), configs, **args))
    else:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            futures = {pool.submit(run_problem, str(p), configs, **args): p for p in pending}
            for i, fut in enumerate(as_completed(futures), 1):
                report(i, futures[fut], fut.result())

    rows = read_rows(csv_path) if csv_path.exists() else []
    rows.sort(key=lambda r: (r["problem"], r["solver"], r["order"], -r["eps"]))
    write_rows(rows, csv_path)
    summary = summarize(rows, max_iter, time_limit)
    meta = {"max_iter": max_iter, "time_limit": time_limit, "workers": workers, "machine": machine_info(),
            "started": started, "wall": time.perf_counter() - t_start}
    figures = plot_profiles(rows, out / "profiles") if rows else []
    text = markdown(summary, skipped, meta, command, len({r["problem"] for r in rows}), "profiles.png", kkt_form)
    (out / "README.md").write_text(text)
    with (out / "summary.csv").open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["eps", "solver", "order", "problems", "solved", "rate", "sgm_iterations", "sgm_time",
                    "factorizations_mean", "factorizations_max", "failures", "runaway"])
        for s in summary:
            w.writerow([s["eps"], s["solver"], s["order"], s["problems"], s["solved"], f"{s['rate']:.4f}",
                        f"{s['sgm_iterations']:.2f}", f"{s['sgm_time']:.4f}", f"{s['factorizations_mean']:.2f}",
                        s["factorizations_max"], _fmt_failures(s["failures"]), s["runaway"]])
    if progress:
        print(text)
    return {"rows": rows, "summary": summary, "skipped": skipped, "kkt_form": kkt_form, "figures": figures, "out": out}
