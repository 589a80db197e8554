"""The contact scenes of ``admmkit bench adaptive``: the reference energy and the rows of every level and mesh.

The true relative energy error is ``sqrt(2 (J(u_h) - J_ref + c_h)) / ||u||_a``
(as in ``admmkit bench estimators``: J(v) - J(u) >= ||v - u||_a^2 / 2 for a
feasible v), J_ref extrapolated from a P2 adaptive solve to a tight target
(gamma 0.01) from its two finest levels with J_k - J_ref = C N_k^-p, p twice
the estimate's rate over its five finest levels (:func:`reference`).  c_h is
0 where the obstacle is flat (Examples 1 and 2); Hertz's curved one adds back
what the between-node penetration took off J(u_h)
(``hertz.penetration_term``).  Where J(u_h) + c_h < J_ref (Hertz's
coarsest meshes, the curved contact zone across a few nodes) the error is
NaN: the energy cannot measure it.  Nor where it is below ``RESOLVED`` times
the reference's energy floor: on Hertz's finest levels the energy rises by
up to 7e-15 (of 1.86e-7) from one level to the next (the boundary's new
vertices land on the circle, so the body grows towards the plane); on
Example 2's a little (each new contact node adds a constraint, so the
discrete admissible sets are not nested).
"""
from __future__ import annotations

import math
import time

import numpy as np

import admmkit

from admmkit.problems.contact.validation.reference import energy, energy_norm

from admmkit.benchmarks.adaptive.algebraic import contact_algebraic_error, contact_exact
from admmkit.benchmarks.adaptive.levels import Clock, level_row, uniform_level

CONTACT_NAMES = {"ex1": "Example 1", "ex2": "Example 2", "hertz": "Hertz"}
#: a true error is reported where it is at least this times the reference's energy floor (its energy's rise
#: between fine levels: each new contact node adds a constraint, and Hertz's curved boundary gains vertices on the
#: circle).  An error e measured against a floor f is sqrt(e^2 +- f^2): within 13 % of it from e = 2 f on
RESOLVED = 2.0


def contact_scene(name: str, h: float, order: int):
    """Contact Example 1 or 2 (``name``) on the structured mesh of size h, in P``order``."""
    from admmkit.problems.contact import example1, example2
    return {"ex1": example1, "ex2": example2}[name](h=h, order=order)


def energy_floor(energies, norm: float) -> float:
    """sqrt(2 r) / norm, r the largest rise from one energy to the next (0 if they only fall): the energy's
    resolution in relative energy-norm error, where each refinement should lower it."""
    rise = max([max(b - a, 0.0) for a, b in zip(energies, energies[1:])], default=0.0)
    return math.sqrt(2 * rise) / norm


def reference(target: float, name: str = "ex1", scene=None, correction=None, start: str = "h = 1/5") -> dict:
    """J_ref of a contact scene: P2 adaptive to ``target`` (gamma 0.01), the energy of each level's exact discrete
    solution (:func:`contact_exact`) extrapolated.

    ``scene``: the P2 scene to start from (default: Example ``name`` with h = 1/5); ``correction(ops, result)``:
    c_h, added to every level's energy as in the true error (default 0); ``start``: how the report names the
    start. Returns J_ref,
    ``norm`` = ||u||_a (of the finest solve), the finest level's unknowns, relative estimate and energy, and
    ``own_error``: the relative energy error of the finest solve against J_ref (the extrapolation's
    correction), the reference's own accuracy; ``energy_floor``: sqrt(2 r) / ||u||_a with r the largest rise of
    the energy between two of its five finest levels (0 where it only fell), the energy's resolution
    (:data:`RESOLVED`).
    """
    from admmkit.problems.contact.solvers.adaptive import solve_adaptive
    levels = []
    correction = correction or (lambda ops, res: 0.0)

    def log(level, out):            # the energy of u_h*: an iterate that penetrates a little has J below J(u_h*)
        exact = contact_exact(out.model, out.result) or out.result           # by a term linear in its error
        u = exact.x
        levels.append((level.unknowns, energy(out.model, u) + correction(out.model, exact),
                       energy_norm(out.model, u), level.relative_estimate))
    t0 = time.perf_counter()
    scene = contact_scene(name, 1 / 5, 2) if scene is None else scene
    out = solve_adaptive(scene, target, gamma=0.01, max_levels=60, log=log)
    (n1, j1, _, _), (n2, j2, _, _), (n3, j3, norm, rel) = levels[-3:]
    tail = levels[-5:]          # p: twice the estimate's rate (the energy error is the squared energy-norm error)
    floor = energy_floor([t[1] for t in tail], norm)
    p = -2 * float(np.polyfit(np.log([t[0] for t in tail]), np.log([t[3] for t in tail]), 1)[0])
    p = min(max(p, 0.5), 4.0)
    p_energy = math.log((j1 - j2) / (j2 - j3)) / math.log(n2 / n1) if j1 > j2 > j3 else math.nan
    if j2 > j3:
        j_ref = j3 - (j2 - j3) / ((n3 / n2) ** p - 1.0)
        own = math.sqrt(2 * (j3 - j_ref)) / norm
    else:               # the energies did not fall: no extrapolation, the finest level's estimate is its accuracy
        j_ref, own = j3, math.nan
    seconds = time.perf_counter() - t0
    print(f"  {name} reference: P2 adaptive to {target:g} ({out.status}), {n3} unknowns, estimate {rel:.2e}, "
          f"energy rate p = {p:.2f} (from the energies {p_energy:.2f}), own error {own:.2e}, energy floor "
          f"{floor:.2e}, {seconds:.1f} s", flush=True)
    return {"J_ref": j_ref, "norm": norm, "unknowns": n3, "relative_estimate": rel, "J_finest": j3, "p": p,
            "p_energy": p_energy, "own_error": own, "energy_floor": floor, "status": out.status, "target": target,
            "scene": CONTACT_NAMES[name], "start": start, "seconds": seconds}


def contact_rows(name: str, order: int, target: float, ref: dict, start, uniform, a_priori=(), correction=None,
                 extra=None) -> list[dict]:
    """Adaptive (from ``start``), uniform and a priori rows of one contact scene in P``order``.

    ``uniform``, ``a_priori``: pairs (h, scene), each mesh solved once, cold; ``correction(ops, result)``:
    c_h of the true error (default 0); ``extra(ops, result)``: more columns for the row (Hertz's a and p0).
    """
    from admmkit.problems.contact.solvers.adaptive import solve_adaptive
    rows, clock = [], Clock()
    correction = correction or (lambda ops, res: 0.0)
    extra = extra or (lambda ops, res: {})

    def true_error(ops, res):       # NaN where the energy cannot measure it (Hertz's coarsest and finest levels)
        excess = energy(ops, res.x) - ref["J_ref"] + correction(ops, res)
        absolute = math.sqrt(2 * excess) if excess >= 0 else math.nan
        if absolute / ref["norm"] < RESOLVED * ref["energy_floor"]:
            absolute = math.nan
        return absolute / ref["norm"], absolute

    def measured(ops, res):
        """(u_h*, relative and absolute true error of u_h*, a and p0 of what ``res`` returned): a level's or a
        mesh's discretisation error is that of its exact discrete solution (a balanced stop's u may penetrate)."""
        exact = contact_exact(ops, res)
        rel, absolute = (math.nan, math.nan) if exact is None else true_error(ops, exact)
        return exact, rel, absolute, extra(ops, res)

    def log(level, out):
        t0 = time.perf_counter()
        exact, rel, absolute, more = measured(out.model, out.result)
        cold = cold_contact(out.model)
        algebraic = contact_algebraic_error(out.model, out.result.x, exact)
        clock.excluded += time.perf_counter() - t0
        rows.append(level_row(name, order, "adaptive", len(rows) + 1, math.nan, level.unknowns,
                              level.relative_estimate, level.estimate, rel, absolute, level.iterations,
                              level.seconds, clock.now(), level.status, cold, algebraic, **more))
    solve_adaptive(start, target, max_levels=60, log=log)
    for method, meshes in (("uniform", uniform), ("a_priori", a_priori)):
        for i, (h, scene) in enumerate(meshes):
            level, wall, (_, rel, absolute, more) = uniform_level(solve_adaptive, scene, measured)
            rows.append(level_row(name, order, method, i + 1, h, level.unknowns, level.relative_estimate,
                                  level.estimate, rel, absolute, level.iterations, level.seconds, wall,
                                  level.status, **more))
    return rows


def cold_contact(ops) -> int:
    """Iterations of a cold start on an adaptive level (mode condensed, SADMM, rho_0 1e3, the same stop)."""
    from admmkit.problems.contact.solvers.estimate import BalancedStop
    from admmkit.problems.contact.solvers.methods import method
    from admmkit.problems.contact.solvers.problem import contact_problem
    problem = contact_problem(ops, mode="condensed")
    order, policy = method("sadmm")
    return admmkit.solve(problem, rho=1e3, policy=policy, order=order, stop=BalancedStop(problem),
                         max_iter=20_000).iterations
