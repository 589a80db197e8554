"""``admmkit solve contact`` and ``admmkit demo`` (the studies of this plug-in are in benchmarks/).

    admmkit solve contact --scene ex1 --h 1/40 --method sadmm --rho 1e3 [--mode auto|full|condensed]
                          [--json FILE] [--csv FILE] [--plot FILE.png] [--vtk BASENAME]
    admmkit demo [--out out/demo]
"""
from __future__ import annotations

import json
from pathlib import Path

from admmkit.cli import add_stop_options, positive_float, progress_callback, stop_rule

from .methods import METHODS, method as resolve_method
from .problem import MODES


def register(subparsers) -> None:
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
        from .plot import figure_solution
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


def register_demo(commands) -> None:
    """Register ``demo``, the main job: the paper's two examples with SADMM."""
    d = commands.add_parser("demo", help="the main job: solve the paper's two examples with SADMM and plot them")
    d.add_argument("--out", default="out/demo", help="folder for the figures (default out/demo)")
    d.set_defaults(func=_demo)


def _demo(args) -> int:
    from .demo import run_demo
    return run_demo(args.out)
