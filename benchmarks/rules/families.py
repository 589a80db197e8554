"""The discrete problems of the benchmarks, their reference solutions and error norms.

Every benchmark problem is one convex QP, given to all solvers *as the same
discrete problem*:

    min 1/2 x'Px + q'x   subject to   l <= A x <= u          (``qp_form``)

- contact (``ex1``, ``ex2``; mesh size h, Poisson ratio nu, P1/P2): P = K,
  q = -f, A = B, l = -inf, u = g.  Error of u in the energy norm
  ||u - u*||_K / ||u*||_K; error of the pressure lam in the lumped boundary
  mass norm ||lam - lam*||_Mc / ||lam*||_Mc.
- obstacle (``radial``: Bueler's radial obstacle on (-2, 2)^2, cell size h):
  P = K, q = -F, A = I, l = psi, u = +inf.  Error of u in the lumped L2 norm
  ||u - u*||_M / ||u*||_M (as docs/results/obstacle/); the discretisation
  error against the exact solution is reported beside it (``floor``).
- QPs (``qp:random-mixed``, ``qp:DUAL2``, ``qp:MOSARQP2``, ``qp:CONT-050``):
  Euclidean relative error ||x - x*||_2 / ||x*||_2 (all four are strictly
  convex, so x* is unique).

Reference solutions (computed once per problem and cached on disk):

- contact and obstacle: the primal-dual active set solution
  (:mod:`admmkit.benchmarks.rules.pdas`), exact once its active set settles, with
  its KKT residuals, cross-checked against cvxpy + Clarabel at tolerance 1e-10
  when the problem has at most ``CROSS_CHECK_MAX`` unknowns (the relative
  differences are recorded).  Clarabel itself is only accurate to its
  tolerance (interior point), so it cannot measure errors near 1e-10.
- QPs: cvxpy + Clarabel at tolerance 1e-10, then an active-set polish (the
  equality-constrained QP on the active set read off Clarabel's solution,
  :func:`active_set_polish`, kept when it is feasible, has multipliers of the
  right sign and smaller KKT residuals); Clarabel alone left errors of 1e-9 to
  1e-7 in x, a floor under every method's error.
"""
from __future__ import annotations

import copy
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
import scipy.sparse as sp
from admmkit.benchmarks.rules.references import _qp_kkt, active_set_polish, clarabel_solve, pdas_form

#: cross-check the PDAS reference with cvxpy + Clarabel up to this many unknowns
CROSS_CHECK_MAX = 200_000
#: Maros-Meszaros problems of the QP benchmark (strictly convex, 96 to 2597 variables)
MM_QPS = ("DUAL2", "MOSARQP2", "CONT-050")
MM_FOLDER_CANDIDATES = ("../shared/data/maros_meszaros", "/work/shared/data/maros_meszaros")
QP_SCENES = ("qp:random-mixed",) + tuple(f"qp:{n}" for n in MM_QPS)
CONTACT_SCENES = ("ex1", "ex2")
OBSTACLE_SCENES = ("radial",)
CLARABEL_TIGHT = 1e-10
#: the environment variable naming a sweep's cache of reference solutions (set in every worker)
CACHE_ENV = "ADMMKIT_BENCH_CACHE"


def kind_of(scene: str) -> str:
    """'contact', 'obstacle' or 'qp'."""
    if scene in CONTACT_SCENES:
        return "contact"
    if scene in OBSTACLE_SCENES:
        return "obstacle"
    if scene.startswith("qp:"):
        return "qp"
    raise ValueError(f"unknown benchmark scene {scene!r}; known: {', '.join(CONTACT_SCENES + OBSTACLE_SCENES + QP_SCENES)}")


def mm_folder() -> Path | None:
    """The Maros-Meszaros folder beside the repository, if present."""
    root = Path(__file__).resolve().parents[2]
    for cand in MM_FOLDER_CANDIDATES:
        p = (root / cand).resolve()
        if p.is_dir():
            return p
    return None


def problem_key(case: dict) -> str:
    """A short text naming the discrete problem of a case (scene, h, nu, P)."""
    scene = case["scene"]
    parts = [scene.replace(":", "-")]
    if case.get("h") is not None:
        parts.append(f"h{case['h']:.6g}")
    if case.get("nu") is not None:
        parts.append(f"nu{case['nu']:g}")
    if case.get("p") is not None:
        parts.append(f"P{case['p']}")
    return "_".join(parts)


@dataclass
class Discrete:
    """One discrete problem with everything the solvers and the error measures need."""

    key: str
    kind: str
    n: int
    P: sp.csc_matrix
    q: np.ndarray
    A: sp.csc_matrix
    l: np.ndarray
    u: np.ndarray
    weights: np.ndarray               # lam = y / weights (y the multiplier of l <= Ax <= u)
    x_norm: Callable                  # the error norm of x
    lam_norm: Callable                # the error norm of lam
    norm_name: str
    make_admm: Callable               # () -> a fresh admmkit.Problem (its setup is timed)
    rho_unit: float                   # rho_0 = rho_scale * rho_unit (E for contact)
    info: dict = field(default_factory=dict)
    pdas_args: Callable | None = None  # () -> kwargs of pdas(...) for this problem (setup timed)
    floor: Callable | None = None      # x -> discretisation error against an exact solution
    ref_x: np.ndarray | None = None
    ref_lam: np.ndarray | None = None
    ref_info: dict = field(default_factory=dict)

    def errors(self, x, lam=None) -> dict:
        """Relative errors of x (and lam) against the reference, in this problem's norms."""
        out = {"err": float(self.x_norm(np.asarray(x) - self.ref_x) / max(self.x_norm(self.ref_x), 1e-300))}
        if lam is not None and self.ref_lam is not None:
            out["err_lam"] = float(self.lam_norm(np.asarray(lam) - self.ref_lam)
                                   / max(self.lam_norm(self.ref_lam), 1e-300))
        return out


_CACHE: dict[str, Discrete] = {}


def discrete(case: dict, cache_dir: str | Path | None = None, cross_check_max: int = CROSS_CHECK_MAX) -> Discrete:
    """The discrete problem of a case (built once per process), with its reference solution."""
    key = problem_key(case)
    if key not in _CACHE:
        _CACHE.clear()    # one problem at a time per worker: cases come grouped by problem
        kind = kind_of(case["scene"])
        d = {"contact": _contact, "obstacle": _obstacle, "qp": _qp}[kind](case)
        _attach_reference(d, cache_dir, cross_check_max)
        _CACHE[key] = d
    return _CACHE[key]


# ---------------------------------------------------------------- contact
def _contact(case: dict) -> Discrete:
    from admmkit.problems.contact import assemble, contact_problem, example1, example2

    example = {"ex1": example1, "ex2": example2}[case["scene"]]
    changes = {}
    if case.get("nu") is not None:
        changes["nu"] = case["nu"]
    if case.get("p") is not None:
        changes["order"] = int(case["p"])
    scene = example(h=case["h"], **changes)
    ops = assemble(scene)
    K = ops.K.tocsc()
    mc = ops.mc

    def energy(v):
        return math.sqrt(max(float(v @ (K @ v)), 0.0))

    def mass_c(v):
        return math.sqrt(max(float(mc @ (v * v)), 0.0))

    def make_admm():
        return contact_problem(ops, mode="auto")

    def pdas_args():
        # the same boundary Schur complement as ADMM's condensed mode (its setup is timed with PDAS)
        problem = contact_problem(ops, mode="auto")
        if getattr(problem, "mode", "") == "condensed":
            recover = lambda mu: problem.schur.solve(ops.f - ops.B.T @ mu)  # noqa: E731
            return {"compliance": (problem.C, problem.d0, recover), "weights": mc}
        return {"weights": mc}

    m = ops.n_c
    return Discrete(key=problem_key(case), kind="contact", n=ops.n_free, P=K, q=-ops.f, A=ops.B.tocsc(),
                    l=np.full(m, -np.inf), u=ops.g.copy(), weights=mc, x_norm=energy, lam_norm=mass_c,
                    norm_name="energy norm ||u - u*||_K / ||u*||_K", make_admm=make_admm, rho_unit=scene.E,
                    info={"n_free": ops.n_free, "n_c": m, "E": scene.E, "nu": scene.nu, "P": scene.order,
                          "h": scene.h},
                    pdas_args=pdas_args)


# ---------------------------------------------------------------- obstacle
def _obstacle(case: dict) -> Discrete:
    from admmkit.linalg.linsolve import CachedFactorization
    from admmkit.problems.obstacle import make_problem, radial
    from admmkit.problems.obstacle.problem import DEFAULT_BACKEND

    base = make_problem(radial(h=case["h"]))
    m = base.m

    def lumped(v):
        return math.sqrt(max(float(m @ (v * v)), 0.0))

    def make_admm():
        # the assembled operators are shared; a fresh factorisation cache per run, so that
        # every timed run pays its own factorisations (K + rho M)
        problem = copy.copy(base)
        K = base.K
        problem._solver = CachedFactorization(lambda rho: (K + rho * sp.diags(m)).tocsc(), backend=DEFAULT_BACKEND)
        return problem

    def pdas_args():
        # u >= psi  <=>  -u <= -psi; lam (admmkit's sign, <= 0) = -mu / m
        return {"weights": m, "backend": DEFAULT_BACKEND}

    n = base.n
    return Discrete(key=problem_key(case), kind="obstacle", n=n, P=base.K.tocsc(), q=-base.F,
                    A=sp.identity(n, format="csc"), l=base.psi.copy(), u=np.full(n, np.inf), weights=m,
                    x_norm=lumped, lam_norm=lumped, norm_name="lumped L2 norm ||u - u*||_M / ||u*||_M",
                    make_admm=make_admm, rho_unit=1.0, info={"n": n, "h": case["h"], "cells": base.scene.counts[0]},
                    pdas_args=pdas_args, floor=lambda x: base.errors(x)["L2"])


# ---------------------------------------------------------------- QPs
def _qp(case: dict) -> Discrete:
    from admmkit.problems.qp import QP, load_mat, random_qp

    name = case["scene"].split(":", 1)[1]
    if name == "random-mixed":
        qp = random_qp(1000, 1500, kind="mixed", density=0.01, seed=5)
    else:
        folder = mm_folder()
        if folder is None:
            raise FileNotFoundError(f"Maros-Meszaros folder not found (looked for {MM_FOLDER_CANDIDATES})")
        qp = load_mat(folder / f"{name}.mat")
    data = (qp.P, qp.q, qp.A, qp.l, qp.u)

    def euclid(v):
        return float(np.linalg.norm(v))

    def make_admm():
        return QP(*data, qp.r, name=qp.name)

    return Discrete(key=problem_key(case), kind="qp", n=qp.n, P=qp.P.tocsc(), q=qp.q.copy(), A=qp.A.tocsc(),
                    l=qp.l.copy(), u=qp.u.copy(), weights=np.ones(qp.m), x_norm=euclid, lam_norm=euclid,
                    norm_name="Euclidean ||x - x*||_2 / ||x*||_2", make_admm=make_admm, rho_unit=1.0,
                    info={"n": qp.n, "m": qp.m, "name": qp.name})


# ---------------------------------------------------------------- references
def _attach_reference(d: Discrete, cache_dir, cross_check_max: int) -> None:
    path = None
    if cache_dir is not None:
        path = Path(cache_dir) / f"ref-{d.key}{'-polished' if d.kind == 'qp' else ''}.npz"
        if path.exists():
            data = np.load(path, allow_pickle=False)
            d.ref_x, d.ref_lam = data["x"], data["lam"]
            d.ref_info = json.loads(str(data["info"]))
            return
    t0 = time.perf_counter()
    if d.kind in ("contact", "obstacle"):
        from admmkit.benchmarks.rules.pdas import pdas
        K, f, B, g, to_lam = pdas_form(d)
        kwargs = d.pdas_args()
        kwargs.pop("weights", None)
        res = pdas(K, f, B, g, max_iter=500, **kwargs)
        if not res.converged:
            raise RuntimeError(f"{d.key}: the PDAS reference did not converge ({res.status} after {res.iterations})")
        d.ref_x, d.ref_lam = res.u, to_lam(res.mu)
        info = {"solver": f"PDAS ({res.method}), {res.iterations} Newton steps", "kkt": res.kkt,
                "seconds": time.perf_counter() - t0}
        if d.n <= cross_check_max:
            try:
                x, y, status, _ = clarabel_solve(d, CLARABEL_TIGHT)
                lam = y / d.weights
                info["cross_check"] = {"other": f"cvxpy + Clarabel, tol {CLARABEL_TIGHT:g} ({status})",
                                       **{f"{k}_diff": v for k, v in d.errors(x, lam).items()}}
            except Exception as err:  # cross-check is best effort; say why it is missing
                info["cross_check"] = {"other": f"cvxpy + Clarabel failed: {err}"}
        else:
            info["cross_check"] = {"other": f"none (n = {d.n} > {cross_check_max}; KKT residuals only)"}
        if d.floor is not None:
            info["discretisation_error_L2"] = d.floor(d.ref_x)
    else:
        x, y, status, _ = clarabel_solve(d, CLARABEL_TIGHT)
        if status not in ("optimal",):
            raise RuntimeError(f"{d.key}: the Clarabel reference ended with status {status}")
        kkt = _qp_kkt(d, x, y)
        info = {"solver": f"cvxpy + Clarabel, tol {CLARABEL_TIGHT:g}", "kkt": kkt}
        polished = active_set_polish(d, x, y)
        if polished is not None and max(polished[2].values()) < max(kkt.values()):
            d.ref_x, d.ref_lam = polished[0], polished[1]
            info = {"solver": f"cvxpy + Clarabel, tol {CLARABEL_TIGHT:g}, then an active-set polish",
                    "kkt": polished[2], "cross_check": {"other": "Clarabel before the polish",
                                                        **{f"{k}_diff": v for k, v in d.errors(x, y).items()}}}
        else:
            d.ref_x, d.ref_lam = x, y
        info["seconds"] = time.perf_counter() - t0
    d.ref_info = info
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.stem + ".tmp.npz")
        np.savez(tmp, x=d.ref_x, lam=d.ref_lam, info=json.dumps(info, default=float))
        tmp.replace(path)


