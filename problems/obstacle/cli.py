"""``admmkit solve obstacle``: a named obstacle scene, solved and checked."""
from __future__ import annotations

from admmkit.cli.adaptive import (adaptive_options, add_adaptive_options, balance_gamma, balance_line,
                                  check_adaptive_flags, estimator_name)
from admmkit.cli import (add_common_options, add_output_file, add_result_outputs, exit_code, level_file,
                         positive_float, run_solve, set_help, write_result_csv, write_result_json)
from admmkit.linalg.sparse_backends import AUTO_ORDER, available_backends
from admmkit.policies.paper_methods import PAPER_METHODS

from .estimate import OBSTACLE_GAMMA, BalancedStop
from .plot import plot_solution
from .discrete import make_problem
from .problem import DEFAULT_BACKEND
from .xstep import ADAPTIVE_BACKEND
from .scene import A_STAR, SCENES, has_radial_exact, max_h
from .scene_file import known_scenes, load_scene

#: ``--backend``: the sparse factorisations of admmkit.linalg.linsolve, and the two CG x-steps (problems/obstacle/xstep.py)
SPARSE = ("auto", *AUTO_ORDER)
BACKENDS = (*SPARSE, "iterative", "jacobi")


def register(subparsers) -> None:
    """Register ``solve obstacle``."""
    p = subparsers.add_parser("obstacle", help="-Delta u = f, u >= psi, u = u_D (P1 or P2, NGSolve)",
                              description="Solve an obstacle problem -Delta u = f, u >= psi, u = u_D on a named scene "
                                          "or a TOML scene file, and check it against its exact solution where it has one."
                                          "\n\ntypical: ~12 s at the default h = 1/16 on 2 cores, most of it "
                                          "start-up (imports, compiled kernels), 0.3 GB. needs: ngsolve (installed "
                                          "with admmkit); --plot matplotlib")
    p.add_argument("--scene", default="radial",
                   help=f"a scene by name ({', '.join(SCENES)} built in; --list-scenes for all) or the path of a "
                        f"TOML scene file (docs/obstacle.md, 'Your own obstacle'; default radial)")
    p.add_argument("--list-scenes", action="store_true", help="list the scenes known by name and exit")
    p.add_argument("--h", type=positive_float, default=None,
                   help="cell size, fractions allowed (default: 1/16 for a built-in scene, a file's own h; with "
                        "--target-error the first level's, default a fifth of the box's shorter side)")
    p.add_argument("--fe-order", type=int, choices=(1, 2), default=None,
                   help="P1 or P2 elements (default P1; with --target-error P2, unless --estimator residual, which "
                        "is P1 only)")
    p.add_argument("--backend", default=None, choices=BACKENDS, metavar="NAME",
                   help=f"the x-step's solver of K + rho M: a sparse factorisation, {', '.join(SPARSE)} (auto: the "
                        f"fastest installed; installed here: {', '.join(available_backends())}), or iterative "
                        f"(AMG-preconditioned CG) or jacobi (Jacobi-preconditioned CG with a factorisation where CG "
                        f"is dear) (default {DEFAULT_BACKEND}; {ADAPTIVE_BACKEND} with --target-error in P1)")
    add_output_file(p, "--plot", "FILE.png", "write a plot of u, psi and the contact set (PNG)", extensions=(".png",))
    add_output_file(p, "--vtk", "FILE.vtu", "write u, psi, the contact set and the --estimator's indicator per triangle as VTU "
                    "(with --target-error one file per level, FILE_level<k>.vtu)", extensions=(".vtu",))
    add_adaptive_options(p, max_levels=30, gamma=OBSTACLE_GAMMA, default_stop=True)   # --balance, --target-error
    add_common_options(p, policy="summable", order="zx", methods=PAPER_METHODS)
    add_result_outputs(p, json_help="write the run (provenance, scene, summary, errors, u on the free nodes) as JSON",
                       csv_help="write one row per free node: x, y, u, psi, in_contact")
    set_help(p, tol="relative-change tolerance > 0 in the problem's norm (the paper's rule); default: none, the "
                    f"run stops balanced (--balance {OBSTACLE_GAMMA:g}) unless --tol or --eps-abs is given",
             balance="stop when a guaranteed bound of the algebraic error is below GAMMA x the estimated "
                     "discretisation error, 0 < GAMMA <= 1; the default stop of solve obstacle, with GAMMA = "
                     f"{OBSTACLE_GAMMA:g}, unless --tol or --eps-abs is given")
    p.set_defaults(func=run)


def list_scenes() -> int:
    """``--list-scenes``: one line per scene known by name."""
    for name, origin in known_scenes().items():
        print(f"{name:10s} {origin}")
    return 0


def scene_of(args, h_default=None):
    """The scene of ``--scene`` (a name or a TOML file) with cell size ``--h``, else ``h_default(scene)`` where
    given; ValueError naming ``--scene`` or ``--h`` and the accepted range."""
    try:
        scene = load_scene(args.scene)
    except ValueError as err:
        raise ValueError(f"--scene {args.scene}: {err}") from None
    h = args.h if args.h is not None else (h_default(scene) if h_default else None)
    if h is None:
        return scene
    if h > max_h(scene.box):
        x0, x1, y0, y1 = scene.box
        raise ValueError(f"--h: h = {h:g} is larger than the domain allows; accepted 0 < h <= {max_h(scene.box):.6g} "
                         f"for the scene {scene.name or args.scene} on ({x0:g}, {x1:g}) x ({y0:g}, {y1:g}): two "
                         f"squares across its shorter side, so that it has an interior node (e.g. --h 1/16)")
    try:
        return scene.with_h(h)
    except ValueError as err:
        raise ValueError(f"--h: h = {h:g}: {err}") from None


def run(args) -> int:
    """Build the scene, solve it, print the summary and the errors against the exact solution; 0 only if converged."""
    if args.list_scenes:
        return list_scenes()
    check_adaptive_flags(args)
    gamma = balance_gamma(args, OBSTACLE_GAMMA)      # the balanced stop is the default here
    estimator = estimator_name(args)
    if args.target_error is not None:
        return run_adaptive(args)
    scene = scene_of(args, h_default=lambda s: 1 / 16 if args.scene in SCENES else None)
    args.h = scene.h
    problem = make_problem(scene, backend=args.backend or DEFAULT_BACKEND, fe_order=args.fe_order or 1)
    nx, ny = problem.scene.counts
    print(f"problem      obstacle/{scene.name or args.scene}: h = {args.h:.6g} ({nx} x {ny} squares), "
          f"P{problem.order}, {problem.n} free nodes, side {problem.scene.side}")
    stop = None if gamma is None else BalancedStop(problem, gamma, estimator=estimator)
    result = run_solve(problem, args, stop=stop)
    if stop is not None:
        print(balance_line(stop, "H1 seminorm"))
    contact = problem.contact_set(result.z)
    print(f"contact set  {int(contact.sum())} nodes, area {problem.contact_area(result.z):.6g}")
    err = radius = None
    if problem.scene.exact is not None:
        err = problem.errors(result.x)
        print(f"errors       L2 {err['L2']:.4e}   H1 {err['H1']:.4e}   H1-seminorm {err['H1_semi']:.4e}")
    if has_radial_exact(problem.scene):
        radius = problem.contact_radius(result.z)
        print(f"free bdry    radius {radius:.6f} (sqrt(area/pi))   exact a* = {A_STAR:.6f}   "
              f"difference {radius - A_STAR:+.3e}")
    if args.plot:
        print(f"plot         {plot_solution(problem, result.x, result.z, args.plot)}")
    if args.vtk:
        from .estimate import estimator_of
        from .export import write_vtu
        print(f"vtk          {write_vtu(args.vtk, problem, result.z, estimator_of(problem, estimator)(result.z))}")
    if args.json:
        scene = {"name": args.scene, "h": args.h, "counts": [nx, ny], "side": problem.scene.side,
                 "backend": args.backend or DEFAULT_BACKEND, "n_free": problem.n}
        arrays = {"u": result.x, "z": result.z, "lam": result.lam, "free_nodes": problem.free,
                  "node_xy": problem.nodes[problem.free]}
        extra = {"contact_nodes": int(contact.sum()), "errors": err, "contact_radius": radius}
        if stop is not None:
            extra["balance"] = {"gamma": stop.gamma, "algebraic_bound": stop.algebraic,
                                "discretisation_estimate": stop.discretisation}
        print(f"json         {write_result_json(args.json, result, args, problem=scene | extra, arrays=arrays)}")
    if args.csv:
        xy = problem.nodes[problem.free]
        columns = {"node": problem.free, "x": xy[:, 0], "y": xy[:, 1], "u": result.x, "psi": problem.psi,
                   "in_contact": contact.astype(int)}
        print(f"csv          {write_result_csv(args.csv, columns)}")
    return exit_code(result)


def run_adaptive(args) -> int:
    """``--target-error``: the adaptive loop, one line per level; 0 only if the target was reached."""
    from admmkit.cli import resolve_policy
    from .adaptive import solve_adaptive
    from .plot import plot_adapted
    options = adaptive_options(args, OBSTACLE_GAMMA)      # the loop's options not given: their defaults
    order, policy, name = resolve_policy(args)
    chosen = []
    if args.fe_order is None:           # accuracy in, cheapest model out: P2 (docs/obstacle.md)
        args.fe_order = 2 if options["estimator"] == "zz" else 1
        chosen.append(f"P{args.fe_order} ({'--fe-order 1 for P1' if args.fe_order == 2 else 'the residual estimator is P1 only'})")
    if args.h is None:
        scene = scene_of(args, h_default=lambda s: min(s.box[1] - s.box[0], s.box[3] - s.box[2]) / 5)
        chosen.append(f"first mesh h = {scene.h:.6g}, a fifth of the box's shorter side (--h for another)")
    else:
        scene = scene_of(args)
    args.h = scene.h
    if chosen:
        print("model        " + ", ".join(chosen) + ": the defaults of --target-error")
    print(f"adaptive     obstacle/{scene.name or args.scene}: from h = {args.h:.6g}, P{args.fe_order}, "
          f"target {options['target']:g}, "
          f"theta {options['theta']:g}, gamma {options['gamma']:g}, {options['estimator']} estimator, {name} order {order}")
    print("level    cells  unknowns   estimate  rel.estimate  H1-semi error  iterations  seconds  status")

    def show(level, out):
        if args.vtk:
            from .export import write_vtu
            files.append(write_vtu(level_file(args.vtk, show.k), out.model, out.result.z, out.indicators))
        err = f"{level.errors['H1_semi']:.3e}" if level.errors else "-"
        print(f"{show.k:5d} {level.cells:8d} {level.unknowns:9d}  {level.estimate:.3e}  {level.relative_estimate:12.3e}"
              f"  {err:>13s}  {level.iterations:10d}  {level.seconds:7.2f}  {level.status}", flush=True)
        show.k += 1
    show.k, files = 1, []
    out = solve_adaptive(scene, **options, policy=policy, order=order, rho=args.rho, max_iter=args.max_iter,
                         backend=args.backend, fe_order=args.fe_order, log=show)
    print(f"status       {out.status}  ({out.message})")
    if files:
        print(f"vtk          {len(files)} levels: {files[0]} ... {files[-1]}")
    if args.plot and out.model is not None:
        print(f"plot         {plot_adapted(out.model, out.indicators, out.result.z, args.plot)}")
    if args.json:
        import json
        from dataclasses import asdict
        from admmkit.io import write_text
        body = {"command": "solve obstacle --target-error", "scene": args.scene, "h0": args.h, "fe_order": args.fe_order,
                **options, "status": out.status,
                "message": out.message, "levels": [asdict(level) for level in out.levels]}
        print(f"json         {write_text(args.json, json.dumps(body, indent=1, default=float) + chr(10))}")
    return 0 if out.reached else 1
