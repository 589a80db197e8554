"""``admmkit bench contact3d``: the 3D block on a curved foundation, solved with the AMG x-step.

1. **Where the direct solver struggles.**  For a sequence of meshes, one sparse
   factorisation of the x-step matrix K + rho B'M_c B (``admmkit.linalg.linsolve``,
   backend "auto") against one AMG setup and one CG solve to a relative energy
   error of 1e-8, each in its own process with a time limit; time and peak
   memory.  SADMM needs a new factorisation at every change of rho (5-6 in
   these runs), so the factorisation time is a lower bound for the full mode.
2. **The SADMM run** at the requested size with ``mode="iterative"`` (rho_0 =
   1e3, the paper's stopping rule): iterations, CG iterations, times, peak
   memory, KKT residuals; the figure of the deformed block and of the contact
   pressure on the contact face (``contact3d.png/svg``) and VTK output
   (``--vtk``, default ``out/contact3d/contact3d.vtu``: displacement and contact
   pressure, for ParaView).
3. **Growth with the unknowns** (:func:`run_growth`, alone with ``--growth-only``):
   SADMM with the iterative x-step at each size up to 1e6 unknowns, each in its
   own process; the whole process's wall-clock and CPU time (``getrusage`` of
   the child: start-up, assembly, set-up, SADMM) and its peak memory against
   the memory check's estimate, charted log-log with the growth exponents
   (``contact3d_growth.png/svg``, ``contact3d_growth.md``, ``.csv``).
"""
from __future__ import annotations

import json
import math
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from admmkit.figures import pyplot, save_figure
from admmkit.io import write_text

from admmkit.benchmarks.runner.machine import machine_info
from admmkit.benchmarks.contact.scale_runs import peak_rss_bytes

DEFAULT_H = 1 / 32
PROBE_HS = (1 / 8, 1 / 12, 1 / 16, 1 / 24, 1 / 32)
SADMM_HS = (1 / 8, 1 / 12, 1 / 16, 1 / 24)
#: the sizes of the growth chart: 5.8e3 to 1.04e6 unknowns
GROWTH_HS = (1 / 8, 1 / 12, 1 / 16, 1 / 24, 1 / 32, 1 / 48)
#: the issue's target at h = 1/48 (1.04e6 unknowns): the whole process in 60 s, at most 8 GB
TARGET_SECONDS, TARGET_BYTES = 60.0, 8e9


def _label(h: float) -> str:
    return f"1/{round(1 / h)}"


def probe(h: float, rho: float = 1e3) -> dict:
    """One factorisation and one AMG-CG solve of the x-step matrix at mesh size h (in this process)."""
    import scipy.sparse as sp
    from threadpoolctl import threadpool_limits

    from admmkit.blocks.iterative import IterativeXSolver
    from admmkit.linalg.linsolve import available_backends, factorize

    from admmkit.problems.contact.solvers.iterative import near_null_space
    from admmkit.problems.contact.model.assembly3d import assemble3d
    from admmkit.problems.contact.model.scene3d import example2_3d

    ops = assemble3d(example2_3d(h=h))
    D = (ops.B.T @ sp.diags(ops.mc) @ ops.B).tocsr()
    A = (ops.K + rho * D).tocsc()
    b = ops.f + rho * ops.B.T @ (ops.mc * ops.g)
    row = {"h": h, "n_free": int(ops.n_free), "backend": available_backends()[0]}
    mode = os.environ.get("ADMMKIT_PROBE", "both")
    import pyamg  # noqa: F401  (warm-up: imports and the backend's first call are not timed)
    factorize(sp.identity(3, format="csc"))(np.ones(3))
    with threadpool_limits(1):
        if mode in ("both", "amg"):
            modes, blocks = near_null_space(ops)
            t0 = time.perf_counter()
            solver = IterativeXSolver(ops.K, D, near_null=modes, blocks=blocks, tol=1e-8, projection=0)
            x = solver.solve(rho, b)
            row |= {"amg_setup_s": solver.setup_time, "amg_total_s": time.perf_counter() - t0,
                    "cg_iterations": solver.cg_iterations,
                    "amg_residual": float(np.linalg.norm(A @ x - b) / np.linalg.norm(b))}
        if mode in ("both", "direct"):
            t0 = time.perf_counter()
            solve = factorize(A)
            t1 = time.perf_counter()
            x = solve(b)
            row |= {"factor_s": t1 - t0, "direct_solve_s": time.perf_counter() - t1,
                    "direct_residual": float(np.linalg.norm(A @ x - b) / np.linalg.norm(b))}
    return row | {"peak_rss_bytes": peak_rss_bytes()}


def probe_in_subprocess(h: float, which: str, timeout: float) -> dict:
    """:func:`probe` of ``which`` ("direct" or "amg") in a fresh process (its own peak memory)."""
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1", ADMMKIT_PROBE=which)
    env["PYTHONPATH"] = str(Path(__file__).resolve().parents[2]) + os.pathsep + env.get("PYTHONPATH", "")
    cmd = [sys.executable, "-m", "admmkit.benchmarks.contact.contact3d", repr(h)]
    start = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        return {"h": h, "status": f"no answer within {timeout:g} s", "wall_s": time.perf_counter() - start}
    if proc.returncode != 0:
        tail = (proc.stderr.strip().splitlines() or ["?"])[-1]
        return {"h": h, "status": f"failed: {tail}", "wall_s": time.perf_counter() - start}
    return json.loads(proc.stdout.strip().splitlines()[-1]) | {"status": "ok", "wall_s": time.perf_counter() - start}


def solve_3d(h: float, rho: float = 1e3) -> dict:
    """SADMM with the iterative x-step on the 3D scene; the solution and the run's figures."""
    import admmkit
    from admmkit import policies
    from threadpoolctl import threadpool_limits

    from admmkit.problems.contact.solvers.problem import contact_problem
    from admmkit.problems.contact.model.assembly3d import assemble3d
    from admmkit.problems.contact.model.scene3d import example2_3d

    t0 = time.perf_counter()
    ops = assemble3d(example2_3d(h=h))
    t1 = time.perf_counter()
    with threadpool_limits(1):
        problem = contact_problem(ops, mode="iterative")
        t2 = time.perf_counter()
        sadmm_order, sadmm_rule = policies.method("sadmm")   # policies/paper_methods.py
        result = admmkit.solve(problem, rho=rho, policy=sadmm_rule, order=sadmm_order,
                               stop=admmkit.RelativeChange(1e-5), max_iter=5000)
    t3 = time.perf_counter()
    return {"ops": ops, "result": result, "solver": problem.solver, "assemble_s": t1 - t0, "setup_s": t2 - t1,
            "solve_s": t3 - t2, "total_s": t3 - t0, "peak_rss_bytes": peak_rss_bytes()}


def write_vtk(ops, u: np.ndarray, lam: np.ndarray, base: Path, p: np.ndarray | None = None) -> Path:
    """VTU file (ParaView, meshio) in double precision: displacement at the vertices; contact pressure, gap and
    status on the contact face (problems/contact/output/export.py; NaN, or -1 for the status, off the face)."""
    from admmkit.problems.contact.output.export import boundary_fields, write_vtu
    base = Path(base)
    base.parent.mkdir(parents=True, exist_ok=True)
    fields = boundary_fields(ops, u, lam, ops.g if p is None else p)
    if p is None:
        del fields["contact_status"]          # no z-step given: no status rather than a guess
    return write_vtu(base, ops, u, fields)


def figure_3d(ops, u: np.ndarray, lam: np.ndarray, p: np.ndarray, path: Path, magnify: float = 20.0) -> list[Path]:
    """The deformed block over the foundation (both x ``magnify``), and the contact pressure on the face z = 0.

    Two stacked panels sized for the docs' page width: the 3D view from slightly
    below the contact face, so that the foundation surface -g(x, y) (grey) and
    the gap between it and the block are visible; then the pressure lam with the
    active nodes (p = g, ``contact_status`` of problems/contact/output/export.py) and
    gap contours.
    """
    import ngsolve as ng
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    from admmkit.problems.contact.output.export import contact_status
    plt = pyplot()
    nv = ops.mesh.nv
    full = ops.full_vector(u)
    disp = np.column_stack([full[:nv], full[nv:2 * nv], full[2 * nv:3 * nv]])
    X = np.array(ops.mesh.ngmesh.Coordinates())
    tris = np.array([[v.nr for v in el.vertices] for el in ops.mesh.Elements(ng.BND)])
    Y = X + magnify * disp
    mag = np.linalg.norm(disp, axis=1)
    scene = ops.scene
    fig = plt.figure(figsize=(10, 8.4))
    ax = fig.add_axes((-0.04, 0.40, 0.94, 0.56), projection="3d")
    # the foundation first (a little larger than the block, so its edges show), then the block
    xx, yy = np.meshgrid(np.linspace(-0.15, scene.Lx + 0.15, 37), np.linspace(-0.25, scene.Ly + 0.25, 13))
    gg = np.vectorize(scene.gap_at)(xx, yy)
    ax.plot_surface(xx, yy, -magnify * gg, color="0.6", alpha=0.45, linewidth=0.3, edgecolor="0.35", shade=False)
    colours = plt.get_cmap("viridis")(mag[tris].mean(axis=1) / max(mag.max(), 1e-300))
    surface = Poly3DCollection(Y[tris], facecolors=colours, edgecolors="none", linewidths=0)
    surface.set_rasterized(True)          # keeps the SVG small (one bitmap instead of 1e5 polygons)
    ax.add_collection3d(surface)
    lo = np.minimum(Y.min(axis=0), [xx.min(), yy.min(), -magnify * gg.max()])
    hi = np.maximum(Y.max(axis=0), [xx.max(), yy.max(), 0.0])
    ax.set_xlim(lo[0], hi[0]); ax.set_ylim(lo[1], hi[1]); ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(hi - lo, zoom=1.35)
    ax.view_init(elev=8, azim=-62)
    ax.set_xlabel("x", labelpad=6); ax.set_ylabel("y", labelpad=2); ax.set_zlabel("z", labelpad=2)
    ax.tick_params(labelsize=8, pad=1)
    ax.set_yticks([0, 0.5, 1.0]); ax.set_zticks([0, 0.5, 1.0])
    sm = plt.cm.ScalarMappable(cmap="viridis", norm=plt.Normalize(0, mag.max()))
    cb = fig.colorbar(sm, cax=fig.add_axes((0.88, 0.50, 0.018, 0.36)))
    cb.set_label("|u|", fontsize=10)
    fig.text(0.5, 0.985, f"Deformed block (u x {magnify:g}, colour |u|) above the rigid foundation z = -g(x, y) "
             f"(grey, x {magnify:g})", ha="center", va="top", fontsize=11)
    ax2 = fig.add_axes((0.08, 0.06, 0.74, 0.3))
    xc = ops.xc
    tpc = ax2.tripcolor(xc[:, 0], xc[:, 1], lam[:ops.n_c], shading="gouraud", cmap="magma", rasterized=True)
    cb2 = fig.colorbar(tpc, cax=fig.add_axes((0.84, 0.075, 0.018, 0.265)))
    cb2.set_label("contact pressure lam", fontsize=10)
    active = contact_status(ops, p)
    ax2.plot(xc[active, 0], xc[active, 1], "c.", ms=2.5, label=f"active nodes ({int(active.sum())}: p = g)")
    ax2.tricontour(xc[:, 0], xc[:, 1], ops.g, levels=6, colors="w", linewidths=0.6)
    ax2.set_xlim(0, scene.Lx); ax2.set_ylim(0, scene.Ly); ax2.set_facecolor("0.85")   # grey: no contact node (clamped)
    ax2.set_aspect("equal"); ax2.set_xlabel("x"); ax2.set_ylabel("y")
    ax2.set_title("Contact pressure on the face z = 0 (white: contours of the gap g)", fontsize=11)
    ax2.legend(loc="upper left", fontsize=9)
    return save_figure(fig, path)


def run_sadmm_modes(hs, modes=("full", "condensed", "iterative"), timeout=600.0) -> list[dict]:
    """SADMM on the 3D scene in each mode and size, each run in its own process (scale.run_in_subprocess)."""
    from admmkit.benchmarks.contact.scale_runs import print_run, run_in_subprocess
    rows = []
    for h in hs:
        for mode in modes:
            print(f"SADMM h = {_label(h)} {mode} ...", flush=True)
            r = run_in_subprocess("ex2_3d", h, mode, timeout=timeout)
            rows.append(r)
            print_run(r)
    return rows


def children_cpu_seconds() -> float:
    """User + system CPU seconds of this process's finished children (``getrusage(RUSAGE_CHILDREN)``)."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_growth(hs=GROWTH_HS, timeout=1800.0) -> list[dict]:
    """SADMM with the iterative x-step at each mesh size, each in its own process (``scale_runs``); each row
    adds ``cpu_s``, the child's CPU seconds (on a shared machine its wall-clock time includes waiting)."""
    from admmkit.benchmarks.contact import scale_runs
    rows = []
    for h in hs:
        print(f"growth: SADMM h = {_label(h)} iterative ...", flush=True)
        before = children_cpu_seconds()
        r = scale_runs.run_in_subprocess("ex2_3d", h, "iterative", timeout=timeout)
        rows.append(r | {"cpu_s": children_cpu_seconds() - before})
        scale_runs.print_run(r)
    return rows


def growth_exponent(rows, key: str) -> float:
    """Least-squares slope of log(row[key]) against log(unknowns) over the converged runs with >= 4e4 unknowns
    (the smaller ones are start-up; 1 is linear growth)."""
    pts = [(math.log(r["n_free"]), math.log(r[key])) for r in rows
           if r.get("status") == "converged" and r["n_free"] >= 4e4 and r.get(key)]
    if len(pts) < 2:
        return math.nan
    mx, my = sum(p[0] for p in pts) / len(pts), sum(p[1] for p in pts) / len(pts)
    return sum((x - mx) * (y - my) for x, y in pts) / sum((x - mx) ** 2 for x, _ in pts)


def figure_growth(rows, path: Path) -> list[Path]:
    """Two log-log panels against the unknowns: the whole process's time (wall and CPU) and SADMM's, and the
    peak memory with the memory check's estimate; growth exponents in the legends, the targets dashed."""
    plt = pyplot()
    done = [r for r in rows if r.get("status") == "converged"]
    n = [r["n_free"] for r in done]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.4))
    for key, label, style in (("wall_s", "whole process, wall clock", "o-"), ("cpu_s", "whole process, CPU", "s-"),
                              ("solve_s", "SADMM loop, wall clock", "^:")):
        ax1.loglog(n, [r[key] for r in done], style, label=f"{label} (n^{growth_exponent(done, key):.2f})")
    ax1.axhline(TARGET_SECONDS, color="r", ls="--", lw=1, label=f"target {TARGET_SECONDS:g} s at 1e6")
    ax1.set_xlabel("unknowns"); ax1.set_ylabel("seconds"); ax1.set_title("time")
    ax2.loglog(n, [r["peak_rss_bytes"] / 1e9 for r in done], "o-",
               label=f"peak RSS (n^{growth_exponent(done, 'peak_rss_bytes'):.2f})")
    ax2.loglog(n, [r["estimate_bytes"] / 1e9 for r in done], "s--", label="estimate of the memory check")
    ax2.axhline(TARGET_BYTES / 1e9, color="r", ls="--", lw=1, label=f"target {TARGET_BYTES / 1e9:g} GB")
    ax2.set_xlabel("unknowns"); ax2.set_ylabel("GB"); ax2.set_title("peak memory")
    for ax, target in ((ax1, TARGET_SECONDS), (ax2, TARGET_BYTES / 1e9)):
        ax.set_ylim(top=max(ax.get_ylim()[1], 1.6 * target))    # the target's line inside the frame, not on it
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8)
    fig.suptitle("3D block (bench contact3d), SADMM with the iterative x-step: growth with the unknowns "
                 "(exponents: sizes >= 4e4)", fontsize=11)
    fig.tight_layout()
    return save_figure(fig, path)


def write_growth(out: Path, rows, command: str) -> list[Path]:
    """contact3d_growth.md, .csv and the chart (``figure_growth``)."""
    from admmkit.benchmarks.runner.report import write_csv
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    keys = ("h", "n_free", "n_c", "status", "iterations", "cg_iterations", "wall_s", "cpu_s", "assemble_s", "setup_s",
            "solve_s", "cg_s", "amg_setup_s", "peak_rss_bytes", "estimate_bytes")
    table = [{k: (r.get("counters", {}).get(k) if k == "cg_iterations" else r.get(k)) for k in keys} for r in rows]
    write_csv(out / "contact3d_growth.csv", table, keys)
    figs = figure_growth(rows, out / "contact3d_growth.png") if any(r.get("status") == "converged" for r in rows) else []
    done = [r for r in rows if r.get("status") == "converged"]
    lines = ["# 3D block: time and memory against the unknowns (iterative x-step)", "",
             f"Produced by `{command}`. SADMM (rho_0 = 1e3, the paper's stopping rule) on the block of "
             "`example2_3d` (the scene `block3d`) with `mode=\"iterative\"`, each size in its own process "
             "(BLAS on one thread). Whole process = start-up, assembly, set-up and SADMM; CPU = the child's user + "
             "system time (`getrusage`), which does not count the time it waited for a core on a shared machine; "
             "peak = its ru_maxrss; estimate = `memory_need3d`, the check made before anything is assembled.", "",
             "| h | unknowns | status | SADMM it. | CG it. | whole process wall (s) | CPU (s) | assembly (s) | "
             "SADMM (s) | peak (GB) | estimate (GB) |",
             "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        if r.get("status") != "converged":
            lines.append(f"| {_label(r['h'])} | {r.get('n_free', '-')} | {r.get('status')}: {r.get('message', '')} "
                         "| | | | | | | | |")
            continue
        lines.append(f"| {_label(r['h'])} | {r['n_free']} | converged | {r['iterations']} | "
                     f"{r['counters'].get('cg_iterations', '-')} | {r['wall_s']:.1f} | {r['cpu_s']:.1f} | "
                     f"{r['assemble_s']:.1f} | {r['solve_s']:.1f} | {r['peak_rss_bytes'] / 1e9:.2f} | "
                     f"{r['estimate_bytes'] / 1e9:.2f} |")
    lines += ["", "Growth exponents (log-log least squares over the sizes >= 4e4; 1 is linear): whole process "
              f"wall {growth_exponent(done, 'wall_s'):.2f}, CPU {growth_exponent(done, 'cpu_s'):.2f}, SADMM "
              f"{growth_exponent(done, 'solve_s'):.2f}, peak memory {growth_exponent(done, 'peak_rss_bytes'):.2f}.",
              "", "Chart: `contact3d_growth.png`.", "", "Machine:", ""]
    lines += [f"- {k}: {v}" for k, v in machine_info().items()]
    write_text(out / "contact3d_growth.md", "\n".join(lines) + "\n")
    return figs


def run_contact3d(out="out/scale", h=DEFAULT_H, probe_hs=PROBE_HS, timeout=600.0,
                  command="admmkit bench contact3d", sadmm_hs=SADMM_HS, vtk="out/contact3d/contact3d",
                  growth_hs=GROWTH_HS, growth_only=False) -> dict:
    """All measurements; print them; write contact3d.md, the figure and the VTK file (``vtk``.vtu:
    double precision, written by meshio; large at h = 1/32, so outside docs/ and not committed), and the
    growth chart of ``growth_hs`` (only that with ``growth_only``)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    growth = run_growth(growth_hs, timeout=max(timeout, 1800.0)) if growth_hs else []
    if growth:
        write_growth(out, growth, command)
    if growth_only:
        return {"growth": growth}
    sadmm = run_sadmm_modes(sadmm_hs, timeout=timeout) if sadmm_hs else []
    probes = []
    for ph in probe_hs:
        row = {"h": ph}
        for which in ("amg", "direct"):
            print(f"probe h = {_label(ph)} {which} ...", flush=True)
            r = probe_in_subprocess(ph, which, timeout)
            row[which] = r
            if r["status"] == "ok":
                print(f"        n = {r['n_free']}  " + (f"AMG setup {r['amg_setup_s']:.2f} s + CG {r['amg_total_s'] - r['amg_setup_s']:.2f} s "
                      f"({r['cg_iterations']} it.)" if which == "amg" else
                      f"factorisation ({r['backend']}) {r['factor_s']:.2f} s") +
                      f"  peak {r['peak_rss_bytes'] / 1e9:.2f} GB", flush=True)
            else:
                print(f"        {r['status']}", flush=True)
        probes.append(row)
    print(f"SADMM, iterative x-step, h = {_label(h)} ...", flush=True)
    run = solve_3d(h)
    ops, res = run["ops"], run["result"]
    c = res.counters
    print(f"        n = {ops.n_free}  n_c = {ops.n_c}  {res.status.value}, {res.iterations} iterations, "
          f"{c['cg_iterations']} CG, total {run['total_s']:.1f} s  peak {run['peak_rss_bytes'] / 1e9:.2f} GB", flush=True)
    figs = figure_3d(ops, res.x, res.lam, res.z, out / "contact3d.png")
    vtu = write_vtk(ops, res.x, res.lam, Path(vtk), p=res.z)
    print(f"        figure {figs[0]}, VTK {vtu}", flush=True)
    _write_md(out / "contact3d.md", probes, run, command, figs, vtu, sadmm)
    return {"probes": probes, "run": run, "sadmm": sadmm, "growth": growth}


def _write_md(path, probes, run, command, figs, vtu, sadmm=()) -> None:
    ops, res = run["ops"], run["result"]
    kkt, c = res.kkt or {}, res.counters
    lines = ["# 3D: elastic block on a curved rigid foundation (P1 tetrahedra, AMG x-step)", "",
             f"Produced by `{command}`. The 3D analogue of the paper's Example 2 "
             "(`problems/contact/model/scene3d.py`): block (0,3)x(0,1)x(0,1), clamped at x = 0, traction (0, 0, -2) on "
             "x = 3, frictionless contact on z = 0 with g = 0.003 (x-1.5)^2 + 0.003 (y-0.5)^2 + 0.001, E = 5000, "
             "nu = 0.49.", "",
             "## Where the direct solver struggles", "",
             "One factorisation of K + rho B'M_c B (rho = 1e3, `admmkit.linalg.linsolve`, backend auto) against one AMG "
             "setup + CG solve to 1e-8 (relative energy error), each in its own process (BLAS on one thread); "
             "peak = the process's ru_maxrss. In the full mode SADMM refactorises at every change of rho.",
             "", "| h | unknowns | factorisation (s) | peak direct (GB) | AMG setup + CG (s) | CG it. | peak AMG (GB) |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    for row in probes:
        d, a = row["direct"], row["amg"]
        n = d.get("n_free") or a.get("n_free", "")
        fd = f"{d['factor_s']:.2f}" if d["status"] == "ok" else d["status"]
        md = f"{d['peak_rss_bytes'] / 1e9:.2f}" if d["status"] == "ok" else "-"
        fa = f"{a['amg_total_s']:.2f}" if a["status"] == "ok" else a["status"]
        ma = f"{a['peak_rss_bytes'] / 1e9:.2f}" if a["status"] == "ok" else "-"
        lines.append(f"| {_label(row['h'])} | {n} | {fd} | {md} | {fa} | {a.get('cg_iterations', '-')} | {ma} |")
    if sadmm:
        lines += ["", "## SADMM by x-step mode", "",
                  "SADMM (rho_0 = 1e3, the paper's stopping rule) on the same scene in each mode, each run in its own "
                  "process; time = setup + SADMM (the assembly is common); refused = the memory estimate exceeded "
                  "the available memory, so nothing was assembled.", "",
                  "| h | unknowns | n_c | full (s) | condensed (s) | iterative (s) | peak full / condensed / iterative (GB) |",
                  "|---|---:|---:|---:|---:|---:|---|"]
        by_h: dict = {}
        for r in sadmm:
            by_h.setdefault(r["h"], {})[r["mode"]] = r
        for hh, runs in sorted(by_h.items(), reverse=True):
            any_run = next((r for r in runs.values() if "n_free" in r), {})
            cell = lambda m: (f"{runs[m]['setup_s'] + runs[m]['solve_s']:.2f}" if runs.get(m, {}).get("status") == "converged"  # noqa: E731
                              else runs.get(m, {}).get("status", "-"))
            mem = lambda m: (f"{runs[m]['peak_rss_bytes'] / 1e9:.2f}" if "peak_rss_bytes" in runs.get(m, {}) else "-")  # noqa: E731
            lines.append(f"| {_label(hh)} | {any_run.get('n_free', '')} | {any_run.get('n_c', '')} | {cell('full')} | "
                         f"{cell('condensed')} | {cell('iterative')} | {mem('full')} / {mem('condensed')} / {mem('iterative')} |")
    lines += ["", f"## SADMM with the iterative x-step, h = {_label(ops.scene.h)}", "",
              f"- unknowns {ops.n_free}, contact nodes {ops.n_c}",
              f"- {res.status.value} after {res.iterations} iterations ({res.rho_changes} rho changes); "
              f"{c['cg_iterations']} CG iterations in all, {c['amg_setups']} AMG setup(s), {c['amg_refreshes']} "
              f"Galerkin refresh(es), {c['cg_unconverged']} inexact solves that hit the CG cap",
              f"- assembly {run['assemble_s']:.1f} s, setup {run['setup_s']:.1f} s, SADMM {run['solve_s']:.1f} s "
              f"(AMG setup {run['solver'].setup_time:.1f} s, refreshes {run['solver'].refresh_time:.1f} s, "
              f"CG {run['solver'].solve_time:.1f} s); peak memory {run['peak_rss_bytes'] / 1e9:.2f} GB",
              f"- KKT: stationarity {kkt.get('stationarity', float('nan')):.2e}, penetration "
              f"{kkt.get('penetration', float('nan')):.2e}, negative pressure {kkt.get('negative_pressure', float('nan')):.2e}; "
              f"{kkt.get('active_nodes', '?')} active nodes; total contact force {kkt.get('contact_force', float('nan')):.4f} "
              f"(the applied load is 2.0; the clamp at x = 0 carries the difference)",
              f"- figure `{figs[0].name}` (deformed block, pressure on the contact face); VTK file `{vtu}` "
              "(displacement and contact pressure for ParaView; not committed: `*.vtu` is git-ignored)", "",
              "Machine (shared with other engineers during the run):", ""]
    lines += [f"- {k}: {v}" for k, v in machine_info().items()]
    write_text(Path(path), "\n".join(lines) + "\n")


if __name__ == "__main__":  # child process of probe_in_subprocess
    print(json.dumps(probe(float(sys.argv[1]))))
