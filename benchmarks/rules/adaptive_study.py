"""``admmkit bench adaptive``: adaptive against uniform refinement, at the same true error.

Scenes (``SCENES``): contact Example 1 in P1 and P2 and the radial
obstacle (P1).  For each:

- **adaptive**: every level of ``solve_adaptive`` (ZZ estimator, Dörfler
  theta 0.5, balanced stop gamma 0.1, warm start), from the scene's coarse
  mesh to a target estimate; the wall time is cumulative over the levels
  (meshing, assembly, refinement, solve and estimate; the time spent here
  computing the true error and the cold starts is left out);
- **uniform**: a sequence of h, each mesh solved once, cold, with the same
  balanced stop (``solve_adaptive`` capped at one level); its wall time is
  that one solve's, not the sum over the coarser meshes (in uniform
  refinement's favour).  The obstacle also with today's stop
  (``RelativeChange(1e-5)``, as ``admmkit solve obstacle --balance off``), with
  the plug-in's default x-step (SuperLU) and with AMG-preconditioned CG
  (``--backend iterative``).  The adaptive obstacle's x-step is Jacobi-CG
  (``problems/obstacle/xstep.py``); the uniform cold solves keep SuperLU.

The true relative energy error of every level and mesh:

- **radial obstacle**: ``|u - u_h|_{H1} / |u|_{H1}`` against the exact
  solution;
- **contact**: ``sqrt(2 (J(u_h) - J_ref)) / ||u||_a`` (as in
  ``admmkit bench estimators``: J(v) - J(u) >= ||v - u||_a^2 / 2 for a
  feasible v), J_ref extrapolated from a P2 adaptive solve to a tight target
  (gamma 0.01), extrapolated from its two finest levels with J_k - J_ref =
  C N_k^-p, p twice the estimate's rate over its five finest levels
  (:func:`reference`).

The report (tables, ratios, rates, charts): ``adaptive_report.py``.
"""
from __future__ import annotations

import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import admmkit
from admmkit.benchmarks.runner.options import print_files

OBSTACLE_UNIFORM_N = (16, 32, 64, 128, 256, 512)          # h = 4/N on (-2, 2)^2
#: the obstacle's uniform meshes with today's stop, by the x-step: the plug-in's default (a SuperLU
#: factorisation per rho) and AMG-preconditioned CG (backend "iterative"), the faster on fine uniform meshes
DEFAULT_BACKEND = "superlu"
TODAY_BACKENDS = {"uniform_today": DEFAULT_BACKEND, "uniform_today_amg": "iterative"}
CONTACT_UNIFORM_H = {1: (5, 10, 20, 40, 80, 160, 320), 2: (5, 10, 20, 40, 80, 160)}   # h = 1/value
# (scene, order): the adaptive target; "reference": each contact scene's reference target
FULL = {"obstacle_target": 5e-3, "contact_target": {("ex1", 1): 1e-2, ("ex1", 2): 3e-4, ("ex2", 2): 1e-3},
        "reference_target": {"ex1": 5e-5, "ex2": 1e-4}}
QUICK = {"obstacle_target": 8e-2, "contact_target": {("ex1", 1): 6e-2, ("ex1", 2): 1e-2, ("ex2", 2): 3e-2},
         "reference_target": {"ex1": 2e-3, "ex2": 5e-3}}
CONTACT_NAMES = {"ex1": "Example 1", "ex2": "Example 2"}
QUICK_CUT = 3                                             # the three coarsest uniform meshes


def _row(scene, order, method, level, h, unknowns, relative_estimate, estimate, true_error, absolute_error,
         iterations, seconds, wall, status, cold_iterations=None) -> dict:
    row = {"scene": scene, "order": order, "method": method, "level": level, "h": h, "unknowns": unknowns,
           "relative_estimate": relative_estimate, "true_error": true_error,
           "effectivity": estimate / absolute_error if absolute_error > 0 else math.inf,
           "iterations": iterations, "cold_iterations": iterations if cold_iterations is None else cold_iterations,
           "seconds": seconds, "wall_seconds": wall, "status": status}
    print(f"  {scene:9s} P{order} {method:14s} {level:2d}  n = {unknowns:7d}  est {relative_estimate:.3e}  "
          f"true {true_error:.3e}  eff {row['effectivity']:.2f}  it {iterations:4d} (cold {row['cold_iterations']:4d})"
          f"  wall {wall:7.2f} s", flush=True)
    return row


class _Clock:
    """Wall time since start, less the time spent in the study's own callbacks (the true error)."""

    def __init__(self):
        self.start, self.excluded = time.perf_counter(), 0.0

    def now(self) -> float:
        """Seconds so far, without the excluded ones."""
        return time.perf_counter() - self.start - self.excluded


def _uniform(solve_adaptive, scene, measure, **options):
    """One mesh, one level, cold: its Level, the wall time to the level's end, and ``measure(model, result)``.

    Taken in the level's callback: after it the loop refines the mesh, which a uniform solve does not need.
    """
    got, t0 = {}, time.perf_counter()

    def log(level, out):
        got["wall"] = time.perf_counter() - t0
        got["level"], got["value"] = level, measure(out.model, out.result)
    solve_adaptive(scene, 1e-9, max_levels=1, log=log, **options)
    return got["level"], got["wall"], got["value"]


# ---------------------------------------------------------------------------------------------------- obstacle
def obstacle_rows(target: float, meshes=OBSTACLE_UNIFORM_N) -> list[dict]:
    """Adaptive and uniform (balanced stop and today's stop) rows of the radial obstacle."""
    from admmkit.problems.obstacle import ObstacleProblem, radial
    from admmkit.problems.obstacle.adaptive import solve_adaptive
    norm = _radial_norm(ObstacleProblem(radial(h=4 / 128)).mesh)
    rows, clock = [], _Clock()
    scene = lambda N: replace(radial(h=4 / N), exact=None)      # noqa: E731  (the error is computed here, untimed)

    def log(level, out):
        t0 = time.perf_counter()
        cold, error = _cold_obstacle(out.model), _h1_error(out.model, out.result.z)
        clock.excluded += time.perf_counter() - t0
        rows.append(_row("obstacle", 1, "adaptive", len(rows) + 1, math.nan, level.unknowns,
                         level.relative_estimate, level.estimate, error / norm, error, level.iterations,
                         level.seconds, clock.now(), level.status, cold))
    solve_adaptive(scene(8), target, max_levels=40, log=log)
    for i, N in enumerate(meshes):       # a cold start from rho 1: the plug-in's default, a factorisation per rho
        level, wall, error = _uniform(solve_adaptive, scene(N), lambda model, res: _h1_error(model, res.z),
                                      backend=DEFAULT_BACKEND)
        rows.append(_row("obstacle", 1, "uniform", i + 1, 4 / N, level.unknowns, level.relative_estimate,
                         level.estimate, error / norm, error, level.iterations, level.seconds, wall, level.status))
    for method, backend in TODAY_BACKENDS.items():
        for i, N in enumerate(meshes):
            rows.append(_obstacle_today(scene(N), i + 1, norm, method, backend))
    return rows


def _obstacle_today(scene, index: int, norm: float, method: str = "uniform_today",
                    backend: str = DEFAULT_BACKEND) -> dict:
    """One uniform mesh solved with today's stop (RelativeChange 1e-5, summable rule, order zx, rho 1)."""
    from admmkit.problems.obstacle import ObstacleProblem
    from admmkit.problems.obstacle.estimate import estimator_of
    t0 = time.perf_counter()
    problem = ObstacleProblem(scene, backend=backend)
    res = admmkit.solve(problem, rho=1.0, policy="summable", order="zx", stop=admmkit.RelativeChange(1e-5),
                        max_iter=10_000)
    wall = time.perf_counter() - t0
    estimate = float(math.sqrt(sum(estimator_of(problem, "zz")(res.z) ** 2)))
    error = _h1_error(problem, res.z)
    return _row("obstacle", 1, method, index, scene.h, problem.n, estimate / norm, estimate, error / norm,
                error, res.iterations, wall, wall, res.status.value)


def _h1_error(problem, z) -> float:
    """``|u - u_h|_{H1}`` against the exact radial solution (as ``ObstacleProblem.errors``)."""
    import ngsolve as ng
    from admmkit.problems.obstacle.scene import radial_exact_cf
    _, grad = radial_exact_cf()
    d = ng.grad(problem.gridfunction(z)) - grad
    return math.sqrt(max(ng.Integrate(ng.InnerProduct(d, d) * ng.dx(bonus_intorder=6), problem.mesh), 0.0))


def _cold_obstacle(problem) -> int:
    """Iterations of a cold start on an adaptive level (the same stop, rule and rho_0 as solve_adaptive's)."""
    from admmkit.problems.obstacle.estimate import BalancedStop
    return admmkit.solve(problem, rho=1.0, policy="summable", order="zx", stop=BalancedStop(problem, 0.1),
                         max_iter=10_000).iterations


def _cold_contact(ops) -> int:
    """Iterations of a cold start on an adaptive level (mode condensed, SADMM, rho_0 1e3, the same stop)."""
    from admmkit.problems.contact.solvers.estimate import BalancedStop
    from admmkit.problems.contact.solvers.methods import method
    from admmkit.problems.contact.solvers.problem import contact_problem
    problem = contact_problem(ops, mode="condensed")
    order, policy = method("sadmm")
    return admmkit.solve(problem, rho=1e3, policy=policy, order=order, stop=BalancedStop(problem, 0.1),
                         max_iter=20_000).iterations


def _radial_norm(mesh) -> float:
    """``|u|_{H1}`` of the exact radial solution, integrated on a fine mesh."""
    import ngsolve as ng
    from admmkit.problems.obstacle.scene import radial_exact_cf
    _, grad = radial_exact_cf()
    return math.sqrt(ng.Integrate(ng.InnerProduct(grad, grad) * ng.dx(bonus_intorder=6), mesh))


# ----------------------------------------------------------------------------------------------------- contact
def _energy(ops, u) -> float:
    return float(0.5 * u @ (ops.K @ u) - ops.f @ u)


def _contact_scene(name: str, h: float, order: int):
    from admmkit.problems.contact import example1, example2
    return {"ex1": example1, "ex2": example2}[name](h=h, order=order)


def reference(target: float, name: str = "ex1") -> dict:
    """J_ref of contact Example 1 or 2 (``name``): P2 adaptive to ``target`` (gamma 0.01), the energy extrapolated.

    Returns J_ref, ``norm`` = ||u||_a (of the finest solve), the finest level's unknowns, relative estimate and
    energy, and ``own_error``: the relative energy error of the finest solve against J_ref (the extrapolation's
    correction), the reference's own accuracy.
    """
    from admmkit.problems.contact.solvers.adaptive import solve_adaptive
    levels = []

    def log(level, out):
        u = out.result.x
        levels.append((level.unknowns, _energy(out.model, u), float(math.sqrt(u @ (out.model.K @ u))),
                       level.relative_estimate))
    t0 = time.perf_counter()
    out = solve_adaptive(_contact_scene(name, 1 / 5, 2), target, gamma=0.01, max_levels=60, log=log)
    (n1, j1, _, _), (n2, j2, _, _), (n3, j3, norm, rel) = levels[-3:]
    tail = levels[-5:]          # p: twice the estimate's rate (the energy error is the squared energy-norm error)
    p = -2 * float(np.polyfit(np.log([t[0] for t in tail]), np.log([t[3] for t in tail]), 1)[0])
    p = min(max(p, 0.5), 4.0)
    p_energy = math.log((j1 - j2) / (j2 - j3)) / math.log(n2 / n1) if j1 > j2 > j3 else math.nan
    j_ref = j3 - (max(j2 - j3, 0.0) / ((n3 / n2) ** p - 1.0))
    own = math.sqrt(2 * max(j3 - j_ref, 0.0)) / norm
    print(f"  {name} reference: P2 adaptive to {target:g} ({out.status}), {n3} unknowns, estimate {rel:.2e}, "
          f"energy rate p = {p:.2f} (from the energies {p_energy:.2f}), own error {own:.2e}, {time.perf_counter() - t0:.1f} s", flush=True)
    return {"J_ref": j_ref, "norm": norm, "unknowns": n3, "relative_estimate": rel, "J_finest": j3, "p": p, "p_energy": p_energy,
            "own_error": own, "status": out.status, "target": target, "scene": CONTACT_NAMES[name]}


def contact_rows(order: int, target: float, ref: dict, meshes, name: str = "ex1") -> list[dict]:
    """Adaptive and uniform rows of contact Example 1 or 2 (``name``) in P``order``."""
    from admmkit.problems.contact.solvers.adaptive import solve_adaptive
    rows, clock = [], _Clock()

    def true_error(ops, u):
        absolute = math.sqrt(2 * max(_energy(ops, u) - ref["J_ref"], 0.0))
        return absolute / ref["norm"], absolute

    def log(level, out):
        t0 = time.perf_counter()
        rel, absolute = true_error(out.model, out.result.x)
        cold = _cold_contact(out.model)
        clock.excluded += time.perf_counter() - t0
        rows.append(_row(name, order, "adaptive", len(rows) + 1, math.nan, level.unknowns, level.relative_estimate,
                         level.estimate, rel, absolute, level.iterations, level.seconds, clock.now(), level.status,
                         cold))
    solve_adaptive(_contact_scene(name, 1 / 5, order), target, max_levels=60, log=log)
    for i, n in enumerate(meshes):
        level, wall, (rel, absolute) = _uniform(solve_adaptive, _contact_scene(name, 1 / n, order),
                                                lambda model, res: true_error(model, res.x))
        rows.append(_row(name, order, "uniform", i + 1, 1 / n, level.unknowns, level.relative_estimate,
                         level.estimate, rel, absolute, level.iterations, level.seconds, wall, level.status))
    return rows


def run(out: Path, command: str, quick: bool = False) -> list[Path]:
    """Run the study; write adaptive.csv, adaptive.md and the charts to ``out``."""
    from admmkit.benchmarks.rules.adaptive_report import write_report
    setting = QUICK if quick else FULL
    cut = QUICK_CUT if quick else None
    print("adaptive against uniform refinement:", flush=True)
    refs = {name: reference(target, name) for name, target in setting["reference_target"].items()}
    rows = obstacle_rows(setting["obstacle_target"], OBSTACLE_UNIFORM_N[:cut])
    for (name, order), target in setting["contact_target"].items():
        rows += contact_rows(order, target, refs[name], CONTACT_UNIFORM_H[order][:cut], name)
    return write_report(Path(out), rows, list(refs.values()), command, quick)


def register(targets) -> None:
    """``admmkit bench adaptive``."""
    b = targets.add_parser("adaptive", help="adaptive against uniform refinement at the same true error "
                                            "(contact Example 1 P1/P2, radial obstacle)",
                           description="Unknowns, wall time, rates, effectivity and iterations of adaptive and "
                                       "uniform refinement (benchmarks/rules/adaptive_study.py).")
    b.add_argument("--out", default="out/adaptive_study", help="output folder (default out/adaptive_study)")
    b.add_argument("--quick", action="store_true", help="coarse targets and the three coarsest uniform meshes")
    b.set_defaults(func=_run)


def _run(args) -> int:
    print_files(run(Path(args.out), args.command_line, quick=args.quick))     # the command as typed, for the report
    return 0
