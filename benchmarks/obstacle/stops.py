"""When to stop ADMM on the radial obstacle: at an algebraic tolerance, or balanced with the discretisation error.

For each mesh (h = 4/N) three stops of the same method (summable, order zx,
rho_0 = 1):

- ``relative change 1e-5``: the paper's rule (the old default of ``solve obstacle``);
- ``residuals 1e-10``: Boyd's residuals at 1e-10 / 1e-9 (a tight algebraic stop);
- ``balanced 0.1``: :class:`admmkit.problems.obstacle.estimate.BalancedStop`, a
  guaranteed bound of the algebraic error below 0.1 x the ZZ estimate of the
  discretisation error (the new default).

Each row: iterations, seconds, the H1-seminorm and L2 errors of the returned z
against the exact solution, the true algebraic error ||z - u_h||_a against
the tight run, the bound and the estimate where the stop computes them.
Each run gets a freshly built problem, so no run finds factorisations an
earlier one cached; the stop's own set-up (the factorisation of K for the
bound, the estimator's mesh data) is made before the clock starts.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from admmkit import RelativeChange, ResidualTolerance, solve
from admmkit.figures import pyplot, save_figure
from admmkit.io import write_text
from admmkit.problems.obstacle.estimate import BalancedStop
from admmkit.problems.obstacle import make_problem
from admmkit.problems.obstacle.scene import radial

from admmkit.benchmarks.runner.report import fmt, md_table, write_csv

STOPS = ("relative change 1e-5", "residuals 1e-10", "balanced 0.1")


def _stop(name: str, problem):
    return {"relative change 1e-5": lambda: RelativeChange(1e-5),
            "residuals 1e-10": lambda: ResidualTolerance(1e-10, 1e-9),
            "balanced 0.1": lambda: BalancedStop(problem, 0.1)}[name]()


def stops(meshes) -> list[dict]:
    """One row per (mesh, stop)."""
    rows = []
    for N in meshes:
        runs = {}
        for name in STOPS:
            problem = make_problem(radial(h=4 / N))     # anew: no run finds another's cached factorisations
            stop = _stop(name, problem)
            t0 = time.perf_counter()
            res = solve(problem, rho=1.0, policy="summable", order="zx", stop=stop, max_iter=20_000)
            runs[name] = (res, time.perf_counter() - t0, stop)
        u_h = runs["residuals 1e-10"][0].z
        for name, (res, seconds, stop) in runs.items():
            d = res.z - u_h
            err = problem.errors(res.z)
            rows.append({"N": N, "h": 4 / N, "n": problem.n, "stop": name, "status": res.status.value,
                         "iterations": res.iterations, "seconds": seconds, "H1_semi": err["H1_semi"], "L2": err["L2"],
                         "algebraic_true": float(np.sqrt(d @ (problem.K @ d))),
                         "algebraic_bound": getattr(stop, "algebraic", float("nan")),
                         "discretisation_estimate": getattr(stop, "discretisation", float("nan"))})
            r = rows[-1]
            print(f"  h = 4/{N:<4d} {name:22s} {r['status']:20s} {r['iterations']:5d} it  {seconds:7.2f} s  "
                  f"H1 {r['H1_semi']:.3e}  L2 {r['L2']:.3e}  algebraic {r['algebraic_true']:.1e}", flush=True)
    return rows


def markdown(rows: list[dict]) -> str:
    """The table of every (mesh, stop)."""
    body = [[f"1/{round(1 / r['h'])}", r["n"], r["stop"], r["status"], r["iterations"], fmt(r["seconds"], ".2f"),
             fmt(r["H1_semi"], ".3e"), fmt(r["L2"], ".3e"), fmt(r["algebraic_true"], ".1e"),
             fmt(r["algebraic_bound"], ".1e"), fmt(r["discretisation_estimate"], ".3e")] for r in rows]
    return md_table(["h", "free nodes", "stop", "status", "iterations", "seconds", "H1-semi error", "L2 error",
                     "true algebraic error", "its bound", "ZZ estimate"], body)


def plot(rows: list[dict], path: Path) -> Path:
    """Errors against h (left) and iterations against h (right), one line per stop."""
    plt = pyplot()
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 4))
    for name, marker, colour in zip(STOPS, "osd", ("C0", "C1", "C2")):
        sub = [r for r in rows if r["stop"] == name]
        h = [r["h"] for r in sub]
        ax.loglog(h, [r["L2"] for r in sub], marker + "-", color=colour, label=f"L2, {name}")
        ax.loglog(h, [r["H1_semi"] for r in sub], marker + ":", color=colour, mfc="none", label=f"H1 semi, {name}")
        bx.loglog(h, [r["iterations"] for r in sub], marker + "-", color=colour, label=name)
    ax.set_xlabel("h"); ax.set_ylabel("error against the exact solution"); ax.legend(fontsize=7)
    bx.set_xlabel("h"); bx.set_ylabel("ADMM iterations"); bx.legend(fontsize=8)
    for a in (ax, bx):
        a.grid(True, which="both", alpha=0.3)
        a.xaxis.set_minor_formatter(plt.NullFormatter())
    fig.suptitle("radial obstacle: where to stop ADMM (summable, zx, rho_0 = 1)")
    fig.tight_layout()
    return save_figure(fig, path, ("png",), dpi=120)[0]


def run(out: Path, meshes, command: str) -> list[Path]:
    """Run the study and write stops.csv, stops.md and stops.png to ``out``."""
    print("stopping rules (radial, summable zx, rho0 = 1):", flush=True)
    rows = stops(meshes)
    write_csv(out / "stops.csv", rows)
    write_text(out / "stops.md", "# Where to stop ADMM on the radial obstacle\n\n" + markdown(rows)
               + f"\n\nMade by `{command}`.\n")
    return [out / "stops.csv", out / "stops.md", plot(rows, out / "stops.png")]
