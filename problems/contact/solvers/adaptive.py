"""Adaptive meshes for 2D and 3D contact: solve -> estimate -> mark -> refine, until a target accuracy.

Frictionless, Tresca and Coulomb scenes (the friction models in 2D and 3D
alike; what each level's bound means with friction:
:mod:`admmkit.problems.contact.solvers.adaptive_friction`).

One level (:func:`solve_adaptive`):

1. **solve** the scene on the current mesh (mode condensed) with ADMM,
   stopped balanced with the discretisation error
   (:class:`admmkit.problems.contact.solvers.estimate.BalancedStop`), started
   from the previous level's rho, its contact pressure (with friction also the
   tangential traction; interpolated along Gamma_C, in 3D on the contact
   face, ``surface_interpolate`` of ``admmkit.problems.contact.solvers.adaptive3d``)
   and, in 2D, its displacement on Gamma_C (normal, and tangential with
   friction: the field with that trace,
   :mod:`admmkit.problems.contact.solvers.warm_trace`). For Coulomb the slip
   bound mu p_n is the interpolated pressure's. Later levels cost few
   iterations in 2D; in 3D they cost as many as a cold start (docs/contact.md);
2. **estimate**: the indicators eta_T (``estimator="zz"``, the default, or
   ``"residual"``, Hild & Nicaise's, with the ADMM pressure, frictionless only;
   the balanced stop uses the same one) and the relative estimate ``eta / ||u_h||_a``;
3. stop if it is at most ``target``; else **mark** the smallest set of
   elements that carries a share ``theta`` of sum eta_T^2 (Dörfler);
4. **refine** them with NGSolve's refinement (bisection of the marked
   triangles or tetrahedra and their closure) and assemble the scene's data
   (tractions, gap, contact boundary) on the new mesh (a 3D scene by
   ``adaptive3d.assemble3d_on``).

It ends ``target_reached``, or says truthfully that the target was not
reached (``level_cap``, ``unknowns_cap``) or that a level's ADMM run did not
converge (``admm_failed``; for Coulomb also when the fixed point did not).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from admmkit.fe.adaptive import AdaptiveResult, check_adaptive, dorfler_mark, needed_unknowns
from admmkit.fe.balanced_stop import GAMMA

from admmkit.problems.contact.model.assembly import ContactOperators, assemble, build_mesh
from admmkit.problems.contact.model.scene import Scene
from admmkit.problems.contact.model.scene3d import Scene3D
from admmkit.problems.contact.solvers.adaptive3d import assemble3d_on, mesh3d, surface_interpolate, unknowns3d
from admmkit.problems.contact.solvers.adaptive_friction import check_adaptive_model, solve_level
from admmkit.problems.contact.solvers.estimate import BalancedStop, estimator_indicators
from admmkit.problems.contact.solvers.estimate_residual import check_estimator
from admmkit.problems.contact.solvers.methods import method
from admmkit.problems.contact.solvers.problem import contact_problem
from admmkit.problems.contact.solvers.warm_trace import ContactTrace, contact_trace, start_at, trace_warm_start
from admmkit.problems.fe import mesh_copy, refine_marked


@dataclass
class Level:
    """One level of an adaptive contact solve."""

    cells: int
    unknowns: int
    contact_nodes: int
    estimate: float                 # eta, the chosen (ZZ or residual) estimate of ||u_h - u||_a
    relative_estimate: float        # eta / ||u_h||_a
    algebraic_bound: float          # the guaranteed bound of ||u - u_h||_a at the stop
    iterations: int
    seconds: float
    status: str
    tresca_solves: int = 0          # Coulomb: the fixed point's Tresca solves on this level (0 otherwise)


def solve_adaptive(scene: Scene, target: float, *, theta: float = 0.5, gamma: float = GAMMA, max_levels: int = 20,
                   max_unknowns: int = 2_000_000, method_name: str = "sadmm", rho: float = 1e3,
                   max_iter: int = 20_000, estimator: str = "zz", coulomb_tol: float = 1e-4,
                   log=None) -> AdaptiveResult:
    """Refine adaptively from the scene's mesh until ``eta / ||u_h||_a <= target`` (module docstring).

    ``coulomb_tol``: a Coulomb scene's fixed point ends on a level when the relative change of s is at most it.

    ``log``: called after each level with the :class:`Level` and the result so far (whose ``model``,
    ``result`` and ``indicators`` are that level's), for progress and per-level output.
    """
    check_adaptive(target, theta, gamma, max_levels, max_unknowns)
    check_estimator(estimator)
    if not isinstance(scene, (Scene, Scene3D)):
        raise ValueError(f"scene must be an admmkit.problems.contact Scene (2D) or Scene3D, got {type(scene).__name__}")
    check_adaptive_model(scene, estimator)
    method(method_name)                                  # an unknown method is refused before any mesh is built
    three = isinstance(scene, Scene3D)
    mesh, out, warm = (mesh3d if three else build_mesh)(scene), AdaptiveResult("running", ""), None
    for _ in range(max_levels):
        dofs = unknowns3d(mesh, scene.order) if three else 2 * (mesh.nv + (mesh.nedge if scene.order == 2 else 0))
        if dofs > max_unknowns:
            out.status = "unknowns_cap"
            out.message = f"the next mesh has about {dofs} unknowns, above max_unknowns = {max_unknowns}; " \
                          f"target {target:g} not reached" + needed_unknowns(out.levels, target)
            if scene.order == 1 and not three:
                out.message += " (P2 elements, --fe-order 2, converge about twice as fast on a 2D scene)"
            return out
        t0 = time.perf_counter()
        level_mesh = mesh_copy(mesh)         # the level's model keeps its own mesh; ``mesh`` is refined in place,
        ops = assemble3d_on(scene, level_mesh) if three else assemble(scene, mesh=level_mesh)   # with its history
        problem = contact_problem(ops, mode="condensed")
        stop = BalancedStop(problem, gamma, estimator=estimator)
        lam0 = None if warm is None else _interpolate(ops, warm.xc, warm.lam)
        s0 = None if lam0 is None or scene.tangential != "coulomb" else scene.mu * np.maximum(lam0[:ops.n_c], 0.0)
        res, report = solve_level(problem, stop, method_name, rho if warm is None else warm.rho, max_iter,
                                  lambda: {} if lam0 is None else _warm_start(problem, lam0, warm.trace), coulomb_tol, s0)
        indicators = estimator_indicators(ops, res.x, res.lam, estimator)
        eta = float(np.sqrt(np.sum(indicators ** 2)))
        relative = eta / max(float(np.sqrt(res.x @ (ops.K @ res.x))), 1e-300)
        level = Level(cells=mesh.ne, unknowns=ops.n_free, contact_nodes=ops.n_c, estimate=eta,
                      relative_estimate=relative, algebraic_bound=stop.algebraic, iterations=res.iterations,
                      seconds=time.perf_counter() - t0, status=res.status.value,
                      tresca_solves=0 if report is None else report.outer_iterations)
        out.record(level, ops, res, indicators)
        if log is not None:
            log(level, out)
        if out.ends(target):
            if out.status == "admm_failed" and report is not None:
                out.message += f" ({res.message})"
            return out
        warm = LastLevel(ops.xc.copy(), res.lam.copy(), res.rho, None if three else contact_trace(problem, res.x))
        refine_marked(mesh, dorfler_mark(indicators, theta))   # the same elements in the same order as level_mesh
    return out.capped(max_levels, target)


class LastLevel(NamedTuple):
    """What a level hands the next: its contact nodes, multiplier and rho, and (2D) its displacement's trace."""

    xc: np.ndarray                  # the contact nodes' coordinates
    lam: np.ndarray                 # the multiplier, by block (pressure, then the tangential tractions)
    rho: float
    trace: ContactTrace | None      # A u on Gamma_C by contact edge (warm_trace); None in 3D


def _interpolate(ops: ContactOperators, xc_old: np.ndarray, lam_old: np.ndarray) -> np.ndarray:
    """The old level's tractions (the pressure, with friction then each tangential block) at the new contact
    nodes, block by block along Gamma_C."""
    along = surface_interpolate if ops.mesh.dim == 3 else _along_boundary
    return np.concatenate([along(xc_old, block, ops.xc) for block in lam_old.reshape(-1, len(xc_old))])


def _warm_start(problem, lam0: np.ndarray, trace: ContactTrace | None = None) -> dict:
    """x0, lam0, z0 on the new mesh from the interpolated tractions lam0; x0 in 2D the field with the last level's
    trace on Gamma_C (``warm_trace``), else (3D, or C not positive definite) w0 = -M_c lam0 (stationarity)."""
    start = None if trace is None else trace_warm_start(problem, trace, lam0)
    return start if start is not None else start_at(problem, np.concatenate(([1.0], -problem.w * lam0)), lam0)


def _along_boundary(xc_old: np.ndarray, values: np.ndarray, xc_new: np.ndarray) -> np.ndarray:
    """Linear interpolation between the two nearest old contact nodes of every new one."""
    from scipy.spatial import cKDTree
    dist, idx = cKDTree(xc_old).query(xc_new, k=min(2, len(xc_old)))
    if dist.ndim == 1:
        return values[idx]
    weights = 1.0 / np.maximum(dist, 1e-300)
    exact = dist[:, 0] <= 1e-14
    out = np.sum(weights * values[idx], axis=1) / np.sum(weights, axis=1)
    out[exact] = values[idx[exact, 0]]
    return out


__all__ = ["Level", "AdaptiveResult", "dorfler_mark", "solve_adaptive"]
