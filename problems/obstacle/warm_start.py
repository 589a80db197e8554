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
AMG-preconditioned CG in P1 (``admmkit.linalg.amg``), a factorisation in P2 (whose
nodal K AMG-CG solves slowly, as in :class:`.estimate.EnergyGap`).

**The step is kept only where it helps** (:func:`warm_start`).  Where u_0
puts nodes on the obstacle that the solution lifts off (P2 nodal values
at a refined free boundary), pinning them can make the start worse: on a
radial P2 level of 1,653 unknowns the step's u was 10 times the estimate
from the level's solution, its projection 2.5 times, the prolongated
start's projection 1.3 times, and ADMM took 30 iterations against 6.  Both
starts z_0 are feasible, and for a feasible z

    1/2 ||z - u_h||_K^2 <= J(z) - J(u_h),       J(v) = 1/2 v'Kv - F'v,

so the start with the lower energy J(z_0) has the smaller of these two
guaranteed error bounds; :func:`warm_start` keeps that one.
"""
from __future__ import annotations

import numpy as np

from admmkit.linalg.amg import AMGPreconditioner
from admmkit.linalg.cg import pcg
from admmkit.linalg.linsolve import factorize

#: the free problem's relative energy tolerance (AMG-CG, P1)
TOL = 1e-8


class FreeProblem:
    """The free problem of an active set A, K_II u_I = F_I - K_IA psi_A (I the rest), its solver kept for the
    next call with the same A: a factorisation in P2, AMG-preconditioned CG in P1 (the AMG set up once per A).

    The balanced stop's bound (:class:`.estimate.EnergyGap`) asks for it at consecutive iterations whose
    touched set has mostly settled; ``setups`` counts the factorisations (P2) or AMG setups (P1).
    """

    def __init__(self, problem, tol: float = TOL):
        self.problem, self.tol, self.setups = problem, float(tol), 0
        self._on: np.ndarray | None = None
        self._solve = self._b = None

    def solution(self, on: np.ndarray, x: np.ndarray) -> np.ndarray:
        """u with u_A = psi_A on the nodes ``on`` (A, a boolean mask) and the free problem solved on the rest,
        from ``x``; a ValueError names a mask or start of the wrong shape, or a start with a NaN."""
        p = self.problem
        on, x = np.asarray(on), _checked(p, x, "x")
        if on.dtype != bool or on.shape != (p.n,):
            raise ValueError(f"on must be a boolean mask of {p.n} values (one per free node), got {on.dtype} "
                             f"of shape {on.shape}")
        free = ~on
        u = np.where(on, p.psi, x)
        if not np.any(free):
            return u
        if self._on is None or not np.array_equal(on, self._on):      # a new A: K_II, its solver and b
            rows = p.K[free]
            self._on, self.setups = on.copy(), self.setups + 1
            self._solve, self._b = self._solver(rows[:, free].tocsr()), p.F[free] - rows[:, on] @ p.psi[on]
        u[free] = self._solve(self._b, u[free])
        return u

    def _solver(self, K_II):
        """(b, x) -> the solution of K_II u = b: a factorisation in P2, AMG-preconditioned CG from x in P1."""
        if getattr(self.problem, "order", 1) == 2:
            solve = factorize(K_II)
            return lambda b, x: solve(b)
        amg = AMGPreconditioner(K_II, np.ones((K_II.shape[0], 1)))
        return lambda b, x: pcg(lambda v: K_II @ v, b, x, amg, tol=self.tol, maxiter=500)[0]


def active_set_start(problem, x0: np.ndarray, tol: float = TOL, free: FreeProblem | None = None
                     ) -> dict[str, np.ndarray]:
    """The warm start ``{"x0", "z0", "lam0"}`` of ``problem`` after one active-set step from ``x0`` (values on
    the free nodes; module docstring); ``free``: a :class:`FreeProblem` to reuse (a new one by default)."""
    x0 = _checked(problem, x0, "x0")
    on = problem.sign * (x0 - problem.psi) <= 0.0
    u = (free or FreeProblem(problem, tol)).solution(on, x0)
    lam = np.where(on, (problem.F - problem.K @ u) / problem.m, 0.0)
    return {"x0": u, "z0": problem.z_step(u, np.zeros(problem.n), 1.0, None), "lam0": lam}


def active_set_multiplier(problem, z: np.ndarray, tol: float = TOL, free: FreeProblem | None = None
                          ) -> np.ndarray:
    """mu >= 0, the nodal contact force of the active-set step from ``z`` (free nodes): the multiplier of the
    discrete problem with z's touched set as its contact set, negative values cut to 0 (any mu >= 0 gives
    a lower bound D(mu) of J(u_h); this one is D's maximiser once the touched set is the solution's).
    ``free``: a :class:`FreeProblem` to reuse, whose solver is kept while the touched set stays."""
    z = _checked(problem, z, "z")
    on = problem.sign * (z - problem.psi) <= 0.0
    u = (free or FreeProblem(problem, tol)).solution(on, z)
    return np.where(on, np.maximum(problem.sign * (problem.K @ u - problem.F), 0.0), 0.0)    # s (K u - F) on A


def warm_start(problem, x0: np.ndarray, lam0: np.ndarray | None = None, step: bool = True,
               tol: float = TOL) -> dict[str, np.ndarray]:
    """The start ``{"x0", "z0", "lam0"}`` of a warm level from the prolongated ``x0`` and ``lam0`` (free nodes).

    Without ``step``: x0 and lam0 as they are, z0 = x0 projected onto the obstacle.  With ``step``: the
    :func:`active_set_start` where its z0 has the lower energy J (module docstring), else the plain start.
    """
    x0 = _checked(problem, x0, "x0")
    plain = {"x0": x0, "z0": problem.z_step(x0, np.zeros(problem.n), 1.0, None)}
    if lam0 is not None:
        plain["lam0"] = _checked(problem, lam0, "lam0")
    if not step:
        return plain
    stepped = active_set_start(problem, x0, tol)
    J = problem.objective                                  # J(z) = 1/2 z'Kz - F'z (+ the boundary data's part)
    return stepped if J(stepped["z0"], stepped["z0"]) <= J(plain["z0"], plain["z0"]) else plain


def _checked(problem, v, name: str) -> np.ndarray:
    """``v`` as a float array of one finite value per free node, else a ValueError naming ``name``."""
    v = np.asarray(v, dtype=float)
    if v.shape != (problem.n,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must hold {problem.n} finite values (one per free node), got shape {v.shape}"
                         + ("" if v.shape != (problem.n,) else " with a NaN or inf"))
    return v


__all__ = ["TOL", "FreeProblem", "active_set_start", "active_set_multiplier", "warm_start"]
