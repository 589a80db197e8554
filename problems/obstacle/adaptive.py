"""Adaptive meshes for the obstacle problem: solve -> estimate -> mark -> refine, until a target accuracy.

One level (:func:`solve_adaptive`):

1. **solve** the discrete problem on the current mesh with ADMM, stopped
   balanced with the discretisation error
   (:class:`admmkit.problems.obstacle.estimate.BalancedStop`) and started from
   the previous level's u, lam and rho, prolongated to the new mesh (P1
   interpolation, as NGSolve's ``GridFunction.Update``), so later levels cost
   few iterations; the prolongated u then takes one active-set step, which
   removes the smooth algebraic error it inherits, where that lowers its energy
   (``active_set_step``, :mod:`admmkit.problems.obstacle.warm_start`); rho
   kept within ``warm_rho`` x the new mesh's own scale (``WARM_RHO``), then
   held for the stop's longest test interval (``every``, 10 iterations;
   :class:`admmkit.fe.adaptive.HeldRho`), and on while the stop predicts it fires
   within that interval (``acceleration`` accelerates the levels' iterations: restarted fast ADMM in
   P2, plain ADMM in P1, by default: ``ACCELERATION``),
   and the x-step is Jacobi-CG, factorising
   only where CG is dear (``problems/obstacle/xstep.py``), in P1, and SuperLU in P2
   (``fe_order=2``: :mod:`admmkit.problems.obstacle.p2`);
2. **estimate**: the indicators eta_T (``estimator="zz"``, the default, or
   ``"residual"``: :mod:`admmkit.problems.obstacle.estimate_residual`; the
   balanced stop uses the same one) and the relative estimate
   ``eta / |u_h|_{H1}``;
3. stop if it is at most ``target``; else **mark** the smallest set of
   triangles that carries a share ``theta`` of sum eta_T^2 (Dörfler 1996);
4. **refine** the marked triangles with NGSolve's own refinement (bisection,
   neighbours refined as conformity needs), on a copy of the mesh, and go on.

The result says truthfully how it ended: ``target_reached``, or
``level_cap`` / ``unknowns_cap`` (the target was not reached; the levels say
what was), or ``admm_failed`` (a level's ADMM run did not converge).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from admmkit import Result, solve
from admmkit.loop.acceleration import make_accelerator
from admmkit.fe.adaptive import AdaptiveResult, HeldRho, check_adaptive, dorfler_mark, needed_unknowns
from admmkit.policies.summable import Summable

from admmkit.problems.fe import p1_prolongation, refined_copy, vertex_parents

from .discrete import check_fe_order, make_problem
from .estimate import OBSTACLE_GAMMA, BalancedStop, estimator_of, zz
from .estimate_residual import check_estimator
from .p2 import prolongation
from .problem import DEFAULT_BACKEND, ObstacleProblem, build_mesh
from .warm_start import warm_start
from .xstep import ADAPTIVE_BACKEND
from .scene import Scene

#: ``acceleration="auto"`` with the summable rule, by element order.  Radial scene, plain against restarted fast
#: ADMM, one run each: P2, targets 2e-3 .. 5e-4, 897 warm iterations in 20.4 s against 611 in 14.7 s; 1.5e-3 ..
#: 4e-4, 1,105 in 29.5 s against 649 in 17.7 s.  P1 (targets 1.2e-2 .. 5e-3): 357 against 309 iterations, no
#: time saved.  With another rule "auto" is plain ADMM: AADMM under fast ADMM raised rho 600-fold on a P2 level
#: of 18,147 unknowns and ran into max_iter (to 3e-4; plain, it took 255 iterations over all levels).
ACCELERATION = {1: None, 2: "fast"}

#: ``warm_rho="auto"``, by element order: a warm level starts from the last level's rho clamped to
#: [lo, hi] x ``problem.rho_scale()`` (the mean K_ii / m_i, about h^-2).  The summable rule moves rho 3x at a
#: time within a level, and a carried rho keeps the move.  On the radial P1 levels, from the default path's
#: starts, rho = 0.1-1 x the scale took 2-4 iterations on every warm level (0.01: 3-56, 3: 6-23), so P1 keeps
#: the last rho within (0.1, 1) x it: with the active-set start, 0.01 bound on the levels of 421 and 3,198
#: unknowns to 3.8e-3 (16 and 13 iterations, against 3 and 2 from 0.1 x the scale).  P2: 0.3 x the scale on
#: every warm level; radial to 3e-4, theta 0.4 / 0.5 / 0.6 / 0.7: 245 / 162 / 176 / 121 warm iterations
#: against 224 / 196 / 213 / 164 carried, and no level's algebraic bound below 0.05 of the estimate, against
#: 1-2 levels in each carried run (docs/obstacle.md).
WARM_RHO = {1: (0.1, 1.0), 2: (0.3, 0.3)}

#: ``active_set_step="auto"``, by element order: whether a warm level starts from one active-set step on the
#: prolongated u where it lowers the start's energy (warm_start.py).  Radial scene, with the step against
#: without, one run each: P1 to 5e-3, 53 warm iterations against 92, levels of more than 5,000 unknowns 2-3
#: iterations each.  P2 to 3e-4, the step taken whatever the energy: 183 warm iterations against 162 (one level
#: started 2.5x the estimate from its solution, against 1.3x without); with the energy test and the stop's
#: doubling intervals (admmkit.fe.balanced_stop): 75 against 131 (bench adaptive, 543e53c against dcb01b7), every
#: level's algebraic error in [0.05, 0.5] of the estimate (docs/obstacle.md)
ACTIVE_SET_STEP = {1: True, 2: True}

#: by element order: whether a warm level's balanced stop tries the active-set multiplier of z's touched set
#: where it may decide a test (``EnergyGap(active_set=True)``, estimate.py).  Radial P2 to 3e-4: 45 warm
#: iterations against 75, every warm level at most a third of a cold start's (one at 0.35 without); P1, with
#: it on every level, gained nothing (21 warm iterations against 20): its starts come from the active-set step
ACTIVE_SET_BOUND = {1: False, 2: True}


@dataclass
class Level:
    """One level of an adaptive solve."""

    cells: int
    unknowns: int
    estimate: float                 # eta, the chosen (ZZ or residual) estimate of |u_h - u|_{H1}
    relative_estimate: float        # eta / |u_h|_{H1}
    algebraic_bound: float          # the guaranteed bound of ||z - u_h||_a at the stop
    iterations: int
    seconds: float
    status: str
    errors: dict | None = None      # against the exact solution, where the scene has one


def solve_adaptive(scene: Scene, target: float, *, theta: float = 0.5, gamma: float = OBSTACLE_GAMMA,
                   max_levels: int = 30, max_unknowns: int = 2_000_000, policy="summable", order: str = "zx",
                   rho: float = 1.0, max_iter: int = 10_000, backend: str | None = None, estimator: str = "zz",
                   fe_order: int = 1, acceleration="auto", warm_rho="auto", active_set_step="auto",
                   log=None) -> AdaptiveResult:
    """Refine adaptively from the scene's mesh until ``eta / |u_h|_{H1} <= target`` (see the module docstring).

    ``gamma``: the balanced stop's, ``OBSTACLE_GAMMA`` (0.5, the top of the band its guaranteed bound keeps the
    algebraic error in; :mod:`admmkit.problems.obstacle.estimate`) unless given.
    ``estimator``: ``"zz"`` or ``"residual"`` (P1 only), for the marking and the balanced stop.
    ``fe_order``: 1 (P1) or 2 (P2 in nodal values, :mod:`admmkit.problems.obstacle.p2`; the warm start
    evaluates the last level's P2 fields at the new nodes).  ``backend``: the x-step's, None for Jacobi-CG in
    P1 (``ADAPTIVE_BACKEND``) and SuperLU in P2 (``solve obstacle --target-error 1e-3``, whole command: 6.6 s
    against 8.4 s for Jacobi-CG and 11.7 s for AMG-CG, one run each, the machine shared).

    ``acceleration``: every level's ADMM (:mod:`admmkit.loop.acceleration`: ``"fast"``, ``"anderson"``, an
    accelerator, None for plain ADMM, or ``"auto"``, the default: ``ACCELERATION``, restarted fast ADMM in
    P2 and plain ADMM in P1 with the summable rule, plain ADMM with any other ``policy``).

    ``warm_rho``: (lo, hi), 0 < lo <= hi: a warm level starts from the last level's rho clamped to
    [lo, hi] x ``problem.rho_scale()``; None: the last level's rho as it is; ``"auto"`` (the default):
    ``WARM_RHO[fe_order]``.

    ``active_set_step``: True: a warm level starts from one active-set step on the prolongated u, with the
    multiplier that step gives, where the step lowers the start's energy
    (:func:`admmkit.problems.obstacle.warm_start.warm_start`); False: from the prolongated u and lam as they
    are; ``"auto"`` (the default): ``ACTIVE_SET_STEP[fe_order]``.

    ``log``: called after each level with the :class:`Level` and the result so far (whose ``model``,
    ``result`` and ``indicators`` are that level's), for progress and per-level output.
    """
    check_adaptive(target, theta, gamma, max_levels, max_unknowns)
    check_estimator(estimator)
    if not isinstance(scene, Scene):
        raise ValueError(f"scene must be a admmkit.problems.obstacle.Scene, got {type(scene).__name__}")
    check_fe_order(fe_order)
    active_set_step = _active_set_step(active_set_step, fe_order)
    if isinstance(acceleration, str) and acceleration.strip().lower() == "auto":
        acceleration = _auto_acceleration(policy, fe_order)
    try:                                                    # an unknown name is refused before any mesh is built
        make_accelerator(acceleration)
    except ValueError:
        raise ValueError(f"acceleration must be None, 'anderson', 'fast', 'auto' or an "
                         f"admmkit.loop.acceleration.Accelerator, got {acceleration!r}") from None
    if fe_order == 2 and estimator != "zz":
        raise ValueError(f"estimator = {estimator!r} is written for P1 elements; with fe_order = 2 use 'zz'")
    window = _warm_window(warm_rho, fe_order)
    backend = backend or (ADAPTIVE_BACKEND if fe_order == 1 else DEFAULT_BACKEND)
    mesh = build_mesh(scene)
    out = AdaptiveResult("running", "")
    warm: dict = {"rho": rho}
    for _ in range(max_levels):
        nodes = mesh.nv + (mesh.nedge if fe_order == 2 else 0)      # P2: a node at each vertex and each edge
        if nodes > max_unknowns:
            out.status = "unknowns_cap"
            out.message = (f"the next mesh has about {nodes} nodes, above max_unknowns = {max_unknowns}; "
                           f"target {target:g} not reached" + needed_unknowns(out.levels, target))
            return out
        t0 = time.perf_counter()
        problem = make_problem(scene, backend=backend, fe_order=fe_order, mesh=mesh)
        fields = warm["at"](problem) if "at" in warm else warm           # P2: the last level's fields at the nodes
        start = {k: fields[k][problem.free] for k in ("x0", "lam0") if k in fields}
        warm_level = "x0" in start
        if warm_level:                      # on the obstacle; the smooth inherited error removed (warm_start.py)
            start = warm_start(problem, start["x0"], start.get("lam0"), active_set_step)
        stop = BalancedStop(problem, gamma, estimator=estimator, active_set=warm_level and ACTIVE_SET_BOUND[fe_order])
        # warm: rho held for the stop's interval, and on while the stop predicts it fires within one
        rule = HeldRho(policy, hold=stop.every, keep=lambda: stop.converging) if warm_level else policy
        rho0 = _clamped(warm["rho"], window, problem) if warm_level else warm["rho"]
        res = solve(problem, rho=rho0, policy=rule, order=order, stop=stop, max_iter=max_iter,
                    acceleration=acceleration, **start)
        indicators = estimator_of(problem, estimator)(res.z)
        eta = float(np.sqrt(np.sum(indicators ** 2)))
        relative = eta / max(zz(problem).energy(res.z), 1e-300)
        level = Level(cells=mesh.ne, unknowns=problem.n, estimate=eta, relative_estimate=relative,
                      algebraic_bound=stop.algebraic, iterations=res.iterations,
                      seconds=time.perf_counter() - t0, status=res.status.value,
                      errors=problem.errors(res.z) if scene.exact is not None else None)
        out.record(level, problem, res, indicators)
        if log is not None:
            log(level, out)
        if out.ends(target):
            return out
        warm = _refine(problem, res, dorfler_mark(indicators, theta))
        mesh = warm.pop("mesh", mesh)
    return out.capped(max_levels, target)


def _auto_acceleration(policy, fe_order: int):
    """``acceleration="auto"``: ``ACCELERATION[fe_order]`` with the summable rule (the default), else None."""
    summable = isinstance(policy, Summable) or (isinstance(policy, str) and policy.strip().lower() == "summable")
    return ACCELERATION.get(fe_order) if summable else None


def _active_set_step(step, fe_order: int) -> bool:
    """``active_set_step`` checked: ``ACTIVE_SET_STEP[fe_order]`` for "auto", else True or False."""
    if isinstance(step, str) and step.strip().lower() == "auto":
        return ACTIVE_SET_STEP[fe_order]
    if not isinstance(step, bool):
        raise ValueError(f"active_set_step = {step!r} is outside the accepted range: True, False or 'auto'")
    return step


def _warm_window(warm_rho, fe_order: int) -> tuple[float, float] | None:
    """``warm_rho`` checked: ``WARM_RHO[fe_order]`` for "auto", None, or (lo, hi) with 0 < lo <= hi finite."""
    if warm_rho is None:
        return None
    if isinstance(warm_rho, str):
        if warm_rho.strip().lower() == "auto":
            return WARM_RHO[fe_order]
        lo = hi = math.nan
    else:
        try:
            lo, hi = (float(v) for v in warm_rho)
        except (TypeError, ValueError):
            lo = hi = math.nan
    if not 0.0 < lo <= hi < math.inf:
        raise ValueError(f"warm_rho = {warm_rho!r} is outside the accepted range: 'auto', None or (lo, hi) "
                         f"with 0 < lo <= hi finite")
    return lo, hi


def _clamped(rho: float, window: tuple[float, float] | None, problem: ObstacleProblem) -> float:
    """rho clamped to window x ``problem.rho_scale()`` (rho itself where the window is None)."""
    if window is None:
        return rho
    scale = problem.rho_scale()
    return min(max(rho, window[0] * scale), window[1] * scale)


def _refine(problem: ObstacleProblem, res: Result, marked: np.ndarray) -> dict:
    """A refined copy of the problem's mesh with its marked cells bisected (the new ``mesh``); u and lam
    prolongated to the new nodes, and rho.

    P1: each new vertex the mean of its parent edge's ends (``problems.fe.p1_prolongation``: NGSolve's
    in-place prolongation, without the in-place hierarchy that made each refinement twice as dear).  P2: the
    fields evaluated at the new nodes on this level's mesh, left as it is (:func:`.p2.prolongation`).
    """
    mesh = refined_copy(problem.mesh, marked)
    if problem.order == 2:
        return {"at": prolongation(problem, res.z, res.lam), "rho": res.rho, "mesh": mesh}
    parents = vertex_parents(mesh, problem.mesh.nv)
    return {"x0": p1_prolongation(parents, problem.full_vector(res.z)),
            "lam0": p1_prolongation(parents, problem.full_multiplier(res.lam)), "rho": res.rho, "mesh": mesh}


__all__ = ["Level", "AdaptiveResult", "dorfler_mark", "solve_adaptive"]
