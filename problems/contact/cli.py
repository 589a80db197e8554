"""``admmkit solve contact``, ``admmkit reproduce paper`` and ``admmkit bench contact``.

    admmkit solve contact --scene ex1 --h 1/40 --method sadmm --rho 1e3 [--mode auto|full|condensed]
                          [--json FILE] [--csv FILE] [--plot FILE.png] [--vtk BASENAME]
    admmkit reproduce paper [--out docs/results/paper] [--quick]
    admmkit bench contact [--out docs/results/contact_speed.md]
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from problems.cli import add_stop_options, positive_float, progress_callback, stop_rule

from .methods import METHODS, method as resolve_method
from .problem import MODES


def add_solve_parser(subparsers) -> None:
    """Register ``solve contact``."""
    p = subparsers.add_parser("contact", help="2D frictionless elastic contact with a rigid foundation (NGSolve)",
                              description="Solve a contact scene with ADMM1, ADMM2, SADMM or any penalty policy.")
    p.add_argument("--scene", default="ex1",
                   help="ex1, ex2 (the paper's examples) or a path to a scene TOML file (default ex1)")
    p.add_argument("--h", type=positive_float, default=None, help="mesh size, fractions allowed (default: the scene's)")
    p.add_argument("--method", default="sadmm",
                   help=f"{', '.join(METHODS)} or a registered penalty policy (order zx) (default sadmm)")
    p.add_argument("--rho", type=positive_float, default=1e3, help="initial penalty rho_0 > 0 (default 1e3)")
    p.add_argument("--order", choices=["xz", "zx"], default=None, help="override the method's update order")
    p.add_argument("--mode", choices=list(MODES), default="auto",
                   help="full: sparse x-steps; condensed: dense x-steps on Gamma_C (default auto)")
    add_stop_options(p, max_iter=20_000)  # the stop is in the energy norm (docs/contact.md)
    p.add_argument("--json", metavar="FILE", default=None,
                   help="write u (free dofs), contact nodes, lam, p, g and the run's summary as JSON")
    p.add_argument("--csv", metavar="FILE", default=None, help="write the contact-boundary table x, y, u_n, g, lam, p")
    p.add_argument("--plot", metavar="FILE.png", default=None, help="write the deformed body and the pressure/gap plot")
    p.add_argument("--magnify", type=positive_float, default=None,
                   help="displacement magnification in --plot (default 10 for ex1, 20 otherwise)")
    p.add_argument("--vtk", metavar="BASENAME", default=None, help="write the displacement for ParaView (VTK)")
    p.set_defaults(func=run)


def _scene(args):
    from .scene import SCENES_DIR, load_scene
    name = str(args.scene)
    path = Path(name)
    if not path.exists() and not (SCENES_DIR / f"{path.name}.toml").exists():
        known = ", ".join(sorted(p.stem for p in SCENES_DIR.glob("*.toml")))
        raise ValueError(f"--scene: unknown scene {name!r}; give one of {known} or the path of a TOML scene file")
    if path.is_dir():
        raise ValueError(f"--scene: {name!r} is a directory, not a TOML scene file")
    changes = {} if args.h is None else {"h": args.h}
    try:
        return load_scene(name, **changes)
    except ValueError as err:
        raise ValueError(f"--scene {name}: {err}") from None


def run(args) -> int:
    """Build the scene, solve it, print the summary and write the requested files."""
    import numpy as np

    from .methods import solve_scene

    if args.max_iter < 1:
        raise ValueError(f"--max-iter must be an integer >= 1, got {args.max_iter}")
    try:
        resolve_method(args.method)
    except ValueError as err:
        raise ValueError(f"--method: {err}") from None
    scene = _scene(args)
    sol = solve_scene(scene, args.method, args.rho, mode=args.mode, stop=stop_rule(args),
                      max_iter=args.max_iter, order=args.order, callback=progress_callback(args.progress))
    ops, r = sol.ops, sol.result
    print(f"problem      contact/{scene.name or args.scene}: h = {scene.h:.6g}, P{scene.order} {scene.mesh_kind}, "
          f"{ops.mesh.ne} triangles")
    print(f"size         n_free {ops.n_free}   n_c {ops.n_c}   mode {sol.mode}   setup {sol.setup_time:.4f} s")
    print(f"method       {args.method}, rho_0 = {args.rho:g}")
    print(r.summary())
    un = ops.B @ r.x
    active = int(np.count_nonzero(ops.g - un <= 1e-4 * max(float(np.abs(ops.g).max()), 1e-300)))
    kkt = r.kkt or {}
    print(f"contact      force {kkt.get('contact_force', float(ops.mc @ r.lam)):.6g}   "
          f"active nodes {active}/{ops.n_c} (g - u_n <= 1e-4 max g)   max u_n {un.max():.4e}")
    if args.history:
        print(f"history      {r.history.to_csv(args.history)}")
    if args.json:
        data = {"scene": scene.name or str(args.scene), "h": scene.h, "method": args.method, "rho0": args.rho,
                "mode": sol.mode, "status": r.status.value, "iterations": int(r.iterations),
                "rho_final": float(r.rho), "rho_changes": int(r.rho_changes), "counters": dict(r.counters),
                "time": dict(r.timings), "setup_time": sol.setup_time, "kkt": kkt,
                "n_free": int(ops.n_free), "n_c": int(ops.n_c),
                "u": r.x.tolist(), "contact_x": ops.xc[:, 0].tolist(), "contact_xy": ops.xc.tolist(),
                "lam": r.lam.tolist(), "p": r.z.tolist(), "g": ops.g.tolist(), "u_n": un.tolist()}
        Path(args.json).write_text(json.dumps(data, indent=1))
        print(f"json         {args.json}")
    if args.csv:
        import csv
        with open(args.csv, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["x", "y", "u_n", "g", "gap", "lam", "p"])
            for (x, y), a, b, lam, p in zip(ops.xc, un, ops.g, r.lam, r.z):
                w.writerow([f"{x:.10g}", f"{y:.10g}", f"{a:.10e}", f"{b:.10e}", f"{b - a:.10e}",
                            f"{lam:.10e}", f"{p:.10e}"])
        print(f"csv          {args.csv}")
    if args.plot:
        from .reproduce import figure_solution
        magnify = args.magnify or (10.0 if scene.name == "example1" else 20.0)
        figure_solution(ops, r.x, r.lam, magnify,
                        f"{scene.name or args.scene}: {args.method}, rho_0 = {args.rho:g}, h = {scene.h:.4g}, "
                        f"u x{magnify:g}", args.plot)
        print(f"plot         {args.plot}")
    if args.vtk:
        import ngsolve as ng
        gf = ops.to_gridfunction(r.x)
        written = ng.VTKOutput(ops.mesh, coefs=[gf], names=["displacement"], filename=str(args.vtk)).Do()
        written = str(written or args.vtk)
        print(f"vtk          {written if written.endswith('.vtu') else written + '.vtu'}")
    return 0 if r.converged else 1


# ---------------------------------------------------------------- reproduce / bench
def add_commands(commands) -> None:
    """Register ``reproduce paper``."""
    r = commands.add_parser("reproduce", help="reproduce a paper's tables and figures",
                            description="Reproduce the paper's section 4: both examples x ADMM1/ADMM2/SADMM x rho x h.")
    r.add_argument("target", choices=["paper"], help="paper: Tables 1-2 and Figs 1-4 of Yuan & Zhang (2023)")
    r.add_argument("--out", default="docs/results/paper", help="output folder (default docs/results/paper)")
    r.add_argument("--quick", action="store_true", help="h = 1/10 and 1/20 only (CI smoke test)")
    r.add_argument("--repeats", type=int, default=1, help="repeats per run, the median time is reported (default 1)")
    r.add_argument("--quiet", action="store_true", help="no progress lines")
    r.set_defaults(func=_reproduce)


def add_bench_parser(targets) -> None:
    """Register ``bench contact``."""
    b = targets.add_parser("contact", help="SADMM time / (one factorisation + solve of K), Ex. 1-2",
                           description="SADMM time against one sparse factorisation + solve of K.")
    b.add_argument("--out", default="docs/results/contact_speed.md", help="Markdown file to write")
    b.add_argument("--h", type=positive_float, action="append", default=None, dest="hs",
                   help="mesh size (repeatable; default 1/40 and 1/200)")
    b.add_argument("--repeats", type=int, default=3, help="repeats, median reported (default 3)")
    b.set_defaults(func=_bench)


def _reproduce(args) -> int:
    from .reproduce import PAPER_HS, run_reproduction
    if args.repeats < 1:
        raise ValueError(f"--repeats must be >= 1, got {args.repeats}")
    hs = (1 / 10, 1 / 20) if args.quick else PAPER_HS
    cmd = f"admmkit reproduce paper --out {args.out}" + (" --quick" if args.quick else "")
    run_reproduction(out=args.out, hs=hs, repeats=args.repeats, progress=not args.quiet, command=cmd)
    return 0


def _bench(args) -> int:
    from .bench import DEFAULT_HS, run_bench
    from .reproduce import h_label
    if args.repeats < 1:
        raise ValueError(f"--repeats must be >= 1, got {args.repeats}")
    hs = tuple(args.hs) if args.hs else DEFAULT_HS
    cmd = f"admmkit bench contact --out {args.out}" + "".join(f" --h {h_label(h)}" for h in args.hs or [])
    run_bench(out=args.out, hs=hs, repeats=args.repeats, command=cmd)
    return 0


if __name__ == "__main__":  # pragma: no cover
    from problems.cli import main
    sys.exit(main(sys.argv[1:]))
