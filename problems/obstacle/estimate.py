"""Error estimates of the obstacle plug-in, and an ADMM stop balanced with the discretisation error.

Two errors stand between an ADMM iterate and the exact solution u of the
variational inequality: the *algebraic* error ||z - u_h||_a (z the iterate,
u_h the exact discrete solution) and the *discretisation* error
||u_h - u||_a, both in the energy norm ``||v||_a = |v|_{H^1}`` (the H1 seminorm).
Iterating once the first is far below the second buys nothing (Ern &
Vohralik 2013, adaptive inexact stopping).

**Algebraic error: a guaranteed bound from the duality gap.**  The discrete
problem is min J(v) = 1/2 v'Kv - F'v subject to s (v - psi) >= 0 (s = +1
for a lower obstacle).  z, the ADMM z-iterate, is feasible (the z-step
projects onto the constraint).  For any mu >= 0 the dual function

    D(mu) = min_v J(v) - mu' s (v - psi) = -1/2 (F + s mu)' K^{-1} (F + s mu) + s mu' psi

is a lower bound of J(u_h) (weak duality), and since u_h minimises J over
the feasible set, J(z) - J(u_h) >= 1/2 ||z - u_h||_K^2.  Hence

    ||z - u_h||_a = ||z - u_h||_K <= sqrt(2 (J(z) - D(mu)))                  (B)

for any mu >= 0.  Two are tried and the larger D(mu) kept: the nodal
contact force of the ADMM multiplier, max(-s M lam, 0) (K u - F + M lam = 0
at a solution), and z's own contact force, max(s (K z - F), 0) on the nodes
where z touches the obstacle (the sharper one once the contact set has
settled); on a warm P2 level a third near a test's threshold, the
multiplier of the problem whose contact set is z's touched set
(:class:`EnergyGap`).  The
bound needs K^{-1} applied to the residual K z - F - s mu (the gap in
residual form, :class:`EnergyGap`): by AMG-preconditioned CG, with a
guaranteed correction for CG's own residual, so it holds whatever CG's
accuracy, and it tends to 0 as ADMM converges.

**Discretisation error: a gradient-recovery (ZZ) estimate** (:mod:`admmkit.problems.obstacle.estimate_zz`),
eta = (sum eta_T^2)^{1/2} of ||grad u_h - G u_h||_{L2(T)}, G u_h the
recovered gradient; or the residual estimator
(:mod:`admmkit.problems.obstacle.estimate_residual`).

**The balanced stop** (:class:`BalancedStop`) fires when (B) <= gamma eta:
the algebraic error of z is then certainly below gamma times the estimated
discretisation error.  Its ``converged`` means exactly that, and the result
says so.
"""
from __future__ import annotations

import math

import numpy as np

from admmkit import BalancedStop as BaseBalancedStop
from admmkit.linalg.amg import AMGPreconditioner
from admmkit.linalg.cg import pcg
from admmkit.linalg.linsolve import factorize

from .estimate_residual import check_estimator, residual_estimator
from .estimate_zz import ZZ, _zz, zz, zz_estimate, zz_indicators
from .warm_start import FreeProblem, active_set_multiplier

#: The obstacle's default gamma, the top of issue #24's band [0.05, 0.5] of the estimate, which bound (B)
#: guarantees.  (B) is tight at a warm level's first iterate and 2-7x loose from the second on, where the
#: ADMM iterate's error had already fallen below 0.05 of the estimate on the fine radial levels: at
#: admmkit's 0.3 the three finest stopped at iteration 2 with 0.03-0.04 (docs/obstacle.md, "The stop's gamma")
OBSTACLE_GAMMA = 0.5


def estimator_of(problem, name: str = "zz"):
    """The indicator function u -> eta_T of the named estimator, ``"zz"`` (this module) or ``"residual"``
    (:mod:`admmkit.problems.obstacle.estimate_residual`), its mesh data built now; ValueError for another name."""
    if check_estimator(name) == "zz":
        return _zz(problem).indicators
    if getattr(problem, "order", 1) != 1:
        raise ValueError(f"estimator 'residual' is written for P1 elements; with P{problem.order} use 'zz'")
    return residual_estimator(problem).indicators


#: the active-set multiplier (a solve with K_II) is tried only where the bound with the other two lies in
#: (enough, DECIDE x enough], where it may decide the test
DECIDE = 4.0

#: EnergyGap's CG goes on until the Friedrichs correction is at most this share of r'y + e'y (bound sharp to 1 %)
SHARP = 0.01

#: the AMG's rho(D^-1 K) from 10 Arnoldi steps (``admmkit.linalg.amg.short_spectral_radius``), as the contact plug-in's:
#: the P1 adaptive radial run to 5e-3 took 7.0, 6.7 s against 8.3, 7.4 s with pyamg's default, paired runs,
#: the same iterations on every level (the bound stays guaranteed: its residual is computed, not CG's)
SPECTRAL_STEPS = 10


class EnergyGap:
    """The guaranteed bound (B) of the algebraic error ||z - u_h||_a; K^{-1} applied by AMG-preconditioned CG.

    **The gap in residual form.**  With b = F + s mu and r = K z - b,

        J(z) - D(mu) = 1/2 r'K^{-1}r + s mu'(z - psi)                         (G)

    (expand 1/2 r'K^{-1}r = 1/2 z'Kz - z'b + 1/2 b'K^{-1}b).  r is small where z is near u_h, and (G) needs
    r'K^{-1}r to a few digits only, where J(z) - D(mu) written out subtracts two numbers of the size of J.
    For any y, with e = r - K y,

        r'K^{-1}r = r'y + e'y + e'K^{-1}e,

    and on the free nodes of the box K >= c M (Friedrichs: the squared H1 seminorm of v is at least
    lambda_1 ||v||_{L2}^2, lambda_1 = pi^2 (1/a^2 + 1/b^2) on an a x b rectangle; the consistent P1 mass
    is at least 1/4 of the lumped one, element by element; in P2 ``mass_ratio`` of the HRZ-lumped one,
    admmkit.problems.obstacle.p2), so e'K^{-1}e <= e'M^{-1}e / c with c = lambda_1 / 4 (P1).  Hence,
    whatever y the CG returns,

        r'K^{-1}r <= r'y + e'y + e'M^{-1}e / c,

    and the bound stays guaranteed; CG only makes it sharp.  The correction e'M^{-1}e / c weighs the
    residual's high frequencies by up to h^-2, so CG (from 0, to a relative energy tolerance ``tol``) goes
    on, 10x tighter each time, until the correction is at most ``sharp`` (default ``SHARP``) of r'y + e'y:
    on the P1 adaptive radial run to 5e-3 that cut the bound's AMG cycles by a third against the written-out
    gap, whose cancellation asked CG for a relative 1e-8 (443 against 686; the run 4.8-6.0 s against 5.6-6.9 s,
    four runs each, the same iterations, meshes and estimate).  ``solver="direct"``
    factorises K instead (exact y, e = 0); ``"auto"`` (the default) does so for P2, whose nodal K took
    AMG-CG 20 ms a bound at 1.8e4 unknowns against 1 ms for a solve with the factor.  The AMG setup of K
    cost 0.3 s at 2.2e5 unknowns where the factorisation cost 1.5 s.

    ``active_set``: whether :meth:`bound` also tries the active-set multiplier of z's touched set where it
    may decide a test (a factorisation of K_II in P2, an AMG setup in P1, kept while the touched set stays:
    :class:`.warm_start.FreeProblem`).  It pays where the touched set starts near the solution's, on a warm
    adaptive level (``solve_adaptive`` turns it on there: ``ACTIVE_SET_BOUND``); a cold run's touched set
    moves for tens of iterations, and each new set costs a factorisation (a cold uniform radial P2 run of
    65,025 unknowns: 17 of them, 8.7 s against 3.9 s without, for 40 iterations against 44).
    """

    def __init__(self, problem, solver: str = "auto", tol: float = 1e-3, sharp: float = SHARP,
                 active_set: bool = False):
        if solver not in ("auto", "amg", "direct"):
            raise ValueError(f"solver must be 'auto', 'amg' or 'direct', got {solver!r}")
        if not sharp > 0:
            raise ValueError(f"sharp = {sharp!r} is outside the accepted range: a number > 0")
        if solver == "auto":        # P2's nodal K: AMG-CG took 20 ms a bound at 1.8e4 unknowns, a factor 1 ms
            solver = "direct" if getattr(problem, "order", 1) == 2 else "amg"
        self.problem, self.solver, self.tol, self.sharp = problem, solver, float(tol), float(sharp)
        if not isinstance(active_set, bool):
            raise ValueError(f"active_set = {active_set!r} is outside the accepted range: True or False")
        self.active_set = active_set
        self._free = FreeProblem(problem)        # its factor kept while z's touched set stays
        x0, x1, y0, y1 = problem.scene.box
        # K >= c M: lambda_1 times the consistent mass's bound against the lumped one (P1 1/4, P2: p2.py)
        self.c = math.pi ** 2 * (1.0 / (x1 - x0) ** 2 + 1.0 / (y1 - y0) ** 2) * getattr(problem, "mass_ratio", 0.25)
        if solver == "direct":      # SuperLU's symmetric mode (admmkit.linalg.linsolve)
            self._K_solve = factorize(problem.K)
        else:
            self._amg = AMGPreconditioner(problem.K, np.ones((problem.n, 1)), spectral_steps=SPECTRAL_STEPS)
        #: how far below psi a value may lie and still count as on the obstacle (rounding of the projection)
        self._feasibility = 1e-12 * max(1.0, float(np.max(np.abs(problem.psi), initial=0.0)))
        self.cg_iterations = 0

    def bound(self, z: np.ndarray, lam: np.ndarray, enough: float = 0.0) -> float:
        """sqrt(2 (J(z) - D(mu))) by (G) with the better of two multipliers; inf if z is not feasible.

        mu_z = max(s (K z - F), 0) on the nodes where z touches the obstacle, 0 elsewhere (z's own contact
        force, sharper once the contact set has settled: on the adaptive radial levels after the first it gave
        the larger D at 64 of 64 tests) and mu_lam = max(-s M lam, 0) (the ADMM multiplier); any mu >= 0 gives
        a bound.  mu_z is tried first; mu_lam, a second solve with K, only where it may decide a test: with
        ``enough`` > 0 (the balanced stop's gamma x estimate) only where mu_z's bound lies in (enough,
        2 enough].  With ``active_set``, where the bound so far lies in (enough, DECIDE x enough], also
        mu_A, the multiplier of the discrete problem whose contact set is z's touched set
        (:func:`.warm_start.active_set_multiplier`): D's maximiser once that set is the solution's, so
        the bound is then sqrt(2 (J(z) - J(u_h))), exact to the first order (a radial P2 level of 685
        unknowns: the bound with mu_z and mu_lam was 3 times the error for five iterations).  The rounding
        of J(z) is added, so the bound never claims less than the floating point can tell.
        """
        p = self.problem
        slack = p.sign * (z - p.psi)
        if np.any(slack < -self._feasibility):
            return math.inf
        Kz = p.K @ z
        rounding = 8 * np.finfo(float).eps * abs(0.5 * z @ Kz - p.F @ z)        # of J(z)
        mu_z = np.where(slack <= self._feasibility, np.maximum(p.sign * (Kz - p.F), 0.0), 0.0)
        gap = self._gap(Kz, z, mu_z)                                           # >= J(z) - D(mu_z) >= 0
        if not enough > 0.0 or enough < math.sqrt(2.0 * (gap + rounding)) <= 2.0 * enough:
            gap = min(gap, self._gap(Kz, z, np.maximum(-p.sign * p.m * lam, 0.0)))
        if self.active_set and enough > 0.0 and enough < math.sqrt(2.0 * (gap + rounding)) <= DECIDE * enough:
            gap = min(gap, self._gap(Kz, z, active_set_multiplier(p, z, free=self._free)))
        return math.sqrt(2.0 * (gap + rounding))

    def _gap(self, Kz: np.ndarray, z: np.ndarray, mu: np.ndarray) -> float:
        """An upper bound of J(z) - D(mu) by (G) (exact up to rounding with the factorisation)."""
        p = self.problem
        r = Kz - p.F - p.sign * mu
        complementarity = float(p.sign * mu @ (z - p.psi))
        if self.solver == "direct":
            return 0.5 * max(float(r @ self._K_solve(r)), 0.0) + complementarity
        y, tol = np.zeros_like(r), self.tol
        while True:
            y, its, _, _, _ = pcg(lambda v: p.K @ v, r, y, self._amg, tol=tol, maxiter=500)
            self.cg_iterations += its
            e = r - p.K @ y                                                    # the true residual, not CG's
            rest = float(r @ y + e @ y)
            correction = float(e @ (e / p.m)) / self.c                         # >= e'K^{-1}e
            if correction <= self.sharp * max(rest, 0.0) or tol < 1e-12:
                return 0.5 * max(rest + correction, 0.0) + complementarity
            tol *= 0.1


class BalancedStop(BaseBalancedStop):
    """:class:`admmkit.BalancedStop` for the obstacle: bound (B) of z against an estimate of z's discretisation error.

    ``estimator``: ``"zz"`` (this module's ZZ estimate, the default) or ``"residual"``
    (:mod:`admmkit.problems.obstacle.estimate_residual`).  ``gamma``: ``OBSTACLE_GAMMA`` (0.5) by default.
    Tested at most ``every`` iterations apart (:mod:`admmkit.fe.balanced_stop`'s
    schedule), first at iterations 1 and 2: a warm level that starts from the
    active-set step (P1) is often done at its first iterate, where (B) is tight
    (9 of 14 warm radial P1 levels to 3.8e-3 stopped there; the true error
    0.02-0.46 of the estimate, the bound 0.02-0.48).  ``active_set``: (B) also tries the active-set
    multiplier where it may decide a test (:class:`EnergyGap`; for warm levels).
    """

    def __init__(self, problem, gamma: float = OBSTACLE_GAMMA, every: int = 10, estimator: str = "zz",
                 active_set: bool = False):
        self._estimate = estimator_of(problem, estimator)      # refuses an unknown name before anything is built
        super().__init__(gamma, every)
        if estimator != "zz":
            self.name = self.name.replace("ZZ", estimator)
        self.problem = problem
        self.estimator = estimator
        self.gap = EnergyGap(problem, active_set=active_set)

    def algebraic_error_bound(self, rec) -> float:
        """(B) for the z-iterate (inf if z is not feasible); the second multiplier only where it may decide."""
        enough = self.gamma * self.discretisation
        return self.gap.bound(rec.z, rec.lam, enough if math.isfinite(enough) else 0.0)

    def discretisation_estimate(self, rec) -> float:
        """The chosen estimate eta (ZZ or residual) of the z-iterate."""
        return float(np.sqrt(np.sum(self._estimate(rec.z) ** 2)))


__all__ = ["OBSTACLE_GAMMA", "ZZ", "zz", "zz_indicators", "zz_estimate", "estimator_of", "EnergyGap", "BalancedStop"]
