"""``admmkit solve obstacle``: a named obstacle scene, solved and checked."""
from __future__ import annotations

import math

from problems.cli import add_common_options, positive_float, run_solve

from .problem import DEFAULT_BACKEND, make_problem
from .scene import A_STAR, SCENES, scene as named_scene


def add_solve_parser(subparsers) -> None:
    """Register ``solve obstacle``."""
    p = subparsers.add_parser("obstacle", help="-Delta u = f, u >= psi, u = u_D (P1, NGSolve)")
    p.add_argument("--scene", default="radial",
                   help=f"named scene: {', '.join(SCENES)} (default radial)")
    p.add_argument("--h", type=positive_float, default=1 / 16, help="cell size, fractions allowed (default 1/16)")
    p.add_argument("--backend", default=DEFAULT_BACKEND, help=f"sparse solver of K + rho M, or iterative for AMG-preconditioned CG (default {DEFAULT_BACKEND})")
    p.add_argument("--plot", metavar="FILE", default=None, help="write a plot of u, psi and the contact set (PNG)")
    add_common_options(p, policy="summable", order="zx")
    p.set_defaults(func=run)


def run(args) -> int:
    """Build the scene, solve it, print the summary and the errors against the exact solution."""
    problem = make_problem(named_scene(args.scene, h=args.h), backend=args.backend)
    nx, ny = problem.scene.counts
    print(f"problem      obstacle/{args.scene}: h = {args.h:.6g} ({nx} x {ny} squares), "
          f"{problem.n} free nodes, side {problem.scene.side}")
    result = run_solve(problem, args)
    contact = problem.contact_set(result.z)
    print(f"contact set  {contact.sum()} nodes, area {problem.contact_area(result.z):.6g}")
    if problem.scene.exact is not None:
        err = problem.errors(result.x)
        radius = problem.contact_radius(result.z)
        print(f"errors       L2 {err['L2']:.4e}   H1 {err['H1']:.4e}   H1-seminorm {err['H1_semi']:.4e}")
        print(f"free bdry    radius {radius:.6f} (sqrt(area/pi))   exact a* = {A_STAR:.6f}   "
              f"difference {radius - A_STAR:+.3e}")
    if args.plot:
        print(f"plot         {plot_solution(problem, result.x, result.z, args.plot)}")
    return 0


def plot_solution(problem, u, z, path):
    """Write a PNG: u and psi along the line y = centre, and the contact set over the mesh."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    full = problem.full_vector(u)
    x, y = problem.nodes.T
    psi_all = problem.scene.evaluate("psi", x, y)
    x0, x1, y0, y1 = problem.scene.box
    yc = y[np.argmin(np.abs(y - (y0 + y1) / 2))]
    line = np.flatnonzero(np.isclose(y, yc))
    line = line[np.argsort(x[line])]
    contact = problem.contact_set(z)

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.5))
    ax1.plot(x[line], full[line], "b-", label="u_h")
    ax1.plot(x[line], psi_all[line], "k--", label="psi")
    if problem.scene.exact is not None:
        xs = np.linspace(x0, x1, 801)
        ax1.plot(xs, problem.scene.exact(xs, np.full_like(xs, yc)), "r:", label="exact u")
    ax1.set_xlabel("x"); ax1.set_title(f"section y = {yc:g}"); ax1.legend()
    tri = ax2.tricontourf(x, y, full, levels=30, cmap="viridis")
    fig.colorbar(tri, ax=ax2, label="u_h")
    free = problem.nodes[problem.free]
    ax2.plot(free[contact, 0], free[contact, 1], "w.", ms=2, label="contact set")
    if problem.scene.exact is not None:
        t = np.linspace(0, 2 * math.pi, 200)
        ax2.plot(A_STAR * np.cos(t), A_STAR * np.sin(t), "r-", lw=1, label="r = a*")
    ax2.set_aspect("equal"); ax2.set_title(f"{problem.scene.name}: u_h and contact set"); ax2.legend(loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
