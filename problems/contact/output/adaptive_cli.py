"""``admmkit solve contact --target-error E``: the adaptive loop, one line per level."""
from __future__ import annotations

import json
from dataclasses import asdict


def run_adaptive(args, scene, method_name: str) -> int:
    """Refine until the estimated relative energy error is <= --target-error; 0 only if it was reached."""
    from admmkit.cli.adaptive import adaptive_options
    from admmkit.io import write_text
    from admmkit.problems.contact.model.scene import Scene
    from admmkit.problems.contact.model.scene3d import Scene3D
    from admmkit.problems.contact.output.plot import figure_adapted
    from admmkit.problems.contact.solvers.adaptive import solve_adaptive
    from admmkit.problems.contact.solvers.adaptive_friction import check_adaptive_model
    options = adaptive_options(args)
    if args.mode not in ("auto", "condensed"):
        raise ValueError(f"--target-error runs every level in mode condensed, got --mode {args.mode}")
    if not isinstance(scene, (Scene, Scene3D)):
        raise ValueError(f"--target-error refines contact scenes (2D or 3D), got {type(scene).__name__}")
    try:
        check_adaptive_model(scene, options["estimator"])
    except ValueError as err:
        raise ValueError(f"--target-error: {err}") from None
    chosen = getattr(args, "adaptive_defaults", {})
    said = (["P2 (cheaper than P1 at every accuracy measured; --fe-order 1 for P1)"] if "order" in chosen else []) \
        + ([f"first mesh h = {'min(L, H) / 5' if hasattr(scene, 'L') else 'min(Lx, Ly, Lz) / 2'} = {chosen['h']:.6g} "
            f"(--h for another)"] if "h" in chosen else [])
    if said:
        where = "2D" if hasattr(scene, "L") else "3D"
        print("model        " + ", ".join(said) + f": the defaults of --target-error in {where}")
    print(f"adaptive     contact/{scene.name}: from h = {scene.h:.6g}, P{scene.order}, target {options['target']:g}, "
          f"theta {options['theta']:g}, gamma {options['gamma']:g}, {options['estimator']} estimator, {method_name}"
          + ("" if scene.tangential == "frictionless" else f", {scene.tangential}"))
    if scene.tangential == "coulomb":
        print("coulomb      alg.bound: of each level's last Tresca problem (s = mu p_n of the step before); the "
              "fixed point ends when s changes by <= 1e-4 or u by <= gamma x estimate (energy norm)")
    print("level    cells  unknowns  n_c   estimate  rel.estimate  alg.bound  iterations  seconds  status")
    count, files = iter(range(1, 10 ** 9)), []

    def show(level, out):
        k = next(count)
        if args.vtk:
            files.append(_level_vtu(args.vtk, k, out))
        print(f"{k:5d} {level.cells:8d} {level.unknowns:9d} {level.contact_nodes:4d}  {level.estimate:.3e}"
              f"  {level.relative_estimate:12.3e}  {level.algebraic_bound:9.2e}  {level.iterations:10d}"
              f"  {level.seconds:7.2f}  {level.status}"
              + (f" ({level.tresca_solves} Tresca solves)" if level.tresca_solves else ""), flush=True)
    out = solve_adaptive(scene, **options, method_name=method_name, rho=args.rho, max_iter=args.max_iter, log=show)
    print(f"status       {out.status}  ({out.message})")
    if files:
        print(f"vtk          {len(files)} levels: {files[0]} ... {files[-1]}")
    if args.plot and out.model is not None:
        last = out.levels[-1]
        title = f"{scene.name}: adapted mesh, {last.cells} triangles, {last.unknowns} unknowns"
        print(f"plot         {figure_adapted(out.model, out.result.x, out.result.lam, out.indicators, title, args.plot)}")
    if args.json:
        body = {"command": "solve contact --target-error", "scene": scene.name, "h0": scene.h, "order": scene.order,
                "tangential": scene.tangential,
                **options, "method": method_name,
                "status": out.status, "message": out.message, "levels": [asdict(level) for level in out.levels]}
        print(f"json         {write_text(args.json, json.dumps(body, indent=1) + chr(10))}")
    return 0 if out.reached else 1


def _level_vtu(base: str, k: int, out):
    """FILE_level<k>.vtu: displacement, contact fields and the indicator of level k (zz_indicator: whichever
    --estimator marked)."""
    from admmkit.cli import level_file
    from admmkit.problems.contact.output.export import boundary_fields, vtu_fields, write_vtu
    ops, res = out.model, out.result
    fields = vtu_fields(ops, boundary_fields(ops, res.x, res.lam, res.z))
    return write_vtu(level_file(base, k), ops, res.x, fields, cells={"zz_indicator": out.indicators})
