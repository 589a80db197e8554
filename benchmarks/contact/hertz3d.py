"""Hertz in 3D under adaptive refinement: a and p0 of the scene ``hertz3d`` against Hertz, level by level.

``python -m admmkit.benchmarks.contact.hertz3d [--target E] [--order 1|2] [--balance GAMMA] [--out DIR]``
runs ``solve_adaptive`` (the loop of ``admmkit solve contact --scene hertz3d --target-error E --balance GAMMA``:
ZZ, Dörfler theta 0.5, the balanced stop, warm starts) and measures every level twice with
:func:`admmkit.problems.contact.validation.hertz3d.measure`:

- **stop**: the level's iterate where the balanced stop fired (what ``--target-error`` returns);
- **discrete**: the same mesh solved to the end (SADMM, relative change 1e-8 in the energy norm), the
  discrete solution itself: the balanced stop bounds the displacement's algebraic error, not the
  pressure's (docs/contact.md), so the two differ where the stop came early.

It writes ``hertz3d.md`` / ``hertz3d.csv`` (one row per level) and ``hertz3d_pressure.png`` (the nodal
pressures of the iterate the run returns against r / a_Hertz, with Hertz's ellipse) under ``--out``.
"""
from __future__ import annotations

import argparse
import math
import resource
import time
from pathlib import Path

import numpy as np

from admmkit import RelativeChange
from admmkit.figures import pyplot, save_figure
from admmkit.io import write_text

from admmkit.problems.contact.model.scene_file import load_scene
from admmkit.problems.contact.solvers.adaptive import solve_adaptive
from admmkit.problems.contact.solvers.methods import solve_scene
from admmkit.problems.contact.validation.hertz3d import hertz_pressure, measure, radii

from admmkit.benchmarks.runner.report import write_csv

COLUMNS = ["level", "cells", "unknowns", "contact_nodes", "relative_estimate", "relative_algebraic", "iterations",
           "seconds", "F", "a_hertz", "stop_a_err", "stop_p0_err", "stop_a_moment_err", "stop_p_max_err",
           "a_fit_err", "p0_fit_err", "a_moment_err", "a_err", "a_area_err", "p0_err", "p_max_err",
           "edge_in", "edge_out", "active_nodes", "discrete_iterations"]
#: the discrete solution of a level: SADMM to this relative change (energy norm)
DISCRETE_TOL = 1e-8


def _measured(ops, res) -> dict | None:
    """measure(), or None where the contact set is too small."""
    try:
        return measure(ops, res.lam, res.z)
    except ValueError:
        return None


def run_hertz3d(target: float = 0.1, order: int = 2, theta: float = 0.5, gamma: float | None = None,
                progress: bool = True):
    """The adaptive run (balanced stop ``gamma``, None: ``solve_adaptive``'s default) and one row per level (module
    docstring); returns (rows, AdaptiveResult, last discrete result)."""
    scene = load_scene("hertz3d", order=order)
    rows, last = [], {}
    t0 = time.perf_counter()

    def log(level, out):
        ops, res = out.model, out.result
        stop = _measured(ops, res)
        exact = solve_scene(ops, "sadmm", 1e3, mode="condensed", stop=RelativeChange(DISCRETE_TOL), max_iter=5000)
        disc = _measured(ops, exact.result)
        last.update(ops=ops, result=exact.result)
        nan = math.nan
        energy = float(np.sqrt(exact.result.x @ (ops.K @ exact.result.x)))
        row = {"level": len(out.levels), "cells": level.cells, "unknowns": level.unknowns,
               "contact_nodes": level.contact_nodes, "relative_estimate": level.relative_estimate,
               "relative_algebraic": level.algebraic_bound / energy,
               "iterations": level.iterations, "seconds": level.seconds,
               "F": disc["F"] if disc else nan, "a_hertz": disc["a_hertz"] if disc else nan,
               "stop_a_err": stop["a_fit_err"] if stop else nan, "stop_p0_err": stop["p0_fit_err"] if stop else nan,
               "stop_p_max_err": stop["p_max_err"] if stop else nan,
               "stop_a_moment_err": stop["a_moment_err"] if stop else nan,
               "discrete_iterations": exact.result.iterations}
        for key in ("a_fit_err", "p0_fit_err", "a_moment_err", "a_err", "a_area_err", "p0_err", "p_max_err", "edge_in", "edge_out",
                    "active_nodes"):
            row[key] = disc[key] if disc else nan
        rows.append(row)
        if progress:
            print(f"level {row['level']:2d}  {level.unknowns:7d} unknowns  rel {level.relative_estimate:.3f}  "
                  f"at the stop: a {row['stop_a_err']:+.2%} p0 {row['stop_p0_err']:+.2%} (discrete "
                  f"{row['a_fit_err']:+.2%}, {row['p0_fit_err']:+.2%})  [{time.perf_counter() - t0:.0f} s, "
                  f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6:.2f} GB]", flush=True)
    balance = {} if gamma is None else {"gamma": gamma}
    out = solve_adaptive(scene, target, theta=theta, log=log, max_levels=40, **balance)
    return rows, out, last


def write_report(out_dir, rows, out, last, target: float, order: int, command: str, seconds: float) -> list[Path]:
    """hertz3d.md, hertz3d.csv and hertz3d_pressure.png under ``out_dir`` (the figure: the returned iterate)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    write_csv(out_dir / "hertz3d.csv", rows, COLUMNS, float_format=".8g")
    pct = lambda v: "-" if not math.isfinite(v) else f"{v:+.2%}"  # noqa: E731
    lines = [f"# Hertz in 3D under adaptive refinement (P{order}, target {target:g})", "",
             f"Produced by `{command}` in {seconds:.0f} s (the discrete solves of the last columns included): "
             f"{out.status} ({out.message}).", "",
             "Against Hertz at the measured load F (problems/contact/validation/hertz3d.py). **At the stop**: the "
             "iterate where the level's balanced stop fired, what `--target-error` returns (on the last level: "
             "its result). **Discrete**: the same mesh solved to a relative change of "
             f"{DISCRETE_TOL:g}.", "",
             "`a`, `p0`: Hertz's profile fitted to the pressure of the nodal forces (the consistent face mass); "
             "`a mom.`: the radius of the nodal forces' second moment; `a ring`: the line of lam^2 against r^2 "
             "over the contact set's outer ring; `a area`: the disc of the contact set's area; `max p`: the "
             "largest nodal pressure; `alg.`: the balanced stop's bound of the algebraic error over ||u_h||_a.",
             "",
             "| level | unknowns | rel. estimate | alg. | F | a Hertz | at the stop: a | p0 | a mom. | "
             "discrete: a | p0 | a mom. | a ring | a area | max p | edge in / out (/a) |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for r in rows:
        lines.append(f"| {r['level']} | {r['unknowns']} | {r['relative_estimate']:.3f} | "
                     f"{r['relative_algebraic']:.1e} | {r['F']:.4e} | {r['a_hertz']:.5f} | "
                     f"{pct(r['stop_a_err'])} | {pct(r['stop_p0_err'])} | {pct(r['stop_a_moment_err'])} | "
                     f"{pct(r['a_fit_err'])} | {pct(r['p0_fit_err'])} | {pct(r['a_moment_err'])} | "
                     f"{pct(r['a_err'])} | {pct(r['a_area_err'])} | {pct(r['p_max_err'])} | "
                     f"{r['edge_in']:.3f} / {r['edge_out']:.3f} |")
    write_text(out_dir / "hertz3d.md", "\n".join(lines) + "\n")
    figure = out_dir / "hertz3d_pressure.png"
    _figure(figure, out.model, out.result, order)
    return [out_dir / "hertz3d.md", out_dir / "hertz3d.csv", figure]


def _figure(path: Path, ops, res, order: int) -> None:
    """The returned iterate's nodal pressures against r / a_Hertz (P2: vertices and midpoints apart), with Hertz's
    ellipse and the profile fitted to the nodal forces."""
    m = measure(ops, res.lam, res.z)
    scene = ops.scene
    r, lam = radii(ops), res.lam[:ops.n_c]
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    near = r <= 1.6 * m["a_hertz"]
    vertex = np.zeros(ops.n_c, dtype=bool) if order == 1 else _is_vertex(ops)
    for which, style, label in ((~vertex, "o", "nodal pressure lam_i" + (" (edge midpoints)" if order == 2 else "")),
                                (vertex, "x", "nodal pressure lam_i (vertices)")):
        if (near & which).any():
            ax.plot(r[near & which] / m["a_hertz"], lam[near & which] / m["p0_hertz"], style, ms=3.5,
                    color="C0" if style == "o" else "C2", mfc="none", label=label)
    rs = np.linspace(0, 1.6, 400)
    ax.plot(rs, hertz_pressure(rs * m["a_hertz"], m["F"], 1.0, scene.E, scene.nu) / m["p0_hertz"], "k-", lw=1.5,
            label="Hertz p0 sqrt(1 - r^2/a^2) at the measured F")
    ax.plot(rs, m["p0_fit"] / m["p0_hertz"] * np.sqrt(np.maximum(1 - (rs * m["a_hertz"] / m["a_fit"]) ** 2, 0)),
            "C1--", lw=1.2, label="Hertz's profile fitted to the nodal forces")
    ax.set_xlabel("r / a (Hertz, at the measured F)")
    ax.set_ylabel("p / p0 (Hertz)")
    ax.set_title(f"hertz3d, P{order}, {ops.n_free} unknowns (returned iterate): a {m['a_fit_err']:+.2%}, "
                 f"p0 {m['p0_fit_err']:+.2%}", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)


def _is_vertex(ops) -> np.ndarray:
    """Which contact nodes are mesh vertices (the others: P2 edge midpoints)."""
    points = np.array(ops.mesh.ngmesh.Coordinates())
    from scipy.spatial import cKDTree
    dist, _ = cKDTree(points).query(ops.xc)
    return dist <= 1e-12


def main(argv=None) -> int:
    """The command line of the module (module docstring)."""
    p = argparse.ArgumentParser(prog="python -m admmkit.benchmarks.contact.hertz3d")
    p.add_argument("--target", type=float, default=0.1)
    p.add_argument("--order", type=int, choices=(1, 2), default=2)
    p.add_argument("--balance", type=float, default=None, metavar="GAMMA",
                   help="gamma of the balanced stop, as admmkit solve contact --balance (default: its default)")
    p.add_argument("--out", default="out/hertz3d")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    rows, out, last = run_hertz3d(args.target, args.order, gamma=args.balance)
    command = (f"python -m admmkit.benchmarks.contact.hertz3d --target {args.target:g} --order {args.order}"
               + ("" if args.balance is None else f" --balance {args.balance:g}"))
    for path in write_report(args.out, rows, out, last, args.target, args.order, command,
                             time.perf_counter() - t0):
        print(path)
    return 0 if out.reached else 1


if __name__ == "__main__":
    raise SystemExit(main())
