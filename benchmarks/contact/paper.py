"""Reproduce the paper's section 4: both examples x ADMM1/ADMM2/SADMM x rho x h.

    admmkit reproduce paper [--out DIR] [--quick]      (default DIR: ./out/paper/)

For each example and mesh size the operators are assembled once; every run
(method, rho) then builds a fresh contact problem and solves it with the
paper's stopping rule ||u^{k+1} - u^k||_K <= 1e-5 ||u^{k+1}||_K (the default of
:func:`admmkit.problems.contact.solve_scene`).  The time reported for a run is
problem setup + solve (wall clock, ``time.perf_counter``): for the condensed
mode the setup contains the sparse factorisation of K and the boundary Schur
complement, so every run pays it.

Written to ``out``: CPU-time tables shaped like the paper's Tables 1 and 2 with
the paper's figures beside ours (:mod:`admmkit.benchmarks.contact.paper_tables`, from the data
file ``benchmarks/contact/data/paper_tables.json``), iteration tables, the true error
at the stop against a tight reference solution of the same discrete problem
(:mod:`admmkit.problems.contact.validation.reference`), the figures (the paper's Figs 1-4 and the
contact pressure / gap along Gamma_C) and a README.md saying what each file is.

The reference is cvxpy + Clarabel, as in the committed results (docs/results/paper).  The reproduction
never puts a weaker one in its place: without cvxpy or Clarabel it refuses before any work, and if
Clarabel does not solve a mesh (the reference falls back to a tight SADMM run) it stops before writing
anything, so the files already in ``out`` stay as they were (:class:`WeakReference`).
"""
from __future__ import annotations

import math
import statistics
import sys
import time
from pathlib import Path

from admmkit.figures import pyplot, save_figure
from admmkit.policies.paper_methods import LABELS as METHOD_LABELS
from admmkit.problems.contact.model.assembly import assemble
from admmkit.problems.contact.solvers.methods import solve_scene
from admmkit.problems.contact.output.plot import figure_deformed, figure_pressure_gap
from admmkit.problems.contact.validation.reference import errors_against, reference_solution
from admmkit.problems.contact.model.scene import example1, example2

from admmkit.benchmarks.contact.paper_data import MAGNIFY, METHOD_NAMES, PAPER_HS, PAPER_RHOS, Run
from admmkit.benchmarks.runner.harness import require
from admmkit.benchmarks.runner.report import h_label, rho_label

EXAMPLES = {"ex1": example1, "ex2": example2}
#: the reference solver of the paper's error table (``Reference.solver`` starts with it)
REFERENCE_SOLVER = "cvxpy + Clarabel"


class WeakReference(ValueError):
    """A mesh's reference is not cvxpy + Clarabel: the reproduction stops before writing anything."""
def _timed_run(ops, method, rho, mode, repeats):
    sols, walls, cpus = [], [], []
    for _ in range(max(1, repeats)):
        c0, t0 = time.process_time(), time.perf_counter()
        sol = solve_scene(ops, method, rho, mode=mode)   # contact_problem(ops, mode) + admmkit.solve
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
        sols.append(sol)
    return sols[-1], statistics.median(walls), statistics.median(cpus), \
        statistics.median(s.setup_time for s in sols), statistics.median(s.result.timings["total"] for s in sols)


def run_reproduction(out="out/paper", hs=PAPER_HS, rhos=PAPER_RHOS, repeats: int = 1,
                     progress: bool = True, examples=("ex1", "ex2"), methods=METHOD_NAMES,
                     mode: str = "auto", command: str | None = None, blas_threads: int | None = 1) -> dict:
    """Run every (example, h, method, rho), write the tables, figures and README into ``out``.

    BLAS is pinned to ``blas_threads`` threads for the whole reproduction (setup included;
    admmkit.solve pins it inside the loop anyway); None leaves it alone.
    Returns {"runs": [Run, ...], "references": {(example, h): Reference}, "files": [Path],
    "wall_time": seconds}.
    """
    from contextlib import nullcontext

    from threadpoolctl import threadpool_limits
    require("reproduce paper", "cvxpy", "clarabel")          # the reference solver, before any work
    with threadpool_limits(blas_threads, user_api="blas") if blas_threads else nullcontext():
        return _run_reproduction(out, hs, rhos, repeats, progress, examples, methods, mode, command, blas_threads)


def _run_reproduction(out, hs, rhos, repeats, progress, examples, methods, mode, command, blas_threads) -> dict:
    from admmkit.benchmarks.contact.paper_tables import write_error_table, write_iteration_table, write_readme, write_time_table

    start = time.perf_counter()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    hs, rhos = tuple(float(h) for h in hs), tuple(float(r) for r in rhos)
    total = len(examples) * len(hs) * len(methods) * len(rhos)
    runs: list[Run] = []
    refs: dict = {}
    keep: dict = {}  # solutions for the figures: (example, h, method, rho) -> (ops, sol)
    h_fig, h_fine = min(hs, key=lambda h: abs(math.log(h * 20))), min(hs)
    rho_fig = min(rhos, key=lambda r: abs(math.log10(r) - 3))
    k = 0
    for ex in examples:
        for h in hs:
            ops = assemble(EXAMPLES[ex](h))
            ref = reference_solution(ops)
            if not ref.solver.startswith(REFERENCE_SOLVER):
                raise WeakReference(f"reproduce paper: the reference of {ex} h={h_label(h)} is {ref.solver!r}, not "
                                    f"{REFERENCE_SOLVER} (Clarabel failed or is missing); nothing written, the "
                                    f"files in {out} are kept")
            refs[(ex, h)] = ref
            if progress:
                print(f"[{ex} h={h_label(h)}] n_free {ops.n_free}, n_c {ops.n_c}; reference ({ref.solver}) "
                      f"{ref.seconds:.2f} s, cross-check {ref.cross_check.get('u_energy_rel_diff', float('nan')):.1e}",
                      file=sys.stderr, flush=True)
            for m in methods:
                for rho in rhos:
                    sol, wall, cpu, setup, solve_t = _timed_run(ops, m, rho, mode, repeats)
                    r = sol.result
                    run = Run(example=ex, h=h, method=m, rho=rho, iterations=r.iterations, status=r.status.value,
                              time=wall, cpu_time=cpu, setup_time=setup, solve_time=solve_t, mode=sol.mode,
                              factorizations=r.factorizations, rho_changes=r.rho_changes, final_rho=r.rho,
                              kkt=dict(r.kkt or {}), errors=errors_against(ops, ref, r.x, r.lam),
                              n_free=ops.n_free, n_c=ops.n_c)
                    runs.append(run)
                    if m == "sadmm" and rho == rho_fig and h == h_fine:
                        keep[ex] = (ops, sol)
                    k += 1
                    if progress:
                        print(f"{k}/{total}  {ex} h={h_label(h):5s} {m:6s} rho={rho_label(rho):4s} "
                              f"{r.iterations:6d} it  {r.status.value:9s} {wall:8.3f} s  "
                              f"err_u {run.errors['err_u_energy']:.1e}", file=sys.stderr, flush=True)
    files: list[Path] = []
    names = {"ex1": ("table1_ex1_time", "iterations_ex1", "fig2_iterations_ex1", "fig1_deformed_ex1"),
             "ex2": ("table2_ex2_time", "iterations_ex2", "fig4_iterations_ex2", "fig3_deformed_ex2")}
    for ex in examples:
        t_name, i_name, f_it, f_def = names[ex]
        files += write_time_table(out / t_name, runs, ex, hs, rhos, methods)
        files += write_iteration_table(out / i_name, runs, ex, hs, rhos, methods)
        files += figure_iterations(runs, ex, h_fig, rhos, out / f"{f_it}.png")
        if ex in keep:
            ops, sol = keep[ex]
            label = "Example 1" if ex == "ex1" else "Example 2"
            files += figure_deformed(ops, sol.u, MAGNIFY[ex],
                                     f"{label}: deformed body (u x{MAGNIFY[ex]:g}), SADMM, h = {h_label(h_fine)}",
                                     out / f"{f_def}.png")
            files += figure_pressure_gap(ops, sol.u, sol.pressure,
                                         f"{label}: contact pressure and gap on Gamma_C, SADMM rho_0 = "
                                         f"{rho_label(rho_fig)}, h = {h_label(h_fine)}",
                                         out / f"pressure_gap_{ex}.png", p=sol.result.z)
    files += write_error_table(out / "error_at_stop", runs, refs)
    wall = time.perf_counter() - start
    readme = write_readme(out, runs, refs, files, wall, hs, rhos, h_fig, h_fine, rho_fig, repeats, mode,
                          command or _default_command(out, hs), blas_threads)
    files.append(readme)
    if progress:
        print(f"done: {len(runs)} runs in {wall:.1f} s; results in {out}", file=sys.stderr)
    return {"runs": runs, "references": refs, "files": files, "wall_time": wall}


def _default_command(out, hs) -> str:
    quick = " --quick" if tuple(hs) == (1 / 10, 1 / 20) else ""
    return f"admmkit reproduce paper --out {out}{quick}"


def figure_iterations(runs, example, h, rhos, path, svg=True):
    """Iterations against rho (log x) at mesh size h, one curve per method: the paper's Figs 2 / 4."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    styles = {"admm1": dict(marker="s", ls="-"), "admm2": dict(marker="^", ls="--", mfc="none"),
              "sadmm": dict(marker="o", ls="-")}
    flagged = {}
    for m in METHOD_NAMES:
        pts = [(r.rho, r.iterations, r.status) for r in runs if r.example == example and r.h == h and r.method == m]
        if not pts:
            continue
        pts.sort()
        ax.plot([p[0] for p in pts], [p[1] for p in pts], label=METHOD_LABELS[m], **styles[m])
        for rho, it, st in pts:
            if st != "converged":
                flagged.setdefault(st, []).append((rho, it))
    for (st, pts), colour in zip(sorted(flagged.items()), ("red", "purple", "black")):
        ax.plot([p[0] for p in pts], [p[1] for p in pts], "o", ms=11, mfc="none", mec=colour, mew=1.2,
                label=st + (" (the rule fired; KKT > 10x its tolerance)" if st == "converged_inaccurate" else ""))
    ax.set_xscale("log"); ax.set_yscale("log")
    ax.set_xlabel("initial penalty rho"); ax.set_ylabel("iterations")
    ax.set_title(f"{'Example 1' if example == 'ex1' else 'Example 2'}: iterations, h = {h_label(h)}")
    ax.grid(alpha=0.3, which="both"); ax.legend(fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path, ("png", "svg") if svg else ("png",))
