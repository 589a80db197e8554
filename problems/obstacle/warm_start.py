"""The start of a warm level: the last level's solution prolongated, then one active-set step.

A warm level inherits the last level's algebraic error: up to gamma times
that level's estimate, which the balanced stop allows.  Its smooth part is
what ADMM removes slowest (the x-step (K + rho M) u = ... damps a component
of eigenvalue lambda of M^{-1} K by about rho / (lambda + rho) an iteration),
and it piles up over the levels until one level takes tens of iterations
(docs/obstacle.md, "Why a fine warm level stalls").  So before ADMM the
prolongated iterate u_0 is corrected by one step of the primal-dual active
set method (Hintermüller, Ito & Kunisch 2003), its active set read off u_0:

    A = {i : s (u_0 - psi)_i <= 0}      the nodes u_0 puts on the obstacle, I the rest,
    u_A = psi_A,   K_II u_I = F_I - K_IA psi_A                      the free problem on I,
    lam_A = (F - K u)_A / m_A,   lam_I = 0                          K u - F + M lam = 0.

Where A is the discrete solution's contact set, u is that solution; where it
is one ring of nodes off (as the prolongated contact set of a level that
refined its free boundary), the error left is local to the free boundary,
which ADMM removes in a few iterations.  The solve with K_II is the price:
AMG-preconditioned CG in P1 (``admmkit.amg``), a factorisation in P2 (whose
nodal K AMG-CG solves slowly, as in :class:`.estimate.EnergyGap`).
"""
from __future__ import annotations

import numpy as np

from admmkit.amg import AMGPreconditioner
from admmkit.cg import pcg
from admmkit.linsolve import factorize

#: the free problem's relative energy tolerance (AMG-CG, P1)
TOL = 1e-8


def active_set_start(problem, x0: np.ndarray, tol: float = TOL) -> dict[str, np.ndarray]:
    """The warm start ``{"x0", "z0", "lam0"}`` of ``problem`` after one active-set step from ``x0`` (values on
    the free nodes; module docstring)."""
    s, psi, K, F = problem.sign, problem.psi, problem.K, problem.F
    x0 = np.asarray(x0, dtype=float)
    if x0.shape != (problem.n,) or not np.all(np.isfinite(x0)):
        raise ValueError(f"x0 must hold {problem.n} finite values (one per free node), got shape {x0.shape}"
                         + ("" if x0.shape != (problem.n,) else " with a NaN or inf"))
    on = s * (x0 - psi) <= 0.0
    free = ~on
    u = np.where(on, psi, x0)
    if np.any(free):
        rows = K[free]
        K_II = rows[:, free].tocsr()
        b = F[free] - rows[:, on] @ psi[on]
        u[free] = _solve_free(problem, K_II, b, u[free], tol)
    lam = np.where(on, (F - K @ u) / problem.m, 0.0)
    return {"x0": u, "z0": problem.z_step(u, np.zeros(problem.n), 1.0, None), "lam0": lam}


def _solve_free(problem, K_II, b: np.ndarray, x: np.ndarray, tol: float) -> np.ndarray:
    """K_II u = b: a factorisation in P2, AMG-preconditioned CG from x in P1."""
    if getattr(problem, "order", 1) == 2:
        return factorize(K_II)(b)
    amg = AMGPreconditioner(K_II, np.ones((K_II.shape[0], 1)))
    u, *_ = pcg(lambda v: K_II @ v, b, x, amg, tol=tol, maxiter=500)
    return u


__all__ = ["TOL", "active_set_start"]
