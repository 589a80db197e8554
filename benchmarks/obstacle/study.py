"""Convergence study and policy sweep for the obstacle plug-in.

    admmkit bench obstacle [--out DIR] [--quick] [--workers N | --dask-workers N]   (default DIR: ./out/obstacle/)

1. Convergence (radial scene, h = 1/4 ... 1/128): L2, H1 and H1-seminorm errors
   against the exact solution, observed rates, the free-boundary radius
   sqrt(|contact set| / pi) against a*, and the KKT residuals of every run.
   ADMM (summable, zx, rho0 = 1) is run to a tight residual tolerance so that
   the discretisation error dominates.
2. Policy sweep (radial scene, h = 1/16): every registered policy x both
   orders x rho0 = 10^-4 ... 10^4 (half decades).  For each run: the
   iterations until the paper's rule (relative change 1e-5) fires with the
   relative error ||u - u_ref||_M / ||u_ref||_M at that point, and the
   iterations until that error is <= 1e-6 (an oracle stop against the cvxpy /
   Clarabel solution u_ref of the same discrete QP), capped at MAX_ITER.  The
   sweep runs on the sweep runner (:mod:`admmkit.benchmarks.runner.sweep`), one case per run,
   finished cases kept in ``sweep/results.jsonl`` under the output folder.

Writes convergence.{csv,md,png}, sweep.{csv,md,png} and radial.png / pyramid.png.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

import admmkit
from admmkit import RelativeChange, ResidualTolerance, solve

from admmkit.figures import pyplot, save_figure
from admmkit.io import write_text
from admmkit.problems.obstacle.plot import plot_solution
from admmkit.problems.obstacle import make_problem, solve_with_cvxpy
from admmkit.problems.obstacle.scene import A_STAR, pyramid, radial

from admmkit.benchmarks.obstacle import stops as obstacle_stops
from admmkit.benchmarks.runner.report import write_csv

MESHES = (16, 32, 64, 128, 256, 512)          # squares per side of (-2, 2)^2: h = 4/N
SWEEP_N = 64                                   # h = 1/16
RHOS = tuple(10.0 ** (k / 2) for k in range(-8, 9))
ORDERS = ("xz", "zx")
MAX_ITER = 10_000
ORACLE_TOL = 1e-6
TIGHT = dict(tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12)


def _rate(e_coarse: float, e_fine: float, h_coarse: float, h_fine: float) -> float:
    return math.log(e_coarse / e_fine) / math.log(h_coarse / h_fine)


def convergence(meshes=MESHES) -> list[dict]:
    """Errors, rates, free-boundary radius and KKT residuals on the radial scene, one row per mesh."""
    rows = []
    for N in meshes:
        t0 = time.perf_counter()
        p = make_problem(radial(h=4 / N))
        res = solve(p, rho=1.0, policy="summable", order="zx", stop=ResidualTolerance(1e-10, 1e-9), max_iter=20_000)
        err = p.errors(res.x)
        radius = p.contact_radius(res.x, tol=1e-8)
        r_max = p.contact_radius(res.x, tol=1e-8, method="max")
        row = dict(N=N, h=4 / N, n=p.n, status=str(res.status), iterations=res.iterations,
                   L2=err["L2"], H1=err["H1"], H1_semi=err["H1_semi"], radius=radius,
                   radius_error=abs(radius - A_STAR), radius_max=r_max, radius_max_error=abs(r_max - A_STAR),
                   **{f"kkt_{k}": v for k, v in res.kkt.items()})
        if rows:
            prev = rows[-1]
            for key in ("L2", "H1", "H1_semi", "radius_error"):
                row[f"rate_{key}"] = _rate(prev[key], row[key], prev["h"], row["h"])
        rows.append(row)
        print(f"  h = 4/{N:<4d} n = {p.n:7d}  {res.status} in {res.iterations:4d} it  L2 {err['L2']:.3e}  "
              f"H1 {err['H1']:.3e}  r {radius:.5f}  ({time.perf_counter() - t0:.1f} s)", flush=True)
    return rows


def sweep_cases(N: int = SWEEP_N, rhos=RHOS, policy_names=None, max_iter: int = MAX_ITER) -> list[dict]:
    """The sweep's cases: every policy x order x rho0 on the radial scene with h = 4/N (a policy's cases one group)."""
    return [{"target": "obstacle_sweep", "N": N, "policy": name, "order": order, "rho0": rho0, "max_iter": max_iter,
             "group": name}
            for name in policy_names or _one_rho_rules() for order in ORDERS for rho0 in rhos]


def _one_rho_rules() -> list[str]:
    """The registered rules with one rho (a rule with a penalty per row needs a QP: the obstacle takes one rho)."""
    from admmkit.benchmarks.fixtures.methods import per_row
    return [name for name in admmkit.policy_names() if not per_row(name)]


_SCENE: dict = {}


def run_case(case: dict) -> dict:
    """Worker entry point: one (policy, order, rho0) of the sweep; the scene and its reference are built once per
    worker process."""
    N, name, order, rho0, max_iter = case["N"], case["policy"], case["order"], case["rho0"], case["max_iter"]
    if _SCENE.get("N") != N:
        p = make_problem(radial(h=4 / N))
        u_ref, _ = solve_with_cvxpy(p, **TIGHT)
        _SCENE.update(N=N, p=p, u_ref=u_ref, ref_norm=p.norm(u_ref))
    p, u_ref, ref_norm = _SCENE["p"], _SCENE["u_ref"], _SCENE["ref_norm"]
    rel_err = lambda u: p.norm(u - u_ref) / ref_norm  # noqa: E731
    res = solve(p, rho=rho0, policy=name, order=order, stop=RelativeChange(1e-5), max_iter=max_iter)
    oracle = solve(p, rho=rho0, policy=name, order=order, stop=RelativeChange(1e-300),
                   max_iter=max_iter, callback=lambda rec: rel_err(rec.x) <= ORACLE_TOL)
    reached = str(oracle.status) == "stopped"
    return dict(policy=name, order=order, rho0=rho0, status=str(res.status),
                iterations=res.iterations, error_at_stop=rel_err(res.x),
                kkt_sign=res.kkt["sign"] if res.kkt else math.nan,
                kkt_complementarity=res.kkt["complementarity"] if res.kkt else math.nan,
                rho_final=res.rho, factorizations=res.counters.get("factorizations", 0),
                iterations_to_tol=oracle.iterations if reached else math.nan)


def sweep(N: int = SWEEP_N, rhos=RHOS, policy_names=None, max_iter: int = MAX_ITER, *, out: Path | None = None,
          executor=None, progress: bool = True, report_only: bool = False, harness: list | None = None) -> list[dict]:
    """Iterations of every policy x order x rho0 on the radial scene with h = 4/N, on the sweep runner
    (:mod:`admmkit.benchmarks.runner.sweep`: local processes or Dask, finished cases kept in ``out/results.jsonl``; a rerun
    resumes; ``report_only``: the finished cases only).  A case that failed in the harness is no row (no rule's
    result); its record goes into the list ``harness`` when one is given."""
    import tempfile

    from admmkit.benchmarks.runner.harness import is_harness_failure
    from admmkit.benchmarks.runner.sweep import Executor, case_id, run_or_report
    cases = sweep_cases(N, rhos, policy_names, max_iter)
    with tempfile.TemporaryDirectory() as scratch:
        folder = Path(out) if out is not None else Path(scratch)
        records, _ = run_or_report(cases, "admmkit.benchmarks.obstacle.study:run_case", folder,
                                   executor=executor or Executor(workers=1), progress=progress, table=False,
                                   report_only=report_only,
                                   label=lambda c: f"{c['policy']} {c['order']} rho0={c['rho0']:.0e}")
    rows = []
    for c in (c for c in cases if case_id(c) in records):
        rec = records[case_id(c)]
        if is_harness_failure(rec):
            if harness is not None:
                harness.append(rec)
            continue
        rows.append(rec["result"] if rec.get("result") is not None else
                    dict(policy=c["policy"], order=c["order"], rho0=c["rho0"], status="error: " + rec["error"][:60],
                         iterations=max_iter, error_at_stop=math.nan, kkt_sign=math.nan, kkt_complementarity=math.nan,
                         rho_final=math.nan, factorizations=0, iterations_to_tol=math.nan))
    return rows


# ---------------------------------------------------------------- output
def _fmt(v, spec=".3e") -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    return format(v, spec) if isinstance(v, float) else str(v)


def convergence_markdown(rows: list[dict]) -> str:
    """Markdown table of errors and observed rates."""
    lines = ["| h | free nodes | iterations | L2 error | rate | H1 error | rate | H1-semi error | rate "
             "| r_area | abs(r_area - a*) | rate | r_max | abs(r_max - a*) | KKT primal | KKT dual/m | KKT sign "
             "| KKT compl. |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(" | ".join([
            f"| 1/{round(1 / r['h'])}", str(r["n"]), str(r["iterations"]),
            _fmt(r["L2"]), _fmt(r.get("rate_L2"), ".2f"), _fmt(r["H1"]), _fmt(r.get("rate_H1"), ".2f"),
            _fmt(r["H1_semi"]), _fmt(r.get("rate_H1_semi"), ".2f"), _fmt(r["radius"], ".5f"),
            _fmt(r["radius_error"]), _fmt(r.get("rate_radius_error"), ".2f"),
            _fmt(r["radius_max"], ".5f"), _fmt(r["radius_max_error"]),
            _fmt(r["kkt_primal"], ".1e"), _fmt(r["kkt_dual_density"], ".1e"), _fmt(r["kkt_sign"], ".1e"),
            _fmt(r["kkt_complementarity"], ".1e")]) + " |")
    return "\n".join(lines) + "\n"


def sweep_markdown(rows: list[dict]) -> str:
    """Two Markdown tables: iterations (paper's rule) and iterations to error 1e-6, rows = policy/order."""
    rhos = sorted({r["rho0"] for r in rows})
    head = "| policy | order | " + " | ".join(f"{x:.0e}" for x in rhos) + " |\n" + "|---|---|" + "---|" * len(rhos)
    out = []
    for title, key in [("Iterations until the paper's rule (relative change 1e-5) fires "
                        "(* = status not converged; the error at the stop in sweep.csv)", "iterations"),
                       (f"Iterations until ||u - u_ref||_M <= {ORACLE_TOL:g} ||u_ref||_M "
                        f"(- = not reached in {MAX_ITER})", "iterations_to_tol")]:
        out += [f"**{title}**", "", head]
        for (name, order) in dict.fromkeys((r["policy"], r["order"]) for r in rows):
            cells = []
            for rho in rhos:
                (r,) = [r for r in rows if r["policy"] == name and r["order"] == order and r["rho0"] == rho]
                v = r[key]
                cell = "-" if isinstance(v, float) and math.isnan(v) else str(int(v))
                if key == "iterations" and r["status"] != "converged":
                    cell += "*"
                cells.append(cell)
            out.append(f"| {name} | {order} | " + " | ".join(cells) + " |")
        out.append("")
    return "\n".join(out)


def plot_convergence(rows: list[dict], path: Path) -> Path:
    """Log-log plot of the errors against h with reference slopes."""
    plt = pyplot()
    h = np.array([r["h"] for r in rows])
    fig, ax = plt.subplots(figsize=(6, 4.5))
    for key, style in [("L2", "o-"), ("H1", "s-"), ("H1_semi", "^--"), ("radius_error", "d:")]:
        label = {"radius_error": "|r_area - a*|", "H1_semi": "H1 seminorm"}.get(key, key)
        ax.loglog(h, [r[key] for r in rows], style, label=label)
    for p, e0 in [(1, rows[0]["H1"]), (2, rows[0]["L2"])]:
        ax.loglog(h, e0 * 0.6 * (h / h[0]) ** p, "k-", lw=0.6, alpha=0.6)
        ax.text(h[-1], e0 * 0.6 * (h[-1] / h[0]) ** p, f" O(h^{p})", fontsize=8, va="center")
    ax.set_xlabel("h"); ax.set_ylabel("error"); ax.grid(True, which="both", alpha=0.3)
    ax.set_title("radial obstacle, P1: errors against the exact solution"); ax.legend()
    fig.tight_layout()
    return save_figure(fig, path, ("png",), dpi=120)[0]


def plot_sweep(rows: list[dict], path: Path) -> Path:
    """Iterations against rho0 for every policy/order, for both stopping criteria."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5), sharey=True)
    for ax, key, title in [(axes[0], "iterations", "paper's rule: relative change 1e-5"),
                           (axes[1], "iterations_to_tol", f"until relative error <= {ORACLE_TOL:g}")]:
        for (name, order) in dict.fromkeys((r["policy"], r["order"]) for r in rows):
            sel = [r for r in rows if r["policy"] == name and r["order"] == order]
            y = [MAX_ITER if (isinstance(r[key], float) and math.isnan(r[key])) else r[key] for r in sel]
            ax.loglog([r["rho0"] for r in sel], y, "o-" if order == "zx" else "s--", ms=4, label=f"{name} {order}")
        ax.axhline(MAX_ITER, color="k", lw=0.6, ls=":")
        ax.set_xlabel("rho0"); ax.set_title(title); ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("iterations"); axes[1].legend(fontsize=8)
    fig.suptitle(f"radial obstacle, h = 1/{SWEEP_N // 4}: iterations across rho0 (cap {MAX_ITER})")
    fig.tight_layout()
    return save_figure(fig, path, ("png",), dpi=120)[0]


def run(out="out/obstacle", *, quick: bool = False, command: str = "admmkit bench obstacle", executor=None,
        progress: bool = True, report_only: bool = False) -> int:
    """Run both studies and write the tables and plots to ``out`` (the sweep's cases on ``executor``, default
    one local process).  ``report_only``: run nothing; rewrite the sweep's files from its finished cases."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    meshes, rhos, n_sweep = (MESHES[:3], RHOS[::4], 16) if quick else (MESHES, RHOS, SWEEP_N)

    if not report_only:
        print("convergence study (radial, summable zx, rho0 = 1):", flush=True)
        rows = convergence(meshes)
        write_csv(out / "convergence.csv", rows)
        write_text(out / "convergence.md", convergence_markdown(rows) + f"\nMade by `{command}`.\n")
        plot_convergence(rows, out / "convergence.png")
        obstacle_stops.run(out, meshes[:-1] if len(meshes) > 3 else meshes, command)

    print(f"policy sweep (radial, h = 4/{n_sweep}):", flush=True)
    failed: list[dict] = []
    srows = sweep(n_sweep, rhos, out=out / "sweep", executor=executor, progress=progress, report_only=report_only,
                  harness=failed)
    from admmkit.benchmarks.runner.harness import check_harness, check_something_left
    check_something_left(srows, failed, len(failed) + len(srows), out / "sweep" / "results.jsonl", report_only)
    write_csv(out / "sweep.csv", srows)
    write_text(out / "sweep.md", sweep_markdown(srows) + f"\nMade by `{command}`.\n")
    plot_sweep(srows, out / "sweep.png")

    if not report_only:
        for sc in (radial(h=1 / 16), pyramid(h=1 / 64)):
            p = make_problem(sc)
            res = solve(p, rho=1.0, policy="summable", order="zx", stop=ResidualTolerance(1e-10, 1e-9))
            plot_solution(p, res.x, res.x, out / f"{sc.name}.png")
    print(f"wrote {', '.join(sorted(f.name for f in out.iterdir()))} to {out}")
    check_harness(failed, len(failed) + len(srows), left_out="left out of the sweep's tables")
    return 0
