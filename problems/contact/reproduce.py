"""Reproduce the paper's section 4: both examples x ADMM1/ADMM2/SADMM x rho x h.

    admmkit reproduce paper [--out docs/results/paper] [--quick]
    python -m problems.contact.reproduce [--out DIR] [--quick]

For each example and mesh size the operators are assembled once; every run
(method, rho) then builds a fresh contact problem and solves it with the
paper's stopping rule ||u^{k+1} - u^k||_K <= 1e-5 ||u^{k+1}||_K (the default of
:func:`problems.contact.solve_scene`).  The time reported for a run is
problem setup + solve (wall clock, ``time.perf_counter``): for the condensed
mode the setup contains the sparse factorisation of K and the boundary Schur
complement, so every run pays it.

Written to ``out``: CPU-time tables shaped like the paper's Tables 1 and 2 with
the paper's figures beside ours, iteration tables, the true error at the stop
against a tight reference solution of the same discrete problem, the figures
(the paper's Figs 1-4 and the contact pressure / gap along Gamma_C) and a
README.md saying what each file is.
"""
from __future__ import annotations

import argparse
import csv
import datetime
import math
import statistics
import sys
import time
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

import numpy as np

import admmkit

from problems.machine import machine_info  # noqa: F401  (the benchmarks of this plug-in import it from here)

from .assembly import ContactOperators, assemble
from .methods import solve_scene
from .problem import contact_problem
from .scene import example1, example2

EXAMPLES = {"ex1": example1, "ex2": example2}
METHOD_NAMES = ("admm1", "admm2", "sadmm")
METHOD_LABELS = {"admm1": "ADMM1", "admm2": "ADMM2", "sadmm": "SADMM"}
PAPER_HS = (1 / 10, 1 / 20, 1 / 30, 1 / 40)
PAPER_RHOS = (1.0, 10.0, 1e2, 1e3, 1e4)
#: displacement magnification of the paper's Figs 1 and 3
MAGNIFY = {"ex1": 10.0, "ex2": 20.0}

# CPU seconds reported by Yuan & Zhang (2023), FreeFEM++ on the authors' machine.
# Copied from the seed text /work/shared/seed/000_6d67a5c7a641af74.txt, section 4,
# Table 1 (example 1, g = 0.01) and Table 2 (example 2).
# PAPER_TIMES[example][method][rho] = (h = 1/10, 1/20, 1/30, 1/40)
PAPER_TIMES = {
    "ex1": {
        "admm1": {1.0: (3.080, 9.305, 29.344, 37.788), 10.0: (2.670, 8.665, 34.726, 37.629),
                  1e2: (0.611, 2.890, 6.224, 10.178), 1e3: (0.229, 0.896, 1.842, 3.765),
                  1e4: (0.306, 1.223, 2.905, 5.742)},
        "admm2": {1.0: (5.213, 12.865, 24.283, 41.639), 10.0: (5.137, 12.331, 23.814, 40.909),
                  1e2: (1.474, 4.169, 7.156, 11.393), 1e3: (0.577, 1.223, 1.978, 3.943),
                  1e4: (0.502, 1.228, 2.479, 4.286)},
        "sadmm": {1.0: (0.562, 1.171, 2.617, 4.214), 10.0: (0.454, 1.135, 2.342, 3.891),
                  1e2: (0.610, 0.984, 2.145, 3.632), 1e3: (0.425, 0.650, 1.321, 2.516),
                  1e4: (0.409, 0.743, 1.496, 2.699)},
    },
    "ex2": {
        "admm1": {1.0: (4.114, 13.733, 35.051, 54.791), 10.0: (3.827, 13.505, 39.201, 65.841),
                  1e2: (1.565, 5.294, 16.247, 26.196), 1e3: (0.933, 2.552, 7.530, 12.051),
                  1e4: (0.699, 2.059, 6.003, 10.109)},
        "admm2": {1.0: (4.008, 13.227, 30.753, 53.383), 10.0: (3.792, 12.91, 29.465, 52.564),
                  1e2: (1.256, 5.132, 12.322, 22.394), 1e3: (0.872, 2.386, 5.276, 8.389),
                  1e4: (0.384, 1.306, 3.059, 5.449)},
        "sadmm": {1.0: (0.378, 1.313, 3.129, 7.029), 10.0: (0.381, 1.227, 2.982, 6.649),
                  1e2: (0.314, 1.116, 2.645, 5.985), 1e3: (0.238, 0.786, 1.932, 5.017),
                  1e4: (0.315, 0.948, 2.313, 3.849)},
    },
}


def paper_time(example: str, method: str, rho: float, h: float) -> float | None:
    """The paper's CPU seconds for this run, or None if the paper has no such entry."""
    row = PAPER_TIMES.get(example, {}).get(method, {}).get(float(rho))
    if row is None:
        return None
    for hp, value in zip(PAPER_HS, row):
        if math.isclose(h, hp, rel_tol=1e-9):
            return value
    return None


def h_label(h: float) -> str:
    """1/40 for 0.025, else the number."""
    frac = Fraction(h).limit_denominator(10_000)
    if frac.numerator == 1 and math.isclose(float(frac), h, rel_tol=1e-12):
        return f"1/{frac.denominator}"
    return f"{h:g}"


def rho_label(rho: float) -> str:
    """1, 10, 1e2, 1e3, ..."""
    if rho > 0 and math.isclose(math.log10(rho), round(math.log10(rho)), abs_tol=1e-12):
        e = round(math.log10(rho))
        return "1" if e == 0 else "10" if e == 1 else f"1e{e}"
    return f"{rho:g}"


# ---------------------------------------------------------------- reference solution
@dataclass
class Reference:
    """A tight solution of the discrete problem min 1/2 u'Ku - f'u s.t. Bu <= g."""

    u: np.ndarray
    lam: np.ndarray
    solver: str
    kkt: dict
    seconds: float
    cross_check: dict = field(default_factory=dict)


def energy_norm(ops: ContactOperators, v: np.ndarray) -> float:
    """sqrt(v'Kv)."""
    return float(np.sqrt(max(v @ (ops.K @ v), 0.0)))


def reference_solution(ops: ContactOperators, tol: float = 1e-10) -> Reference:
    """Solve the discrete QP tightly, cross-checked by a second solver.

    Primary: cvxpy + Clarabel (interior point) at gap/feasibility tolerance ``tol``;
    lam = (dual of Bu <= g) / M_c.  Cross-check: SADMM (rho = 1e3) run until Boyd's
    residuals are below 1e-12.  If Clarabel is unavailable or does not report
    "optimal", the SADMM solution is the reference.  ``cross_check`` holds the
    relative energy-norm and pressure differences between the two.
    """
    t0 = time.perf_counter()
    tight = solve_scene(ops, "sadmm", 1e3, stop=admmkit.ResidualTolerance(1e-12, 1e-12), max_iter=200_000)
    t_admm = time.perf_counter() - t0
    admm = (tight.result.x, tight.result.lam)
    checker = contact_problem(ops, mode="full")
    primary = None
    try:
        import cvxpy as cp
        t0 = time.perf_counter()
        u = cp.Variable(ops.n_free)
        constraint = ops.B @ u <= ops.g
        prob = cp.Problem(cp.Minimize(0.5 * cp.quad_form(u, cp.psd_wrap(ops.K)) - ops.f @ u), [constraint])
        prob.solve(solver=cp.CLARABEL, tol_gap_abs=tol, tol_gap_rel=tol, tol_feas=tol, max_iter=500)
        t_ipm = time.perf_counter() - t0
        if prob.status == "optimal":
            primary = (np.asarray(u.value), np.asarray(constraint.dual_value) / ops.mc, t_ipm)
    except Exception:  # cvxpy/clarabel missing or failing: fall back to the tight ADMM run
        primary = None
    kkt_of = lambda uu, ll: checker.kkt(uu, np.minimum(ops.g, ops.B @ uu), ll)  # noqa: E731
    if primary is None:
        return Reference(admm[0], admm[1], "sadmm, ResidualTolerance(1e-12, 1e-12)", kkt_of(*admm), t_admm)
    u_ref, lam_ref, t_ipm = primary
    lam_norm = math.sqrt(max(float(ops.mc @ lam_ref**2), 1e-300))
    cross = {
        "other": "sadmm, ResidualTolerance(1e-12, 1e-12)",
        "u_energy_rel_diff": energy_norm(ops, admm[0] - u_ref) / energy_norm(ops, u_ref),
        "lam_rel_diff": math.sqrt(float(ops.mc @ (admm[1] - lam_ref) ** 2)) / lam_norm,
    }
    return Reference(u_ref, lam_ref, f"cvxpy + Clarabel, tol {tol:g}", kkt_of(u_ref, lam_ref), t_ipm, cross)


def errors_against(ops: ContactOperators, ref: Reference, u: np.ndarray, lam: np.ndarray) -> dict:
    """Relative energy-norm error of u and relative M_c-norm error of lam."""
    lam_norm = math.sqrt(max(float(ops.mc @ ref.lam**2), 1e-300))
    return {"err_u_energy": energy_norm(ops, u - ref.u) / energy_norm(ops, ref.u),
            "err_lam": math.sqrt(float(ops.mc @ (lam - ref.lam) ** 2)) / lam_norm}


# ---------------------------------------------------------------- plots
def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def vertex_displacement(ops: ContactOperators, u_free: np.ndarray):
    """(points (nv, 2), triangles (nt, 3), displacement at the vertices (nv, 2)).

    VectorH1 numbers all x-component dofs first, then all y; in each component
    the first nv dofs belong to the vertices (P1 nodal values; for P2 the edge
    bubbles vanish at the vertices), so the vertex values are read off the dofs.
    """
    import ngsolve as ng
    mesh = ops.mesh
    points = np.array([v.point[:2] for v in mesh.vertices])
    triangles = np.array([[v.nr for v in el.vertices] for el in mesh.Elements(ng.VOL)])
    full = ops.full_vector(u_free)
    nv, half = mesh.nv, ops.fes.ndof // 2
    return points, triangles, np.column_stack([full[:nv], full[half:half + nv]])


def plot_deformed(ax, ops: ContactOperators, u_free: np.ndarray, magnify: float, title: str = ""):
    """The deformed triangulation (coloured by |u|), the undeformed outline and the obstacle."""
    import matplotlib.tri as mtri
    points, triangles, disp = vertex_displacement(ops, u_free)
    moved = points + magnify * disp
    tri = mtri.Triangulation(moved[:, 0], moved[:, 1], triangles)
    pc = ax.tripcolor(tri, np.linalg.norm(disp, axis=1), shading="gouraud", cmap="viridis")
    ax.triplot(tri, color="k", lw=0.25, alpha=0.5)
    L, H = ops.scene.L, ops.scene.H
    ax.plot([0, L, L, 0, 0], [0, 0, H, H, 0], "k--", lw=0.8, label="undeformed body")
    x = np.linspace(-0.05 * L, 1.05 * L, 400)
    g = np.array([ops.scene.gap_at(xi, 0.0) for xi in x])
    ax.plot(x, -magnify * g, "r-", lw=1.6, label=f"obstacle y = -g(x) (x{magnify:g}, like u)")
    ax.fill_between(x, -magnify * g, -magnify * g.max() - 0.08 * H, color="r", alpha=0.12, lw=0)
    ax.set_aspect("equal")
    ax.set_xlabel("x"); ax.set_ylabel("y")
    ax.set_title(title or f"deformed body, displacement x{magnify:g}")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2, fontsize=8, frameon=False)
    return pc


def plot_pressure_gap(axes, ops: ContactOperators, u_free: np.ndarray, lam: np.ndarray):
    """lam and the gap g - u_n along Gamma_C against x (two axes)."""
    x = ops.xc[:, 0]
    un = ops.B @ u_free
    gap = ops.g - un
    active = gap <= 1e-4 * max(float(np.abs(ops.g).max()), 1e-300)  # the stop leaves gaps ~1e-7 g
    ax1, ax2 = axes
    ax1.plot(x, lam, "b.-", ms=3, label="contact pressure lam")
    ax1.plot(x[active], lam[active], "o", mfc="none", mec="r", ms=5, label="in contact (g - u_n <= 1e-4 max g)")
    ax1.set_ylabel("lam"); ax1.legend(fontsize=8); ax1.grid(alpha=0.3)
    ax2.plot(x, gap, "g.-", ms=3, label="gap g - u_n")
    ax2.plot(x, ops.g, "k--", lw=0.8, label="initial gap g")
    ax2.axhline(0, color="k", lw=0.5)
    ax2.set_ylabel("g - u_n"); ax2.set_xlabel("x on Gamma_C (y = 0)"); ax2.legend(fontsize=8); ax2.grid(alpha=0.3)


def save(fig, path: Path, svg: bool = True) -> list[Path]:
    """Write fig as PNG (and SVG); close it."""
    path = Path(path)
    fig.savefig(path, dpi=130)
    written = [path]
    if svg:
        fig.savefig(path.with_suffix(".svg"))
        written.append(path.with_suffix(".svg"))
    _pyplot().close(fig)
    return written


def figure_deformed(ops, u, magnify, title, path, svg=True):
    """The paper's Figs 1 / 3."""
    plt = _pyplot()
    L, H = ops.scene.L, ops.scene.H
    fig, ax = plt.subplots(figsize=(min(3.6 * L / H + 1.5, 13), 5.0))
    pc = plot_deformed(ax, ops, u, magnify, title)
    fig.colorbar(pc, ax=ax, label="|u|", fraction=0.025, pad=0.02)
    fig.tight_layout()
    return save(fig, path, svg)


def figure_pressure_gap(ops, u, lam, title, path, svg=True):
    """lam and g - u_n along Gamma_C."""
    plt = _pyplot()
    fig, axes = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    plot_pressure_gap(axes, ops, u, lam)
    axes[0].set_title(title)
    fig.tight_layout()
    return save(fig, path, svg)


def figure_solution(ops, u, lam, magnify, title, path):
    """Deformed body over pressure/gap in one PNG (the CLI's --plot)."""
    plt = _pyplot()
    fig = plt.figure(figsize=(9, 8.5))
    gs = fig.add_gridspec(3, 1, height_ratios=[2.2, 1, 1])
    ax0 = fig.add_subplot(gs[0])
    pc = plot_deformed(ax0, ops, u, magnify, title)
    fig.colorbar(pc, ax=ax0, label="|u|", fraction=0.025, pad=0.02)
    ax1 = fig.add_subplot(gs[1]); ax2 = fig.add_subplot(gs[2], sharex=ax1)
    plot_pressure_gap((ax1, ax2), ops, u, lam)
    fig.tight_layout()
    return save(fig, path, svg=False)[0]


def figure_iterations(runs, example, h, rhos, path, svg=True):
    """Iterations against rho (log x) at mesh size h, one curve per method: the paper's Figs 2 / 4."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    markers = {"admm1": "s-", "admm2": "^-", "sadmm": "o-"}
    for m in METHOD_NAMES:
        pts = [(r.rho, r.iterations, r.status) for r in runs if r.example == example and r.h == h and r.method == m]
        if not pts:
            continue
        pts.sort()
        ax.plot([p[0] for p in pts], [p[1] for p in pts], markers[m], label=METHOD_LABELS[m])
        for rho, it, st in pts:
            if st != "converged":
                ax.annotate(st, (rho, it), fontsize=7)
    ax.set_xscale("log"); ax.set_yscale("log")
    ax.set_xlabel("initial penalty rho"); ax.set_ylabel("iterations")
    ax.set_title(f"{'Example 1' if example == 'ex1' else 'Example 2'}: iterations, h = {h_label(h)}")
    ax.grid(alpha=0.3, which="both"); ax.legend()
    fig.tight_layout()
    return save(fig, path, svg)


# ---------------------------------------------------------------- runs
@dataclass
class Run:
    """One (example, h, method, rho) run."""

    example: str
    h: float
    method: str
    rho: float
    iterations: int
    status: str
    time: float            # setup + solve, median over repeats (s)
    cpu_time: float        # process time of the same, median (s)
    setup_time: float
    solve_time: float
    mode: str
    factorizations: int | None
    rho_changes: int
    final_rho: float
    kkt: dict
    errors: dict
    n_free: int
    n_c: int


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


def run_reproduction(out="docs/results/paper", hs=PAPER_HS, rhos=PAPER_RHOS, repeats: int = 1,
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
    with threadpool_limits(blas_threads, user_api="blas") if blas_threads else nullcontext():
        return _run_reproduction(out, hs, rhos, repeats, progress, examples, methods, mode, command, blas_threads)


def _run_reproduction(out, hs, rhos, repeats, progress, examples, methods, mode, command, blas_threads) -> dict:
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
                                         out / f"pressure_gap_{ex}.png")
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


# ---------------------------------------------------------------- tables
def _find(runs, ex, h, m, rho) -> Run | None:
    for r in runs:
        if r.example == ex and r.h == h and r.method == m and r.rho == rho:
            return r
    return None


def _md_table(header: list[list[str]], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header[0]) + " |", "|" + "|".join("---:" for _ in header[0]) + "|"]
    for extra in header[1:]:
        lines.append("| " + " | ".join(extra) + " |")
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def _grid(runs, ex, hs, rhos, methods, cell) -> str:
    head = ["rho"] + [f"{METHOD_LABELS[m]} h={h_label(h)}" for m in methods for h in hs]
    rows = []
    for rho in rhos:
        row = [rho_label(rho)]
        for m in methods:
            for h in hs:
                row.append(cell(_find(runs, ex, h, m, rho), m, rho, h))
        rows.append(row)
    return _md_table([head], rows)


def _status_mark(r: Run) -> str:
    return "" if r.status == "converged" else f" ({r.status})"


def write_time_table(base: Path, runs, ex, hs, rhos, methods) -> list[Path]:
    """Table 1 / 2: our seconds, the paper's, and paper / ours."""
    label = "Table 1 (Example 1, g = 0.01)" if ex == "ex1" else "Table 2 (Example 2)"

    def ours(r, m, rho, h):
        return "-" if r is None else f"{r.time:.3f}{_status_mark(r)}"

    def paper(r, m, rho, h):
        p = paper_time(ex, m, rho, h)
        return "-" if p is None else f"{p:.3f}"

    def ratio(r, m, rho, h):
        p = paper_time(ex, m, rho, h)
        return "-" if (p is None or r is None or r.time <= 0) else f"{p / r.time:.0f}"

    def mode_of(r, m, rho, h):
        return "-" if r is None else r.mode

    text = [f"# {label}: time of the three methods", "",
            "Seconds of problem setup + solve per run (wall clock; the condensed mode's setup, one sparse "
            "factorisation of K and the boundary Schur complement, is paid by every run), "
            "paper's stopping rule ||u^{k+1}-u^k||_K <= 1e-5 ||u^{k+1}||_K, max 20000 iterations. "
            "The paper's figures are FreeFEM++ CPU seconds on the authors' machine "
            "(seed text, section 4). A status other than converged is marked.", "",
            "## Ours (s)", "", _grid(runs, ex, hs, rhos, methods, ours), "",
            "## Paper (s)", "", _grid(runs, ex, hs, rhos, methods, paper), "",
            "## Ratio paper / ours", "", _grid(runs, ex, hs, rhos, methods, ratio), ""]
    modes = sorted({r.mode for r in runs if r.example == ex})
    text += [f"Mode used: {', '.join(modes)}.", ""]
    md = base.with_suffix(".md")
    md.write_text("\n".join(text))
    csv_path = base.with_suffix(".csv")
    with open(csv_path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["example", "method", "h", "rho", "iterations", "status", "time_s", "cpu_s", "setup_s",
                    "solve_s", "paper_s", "paper_over_ours", "mode", "factorizations", "rho_changes", "final_rho"])
        for m in methods:
            for h in hs:
                for rho in rhos:
                    r = _find(runs, ex, h, m, rho)
                    if r is None:
                        continue
                    p = paper_time(ex, m, rho, h)
                    w.writerow([ex, m, h_label(h), f"{rho:g}", r.iterations, r.status, f"{r.time:.6f}",
                                f"{r.cpu_time:.6f}", f"{r.setup_time:.6f}", f"{r.solve_time:.6f}",
                                "" if p is None else p, "" if p is None else f"{p / r.time:.2f}",
                                r.mode, r.factorizations, r.rho_changes, f"{r.final_rho:.6g}"])
    return [md, csv_path]


def write_iteration_table(base: Path, runs, ex, hs, rhos, methods) -> list[Path]:
    """Iteration counts, same shape as the time tables."""
    def cell(r, m, rho, h):
        return "-" if r is None else f"{r.iterations}{_status_mark(r)}"

    def fac(r, m, rho, h):
        return "-" if r is None else f"{r.rho_changes}/{r.factorizations}"

    text = [f"# Iterations, {'Example 1' if ex == 'ex1' else 'Example 2'}", "",
            "Iterations to the paper's stopping rule (||u^{k+1}-u^k||_K <= 1e-5 ||u^{k+1}||_K), max 20000. "
            "The paper gives iteration counts only as figures (Figs 2 and 4, h = 1/20), which did not "
            "survive in the text.", "",
            _grid(runs, ex, hs, rhos, methods, cell), "",
            "## rho changes / factorisations", "", _grid(runs, ex, hs, rhos, methods, fac), ""]
    md = base.with_suffix(".md")
    md.write_text("\n".join(text))
    csv_path = base.with_suffix(".csv")
    with open(csv_path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["example", "method", "h", "rho", "iterations", "status", "rho_changes", "factorizations",
                    "final_rho"])
        for m in methods:
            for h in hs:
                for rho in rhos:
                    r = _find(runs, ex, h, m, rho)
                    if r is not None:
                        w.writerow([ex, m, h_label(h), f"{rho:g}", r.iterations, r.status, r.rho_changes,
                                    r.factorizations, f"{r.final_rho:.6g}"])
    return [md, csv_path]


KKT_KEYS = ("stationarity", "penetration", "negative_pressure", "complementarity")


def write_error_table(base: Path, runs, refs) -> list[Path]:
    """The true error at the stop of every run, and the KKT residuals."""
    head = ["example", "h", "method", "rho", "iterations", "status", "err u (energy)", "err lam (M_c)",
            *KKT_KEYS, "contact force"]
    rows, csv_rows = [], []
    for r in runs:
        kkt = [r.kkt.get(k, float("nan")) for k in KKT_KEYS]
        rows.append([r.example, h_label(r.h), METHOD_LABELS[r.method], rho_label(r.rho), str(r.iterations),
                     r.status, f"{r.errors['err_u_energy']:.2e}", f"{r.errors['err_lam']:.2e}",
                     *(f"{v:.1e}" for v in kkt), f"{r.kkt.get('contact_force', float('nan')):.6g}"])
        csv_rows.append([r.example, h_label(r.h), r.method, f"{r.rho:g}", r.iterations, r.status,
                         f"{r.errors['err_u_energy']:.6e}", f"{r.errors['err_lam']:.6e}",
                         *(f"{v:.6e}" for v in kkt), f"{r.kkt.get('contact_force', float('nan')):.10g}"])
    ref_rows = []
    for (ex, h), ref in refs.items():
        cc = ref.cross_check
        ref_rows.append([ex, h_label(h), ref.solver, f"{ref.seconds:.2f}",
                         *(f"{ref.kkt[k]:.1e}" for k in KKT_KEYS), f"{ref.kkt['contact_force']:.10g}",
                         f"{cc['u_energy_rel_diff']:.1e}" if cc else "-", f"{cc['lam_rel_diff']:.1e}" if cc else "-"])
    text = ["# True error at the stop", "",
            "For every run: the relative error of the displacement in the energy norm, "
            "sqrt(e'Ke)/sqrt(u*'Ku*) with e = u - u*, and of the contact pressure in the M_c norm, "
            "||lam - lam*||_Mc / ||lam*||_Mc, against a reference solution u*, lam* of the same discrete "
            "problem (min 1/2 u'Ku - f'u s.t. Bu <= g) computed once per mesh; and the KKT residuals at "
            "the stop: stationarity ||Ku - f + B'M_c lam||_inf/||f||_inf, penetration max(Bu - g)^+, "
            "negative pressure max(-lam)^+, complementarity max|lam (g - Bu)|.", "",
            "## Reference solutions", "",
            "`diff u` / `diff lam`: relative difference between the reference and an independent SADMM run "
            "to Boyd residuals <= 1e-12 (how accurate the reference is).", "",
            _md_table([["example", "h", "solver", "seconds", *KKT_KEYS, "contact force", "diff u", "diff lam"]],
                      ref_rows), "",
            "## Every run", "", _md_table([head], rows), ""]
    md = base.with_suffix(".md")
    md.write_text("\n".join(text))
    csv_path = base.with_suffix(".csv")
    with open(csv_path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["example", "h", "method", "rho", "iterations", "status", "err_u_energy", "err_lam",
                    *KKT_KEYS, "contact_force"])
        w.writerows(csv_rows)
    return [md, csv_path]


def write_readme(out: Path, runs, refs, files, wall, hs, rhos, h_fig, h_fine, rho_fig, repeats, mode,
                 command, blas_threads=1) -> Path:
    """README.md: what each file is, the command, the machine, the wall time."""
    info = machine_info()
    desc = {
        "table1_ex1_time": "Example 1 times (setup + solve) shaped like the paper's Table 1, with the paper's "
                           "CPU seconds and the ratio paper / ours",
        "table2_ex2_time": "Example 2 times shaped like the paper's Table 2, with the paper's figures and the ratio",
        "iterations_ex1": "Example 1 iteration counts (and rho changes / factorisations), same shape",
        "iterations_ex2": "Example 2 iteration counts, same shape",
        "error_at_stop": "true error at the stop of every run (energy-norm error of u, M_c error of lam) "
                         "against a tight reference of the same discrete problem, and the KKT residuals",
        "fig1_deformed_ex1": f"the paper's Fig. 1: Example 1 deformed body (u x{MAGNIFY['ex1']:g}) and the obstacle "
                             f"y = -g(x) (scaled like u), SADMM rho_0 = {rho_label(rho_fig)}, h = {h_label(h_fine)}",
        "fig3_deformed_ex2": f"the paper's Fig. 3: Example 2 deformed body (u x{MAGNIFY['ex2']:g}) and the obstacle, "
                             f"SADMM, h = {h_label(h_fine)}",
        "fig2_iterations_ex1": f"the paper's Fig. 2: Example 1 iterations against rho_0, h = {h_label(h_fig)}",
        "fig4_iterations_ex2": f"the paper's Fig. 4: Example 2 iterations against rho_0, h = {h_label(h_fig)}",
        "pressure_gap_ex1": f"Example 1 contact pressure lam and gap g - u_n along Gamma_C, SADMM, h = {h_label(h_fine)}",
        "pressure_gap_ex2": f"Example 2 contact pressure lam and gap g - u_n along Gamma_C, SADMM, h = {h_label(h_fine)}",
    }
    by_stem: dict[str, list[str]] = {}
    for f in files:
        by_stem.setdefault(Path(f).stem, []).append(Path(f).suffix.lstrip("."))
    lines = ["# Reproduction of the paper's section 4 (Tables 1-2, Figs 1-4)", "",
             f"Produced by `{command}` on {datetime.date.today().isoformat()}.", "",
             f"- examples: {', '.join(sorted({r.example for r in runs}))}; methods ADMM1 (order xz, fixed rho), "
             "ADMM2 (order zx, fixed rho), SADMM (order zx, summable rule tau = 2, c_max = 100)",
             f"- h in {{{', '.join(h_label(h) for h in hs)}}}, rho_0 in {{{', '.join(rho_label(r) for r in rhos)}}}; "
             f"{len(runs)} runs, {repeats} repeat(s) each (median time)",
             "- stopping rule: the paper's ||u^{k+1}-u^k||_K <= 1e-5 ||u^{k+1}||_K (energy norm), max 20000 iterations",
             f"- mode: {mode} (chosen: {', '.join(sorted({r.mode for r in runs}))}); operators assembled once per "
             "(example, h); each run builds a fresh contact problem, and its time is setup + solve; "
             f"BLAS threads pinned to {blas_threads} (threadpoolctl)",
             "- reference solution per mesh: see error_at_stop.md (assembly and reference solves are not timed)",
             f"- total wall time of the reproduction: {wall:.1f} s", "",
             "## Files", ""]
    for stem, exts in by_stem.items():
        lines.append(f"- `{stem}.{{{','.join(exts)}}}`: {desc.get(stem, '')}")
    lines += ["", "## Machine", ""] + [f"- {k}: {v}" for k, v in info.items()]
    lines += ["", "Other processes may share the machine; times of a few milliseconds are noisy.", ""]
    path = out / "README.md"
    path.write_text("\n".join(lines))
    return path


def main(argv=None) -> int:
    """python -m problems.contact.reproduce [--out DIR] [--quick] [--repeats N]."""
    p = argparse.ArgumentParser(prog="python -m problems.contact.reproduce", description=__doc__.split("\n")[0])
    p.add_argument("--out", default="docs/results/paper")
    p.add_argument("--quick", action="store_true", help="h = 1/10, 1/20 only (CI smoke test)")
    p.add_argument("--repeats", type=int, default=1)
    a = p.parse_args(argv)
    hs = (1 / 10, 1 / 20) if a.quick else PAPER_HS
    cmd = f"python -m problems.contact.reproduce --out {a.out}" + (" --quick" if a.quick else "")
    run_reproduction(out=a.out, hs=hs, repeats=a.repeats, command=cmd)
    return 0


if __name__ == "__main__":
    sys.exit(main())
