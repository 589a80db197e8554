"""Friction in the adaptive contact loop: the models it takes, and one level's solve (a Coulomb fixed point).

:func:`admmkit.problems.contact.solvers.adaptive.solve_adaptive` needs, on
every level, a guaranteed bound of the algebraic error for its balanced stop:

- frictionless, and stick (u_t = 0 on Gamma_C: a frictionless problem on
  the smaller space without the tangential dofs there): the bound (B) of
  ``CondensedGap`` (:mod:`admmkit.problems.contact.solvers.estimate`);
- Tresca: the duality gap (B_t) of ``TrescaGap``
  (:mod:`admmkit.problems.contact.solvers.estimate_friction`), a convex problem
  like the frictionless one;
- Coulomb: the fixed point s^{j+1} = mu max(p_n^j, 0)
  (``admmkit.problems.contact.solvers.coulomb``) whose every step is a
  Tresca problem, stopped balanced by (B_t).  A level's bound is that of its
  **last Tresca problem** (slip bound mu p_n of the step before), not of the
  Coulomb problem, which is not a minimisation: the fixed point's own error is
  estimated by its step: it ends when the relative change of s is at most
  ``coulomb_tol`` or, balanced like the inner solves, when the energy-norm
  step of the displacement between two Tresca solves is at most gamma eta
  (eta: the last ZZ estimate).  With a contraction factor kappa of the fixed
  point the error left is at most kappa / (1 - kappa) times that step;
  kappa is not known (docs/friction.md measured 0.1-0.2 per step), so this
  part is an estimate, not a bound.  (The change of s alone stalls: each
  warm Tresca solve stops balanced after 2 ADMM iterations, and on the 3D
  block the change of s stayed at 2e-4 for 30 steps.)  The
  first Tresca problem of a level starts from s^0 = mu max(p_n, 0) with the
  pressure of the level before interpolated along Gamma_C (the first level
  from s^0 = 0), and from the interpolated tractions (p_n, q).

The residual estimator is refused unless the scene is frictionless (it is
Hild & Nicaise's frictionless one: it counts the tangential stress on
Gamma_C as error); ZZ reads the displacement only and applies unchanged.
"""
from __future__ import annotations

from typing import Callable

import admmkit

from admmkit.problems.contact.solvers.coulomb import CoulombReport, coulomb_fixed_point, warm_z0
from admmkit.problems.contact.solvers.methods import method

#: the tangential models of the adaptive loop (each has a guaranteed algebraic error bound)
ADAPTIVE_TANGENTIAL = ("frictionless", "stick", "tresca", "coulomb")


def check_adaptive_model(scene, estimator: str) -> None:
    """Refuse, with the reason, a tangential model or an estimator the adaptive loop does not take."""
    tangential = scene.tangential
    if tangential not in ADAPTIVE_TANGENTIAL:
        raise ValueError(f"adaptive contact takes tangential = {', '.join(ADAPTIVE_TANGENTIAL)} (each has a guaranteed "
                         f"algebraic error bound for the balanced stop), got {tangential!r}")
    if tangential != "frictionless" and estimator != "zz":
        raise ValueError(f"estimator {estimator!r} is Hild & Nicaise's frictionless residual estimator (it counts the "
                         f"tangential stress on Gamma_C as error); with tangential = {tangential!r} use 'zz'")


def solve_level(problem, stop, method_name: str, rho: float, max_iter: int, start: Callable[[], dict],
                coulomb_tol: float = 1e-4, s0=None) -> tuple[admmkit.Result, CoulombReport | None]:
    """One level's ADMM solve with the balanced ``stop``: (Result, None), or with Coulomb friction the fixed point's
    (whole-solve Result, CoulombReport).

    ``start()`` gives the first run's ``x0``, ``z0``, ``lam0`` (empty: a cold start); it is called after the slip
    bound is set to ``s0`` (Coulomb), so that z0 is that problem's z-step.  Later Tresca solves of the fixed point
    are warm-started from the previous one and its rho, with z0 from a z-step with the new slip bound (as
    ``solve_scene`` does).
    """
    friction = problem.friction
    order, policy = method(method_name)
    if friction is None or friction.law == "tresca":
        return admmkit.solve(problem, rho=rho, policy=policy, order=order, stop=stop, max_iter=max_iter,
                             **start()), None

    def run(warm):    # one Tresca problem of the fixed point, a fresh penalty rule each time
        order_, rule = method(method_name)
        if warm is None:
            return admmkit.solve(problem, rho=rho, policy=rule, order=order_, stop=stop, max_iter=max_iter, **start())
        return admmkit.solve(problem, rho=None, policy=rule, order=order_, stop=stop, max_iter=max_iter,
                             warm_start=warm, z0=warm_z0(problem, warm))

    def settled(previous, last) -> bool:     # ||u^j - u^{j-1}||_a <= gamma eta: the fixed point's step balanced
        return problem.x_distance(previous.x_iterate, last.x_iterate) <= stop.gamma * stop.discretisation

    return coulomb_fixed_point(problem, run, friction.mu, tol=coulomb_tol, s0=s0, settled=settled)


__all__ = ["ADAPTIVE_TANGENTIAL", "check_adaptive_model", "solve_level"]
