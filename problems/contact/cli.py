"""``admmkit solve contact`` and ``admmkit demo`` (the studies of this plug-in are in benchmarks/).

    admmkit solve contact --scene ex1 --h 1/40 --policy sadmm --rho 1e3 [--mode auto|full|condensed|iterative]
                          [--tangential frictionless|stick|tresca|coulomb] [--mu MU] [--slip-bound S]
                          [--json FILE] [--csv FILE] [--plot FILE.png] [--vtk FILE.vtu] [-q]
    admmkit demo [--out out/demo]
"""
from __future__ import annotations

import functools
from pathlib import Path

from admmkit.cli.adaptive import add_adaptive_options, balance_gamma, balance_line, check_adaptive_flags, estimator_name
from admmkit.cli import (LazyHelp, add_common_options, add_output_file, add_result_outputs, exit_code,
                         positive_float, print_summary, progress, resolve_policy, stop_rule, write_history,
                         write_result_csv)

from admmkit.problems.contact.solvers.friction import TANGENTIAL
from admmkit.problems.contact.solvers.methods import METHODS
from admmkit.problems.contact.solvers.problem import MODES


def register(subparsers) -> None:
    """Register ``solve contact``."""
    p = subparsers.add_parser("contact", help="elastic contact with a rigid foundation, with or without friction "
                                              "(NGSolve, 2D and 3D)",
                              description="Solve a contact scene with ADMM1, ADMM2, SADMM or any penalty policy."
                                          "\n\ntypical: ~1 s for ex1 at h = 1/40 on a quiet machine (3.5 s at load "
                                          "5 on 2 cores, most of it importing ngsolve and scipy; no numba for a "
                                          "small body), 0.18 GB; the same scene again 37 % less CPU, 0.09 GB (its "
                                          "operators from the cache, no ngsolve; --no-cache bypasses it); "
                                          "~16 s for block3d_coulomb at h = 1/8, 0.3-0.4 GB; "
                                          "the time grows with the unknowns (bench scale: 1e6 in ~15 s "
                                          "with --mode iterative, 2.4 GB). needs: ngsolve; --mode iterative pyamg; "
                                          "--plot matplotlib; --vtk meshio (all installed with admmkit)")
    p.add_argument("--scene", default="ex1", metavar="NAME|FILE.toml", action=LazyHelp, help=_scene_help)
    p.add_argument("--h", type=positive_float, default=None,
                   help="mesh size, fractions allowed, 0 < h <= the scene's shorter side (default: the scene's; with --target-error, the first level's, "
                        "default min(L, H) / 5 on a 2D rectangle)")
    p.add_argument("--fe-order", type=int, choices=(1, 2), default=None,
                   help="polynomial order of the finite elements, P1 or P2 (default: the scene's; with "
                        "--target-error on a 2D scene P2, cheaper than P1 at every accuracy measured)")
    p.add_argument("--mode", choices=list(MODES), default="auto",
                   help="the x-step: full (sparse factorisation), condensed (dense, on Gamma_C), iterative "
                        "(AMG-preconditioned CG, for large meshes) or auto (default: the solver picks by size)")
    p.add_argument("--tangential", choices=list(TANGENTIAL), default=None,
                   help="tangential condition on Gamma_C (default: the scene's; docs/friction.md)")
    p.add_argument("--mu", default=None, metavar="MU",
                   help="Coulomb's friction coefficient mu >= 0 (with coulomb; overrides the scene's)")
    p.add_argument("--slip-bound", default=None, metavar="S",
                   help="Tresca's slip bound s >= 0, a number or an expression in x, y "
                        "(with tresca; overrides the scene's)")
    add_adaptive_options(p)    # --balance, --target-error (frictionless, mode condensed; docs/contact.md)
    # the stop is in the energy norm (docs/contact.md); --policy takes admm1, admm2, sadmm or a rule (order zx)
    add_common_options(p, policy="sadmm", order="zx", rho=1e3, methods=METHODS, max_iter=20_000)
    add_result_outputs(p, json_help="write the run as JSON: provenance (version, date, command, scene, policy, "
                                    "stop), summary, u on the free dofs with its map to mesh points, contact arrays",
                       csv_help="write the contact-boundary table x, y, u_n, g, gap, lam, p, active "
                                "(with friction also q, slip, s, zone)")
    add_output_file(p, "--plot", "FILE.png", "write the deformed body and the pressure/gap plot "
                    "(with friction also the tangential traction and the stick/slip zones; 2D scenes only)",
                    extensions=(".png",))
    p.add_argument("--magnify", type=positive_float, default=None,
                   help="displacement magnification in --plot (default 10 for ex1, 20 otherwise)")
    add_output_file(p, "--vtk", "FILE.vtu", "write a VTU file for ParaView and meshio: displacement at the "
                    "mesh vertices, contact pressure, gap and status on Gamma_C (with friction also the "
                    "tangential traction, slip and stick/slip zone)", extensions=(".vtu",))
    p.add_argument("--no-cache", action="store_true",
                   help="assemble the scene with NGSolve even when the operator cache holds it, and store nothing "
                        "(also ADMMKIT_NO_CACHE=1; the cache: ~/.cache/admmkit or ADMMKIT_CACHE_DIR, docs/contact.md)")
    p.set_defaults(func=run)


@functools.lru_cache(maxsize=1)
def _scene_names() -> tuple:
    """:func:`scene_names` as pairs, read once per process (the parser's help and ``--scene`` both ask)."""
    import tomllib
    from admmkit.problems.contact.model.scene import SCENES_DIR
    out = {}
    for path in sorted(SCENES_DIR.glob("*.toml")):
        data = tomllib.loads(path.read_text(encoding="utf-8"))
        data = data.get("scene", data)
        out[path.stem] = f"{data.get('dim', 2)}-D, {data.get('tangential', 'frictionless')}"
    return tuple(out.items())


def _scene_help() -> str:
    """``--scene``'s help: every bundled scene (read from their files when the help is shown, not for a run)."""
    scenes = ", ".join(f"{name} ({kind})" for name, kind in scene_names().items())
    return (f"a scene of problems/contact/scenes: {scenes}; or the path of a scene TOML file (docs/scenes.md) "
            f"(default ex1)")


def scene_names() -> dict[str, str]:
    """{name: "2-D, frictionless", ...} of every scene file in problems/contact/scenes (dimension, tangential law)."""
    return dict(_scene_names())


def scene_file(name: str) -> Path:
    """The TOML file of ``--scene``: a file path, or a name in problems/contact/scenes; ValueError naming --scene."""
    from admmkit.cli import did_you_mean
    from admmkit.problems.contact.model.scene import SCENES_DIR
    path = Path(name)
    if path.is_dir():
        raise ValueError(f"--scene: {name!r} is a directory, not a TOML scene file")
    if path.is_file():
        return path
    bundled = SCENES_DIR / f"{name}.toml"
    if "/" not in name and "\\" not in name and bundled.is_file():
        return bundled
    known = scene_names()
    if path.suffix or "/" in name or "\\" in name:      # it looks like a file: say that it is not there
        raise ValueError(f"--scene: no such scene file {name}")
    raise ValueError(f"--scene: unknown scene {name!r}; give one of {', '.join(known)} or the path of a TOML "
                     f"scene file{did_you_mean(name, known)}")


def _scene(args):
    from admmkit.problems.contact.output.cli_output import apply_friction_options
    from admmkit.problems.contact.model.scene_file import load_scene
    name = str(args.scene)
    path = scene_file(name)

    def shown(err) -> str:                                        # a bundled scene by its name, not its path
        return str(err).replace(f"{path}: ", "")
    changes = {key: value for key, value in (("h", args.h), ("order", args.fe_order)) if value is not None}
    try:
        scene = load_scene(path, **changes)
    except ValueError as err:
        if changes and _loads(path):                              # the file loads as it is: the options are to blame
            given = " ".join(f for f, v in (("--h", args.h), ("--fe-order", args.fe_order)) if v is not None)
            raise ValueError(f"{given}: {shown(err)} (scene {name})") from None
        raise ValueError(f"--scene {name}: {shown(err)}") from None
    args.adaptive_defaults = _adaptive_defaults(args, scene)
    if args.adaptive_defaults:
        try:
            scene = load_scene(path, **(changes | args.adaptive_defaults))
        except ValueError as err:
            raise ValueError(f"--target-error on scene {name}: {shown(err)}") from None
    if args.plot and not hasattr(scene, "L"):
        raise ValueError(f"--plot draws 2D scenes only; {scene.name or name} is a 3D scene (dim = 3): "
                         f"write --vtk FILE.vtu and open it in ParaView")
    return apply_friction_options(scene, args)


def _loads(path) -> bool:
    """Whether the scene file ``path`` loads as it is (without --h or --fe-order)."""
    from admmkit.problems.contact.model.scene_file import load_scene
    try:
        load_scene(path)
    except ValueError:
        return False
    return True


def _adaptive_defaults(args, scene) -> dict:
    """``--target-error`` on a 2D scene: accuracy in, cheapest model out; what ``--fe-order`` and ``--h`` left open.

    * P2 without ``--fe-order``: ``bench adaptive`` (docs/results/adaptive_study) measured P2 cheaper than P1
      at every error both reach (Example 1 at 1.6e-2: 1,883 against 18,287 unknowns; Hertz at 3.3e-2: 1,038
      against 17,332), and P1 does not reach 1e-3 on Example 1 within 2e6 unknowns;
    * without ``--h``, a rectangle starts from five cells across its thinner side, h = min(L, H) / 5: the
      levels put the unknowns where the error is, not the scene's uniform h.

    In 3D the same two choices, for the same reason, measured on the 3D block: P2 (from h = 1/2 the frictionless
    block reaches 0.05 with 21,888 P2 unknowns where P1 from h = 1/8 reaches 0.12 with 38,682, and each level's
    factorisation grows with the unknowns), and a block starts from two cells across its thinnest side,
    h = min(Lx, Ly, Lz) / 2 (docs/contact.md).
    """
    if args.target_error is None:
        return {}
    changes = {"order": 2} if args.fe_order is None and scene.order == 1 else {}
    if not hasattr(scene, "L"):                                   # a 3D block
        if args.h is None:
            changes["h"] = min(scene.Lx, scene.Ly, scene.Lz) / 2
        return changes
    if args.h is None and scene.geometry is None:
        changes["h"] = min(scene.L, scene.H) / 5
    return changes


def run(args) -> int:
    """Build the scene, solve it, print the summary and write the requested files; 0 only if converged."""
    from admmkit.problems.contact.output.cli_output import csv_columns, friction_line
    from admmkit.problems.contact.output.export import boundary_fields, vtu_fields, write_json, write_vtu
    from admmkit.problems.contact.solvers.methods import solve_scene

    order, _, name = resolve_policy(args)          # refuses an unknown --policy before anything is built
    estimator = estimator_name(args)               # and an unknown --estimator
    check_adaptive_flags(args)                     # and --theta, --max-levels, --max-unknowns without --target-error
    stop = stop_rule(args)
    if args.target_error is not None:
        from admmkit.problems.contact.output.adaptive_cli import run_adaptive
        return run_adaptive(args, _scene(args), name)
    gamma = balance_gamma(args, None)
    if gamma is not None and args.mode not in ("auto", "condensed"):
        raise ValueError(f"--balance needs --mode condensed (its bound lives on Gamma_C), got --mode {args.mode}")
    scene = _scene(args)
    if gamma is not None and estimator != "zz":    # the stop compares with the residual estimate: built here
        from admmkit.problems.contact.solvers.estimate import balanced_residual_stop
        model, stop, gamma_arg = *balanced_residual_stop(scene, gamma), None
    else:
        mode = "condensed" if gamma else args.mode
        model, stop, gamma_arg = _operators(args, scene, mode), (None if gamma else stop), gamma
    with progress(args, args.max_iter) as show:
        sol = solve_scene(model, name, args.rho, mode="condensed" if gamma else args.mode,
                          stop=stop, max_iter=args.max_iter, order=order, callback=show, balance=gamma_arg)
    stop = sol.stop
    ops, r = sol.ops, sol.result
    args.resolved = {"policy": name, "order": r.order, "policy_repr": r.policy, "stop": stop.name}
    cells = "tetrahedra" if ops.dim == 3 else "triangles"
    print(f"problem      contact/{scene.name or args.scene}: h = {scene.h:.6g}, P{scene.order} {scene.mesh_kind}, "
          f"{ops.n_cells} {cells}, tangential {scene.tangential}")
    print(f"size         n_free {ops.n_free}   n_c {ops.n_c}   mode {sol.mode}   setup {sol.setup_time:.4f} s")
    print_summary(r, name, args.rho)
    if gamma is not None:
        print(balance_line(stop, "energy norm"))
    if sol.coulomb is not None:
        print(f"coulomb      {sol.coulomb.summary()}")
    fields = boundary_fields(ops, r.x, r.lam, r.z)
    active = int(fields["contact_status"].sum())
    print(f"contact      force {float(ops.mc @ fields['contact_pressure']):.6g}   active nodes {active}/{ops.n_c} "
          f"(p = g: on the obstacle after the last z-step)   max u_n {fields['normal_displacement'].max():.4e}")
    line = friction_line(sol, fields)
    if line:
        print(line)
    write_history(r.history, args)
    if args.json:
        print(f"json         {write_json(args.json, sol, args)}")
    if args.csv:
        print(f"csv          {write_result_csv(args.csv, csv_columns(sol, fields))}")
    if args.plot:
        from admmkit.problems.contact.output.plot import figure_solution
        magnify = args.magnify or (10.0 if scene.name.startswith("example1") else 20.0)
        figure_solution(ops, r.x, fields["contact_pressure"], magnify,
                        f"{scene.name or args.scene}: {name}, rho_0 = {args.rho:g}, h = {scene.h:.4g}, "
                        f"u x{magnify:g}", args.plot, p=r.z[:ops.n_c], friction=fields)
        print(f"plot         {args.plot}")
    if args.vtk:
        print(f"vtk          {write_vtu(args.vtk, ops, r.x, vtu_fields(ops, fields))}")
    return exit_code(r) if sol.converged else 1   # with Coulomb friction: the outer fixed point too


def _operators(args, scene, mode: str):
    """The scene's operators through the operator cache (model/operator_cache.py): read back without NGSolve when
    a run before stored them, else assembled (and stored); a 3D scene, or ``--no-cache``, as it is (assembled by
    solve_scene). The memory check of an explicit mode comes first, as solve_scene does it for a scene. ``mode``:
    the one solve_scene is given (with the condensed one, the entry also holds the set-up's order)."""
    from admmkit.problems.contact.model.operator_cache import cacheable, cached_operators
    from admmkit.problems.contact.model.memory import check_memory
    if args.no_cache or not cacheable(scene):
        return scene
    if args.mode in ("full", "condensed", "iterative"):
        check_memory(scene, args.mode)
    return cached_operators(scene, scene_file(str(args.scene)), mode=mode)


def register_demo(commands) -> None:
    """Register ``demo``, the main job: the paper's two examples with SADMM."""
    d = commands.add_parser("demo", help="the main job: solve the paper's two examples with SADMM and plot them",
                            description="Solve the paper's Examples 1 and 2 (Yuan & Zhang 2023) with SADMM and "
                                        "write their figures to --out.\n\ntypical: ~18 s on 2 cores, 0.4 GB. "
                                        "needs: ngsolve, matplotlib (installed with admmkit)")
    d.add_argument("--out", default="out/demo", help="folder for the figures (default out/demo)")
    d.set_defaults(func=_demo)


def _demo(args) -> int:
    from .demo import run_demo
    return run_demo(args.out)
