"""Error estimates of the contact plug-in and an ADMM stop balanced with the discretisation error.

The energy norm is ||v||_a = ||v||_K = (v'Kv)^{1/2}, the x norm of the plug-in.

**Algebraic error: a guaranteed bound** (frictionless contact, condensed
mode).  The discrete problem is min J(u) = 1/2 u'Ku - f'u subject to
B u <= g.  In the condensed mode every iterate is u = u0 + K^{-1} B'w
(u0 = K^{-1} f, d0 = B u0, C = B K^{-1} B', e0 = f'u0), so that

    B u = d0 + C w,      J(u) = -e0/2 + w'Cw/2.

*A feasible point.*  For any d' <= g, w' = C^{-1}(d' - d0) gives a feasible
u' with B u' = d'; two are tried, d' = min(B u, g) and d' = p (the
z-iterate, p <= g), and the one of smaller J kept.  *A lower bound.*  For
any mu >= 0 the dual function is

    D(mu) = min_u J(u) + mu'(B u - g) = -e0/2 + mu'(d0 - g) - mu'C mu/2 <= J(u_h);

the candidates are mu = max(M_c lam, 0) (the ADMM multiplier's nodal force),
each u''s own contact force max(-w', 0) on the nodes where d' = g, and the
active-set multiplier below.  Since u_h
minimises J over the feasible set, J(u') - J(u_h) >= ||u' - u_h||_a^2 / 2, and

    ||u - u_h||_a <= ||u - u'||_a + sqrt(2 (J(u') - D(mu)))                   (B)

with ||u - u'||_a^2 = (w - w')'C(w - w').  Everything lives on Gamma_C: one
Cholesky factorisation of C (n_c x n_c) per problem, then O(n_c^2) per
evaluation.

*The active-set candidate* makes (B) exact once ADMM has found the contact
set.  With A the nodes the iterate touches (p = g or B u >= g), the
multiplier of the problem restricted to B_A u = g_A solves

    C_AA mu_A = (d0 - g)_A,     mu = 0 off A,                              (A)

(the stationarity of D on A).  max(mu, 0) is a dual candidate and
d' = min(d0 - C max(mu, 0), g) a primal one.  If A is the solution's active
set, mu >= 0 and d' = B u_h: J(u') = D(mu) = J(u_h) and (B) is the true
error ||u - u_h||_a.  Measured at the balanced stop (gamma 0.1) on Examples
1 and 2, P1 and P2, h = 1/10 and 1/20: (B) / true error went from 2.0-5.2 to
1.0 (1.6 once), and the stop came 0-8 iterations sooner.  (A) costs one
Cholesky factorisation of C_AA per new active set (kept while A holds).

*Corrected by the primal-dual active set method.*  Early in a run the
touched set A is not the solution's: it holds nodes that the iterate
pushes into the obstacle but the solution lifts off (mu_A < 0 there), and
misses some that d0 - C mu puts through it.  (A) is the stationarity of
the boundary dual, max D(mu) over mu >= 0, a small dense QP, on A; up to
``PDAS_STEPS`` steps of the primal-dual active set method (Hintermüller,
Ito & Kunisch 2003) correct A,

    A <- {i in A : mu_i > 0} + {i not in A : (d0 - C mu)_i > g_i},             (A')

and (A) is solved on the new set, until A holds.  Every set gives valid
candidates (max(mu, 0) >= 0, d' <= g), so (B) stays guaranteed; a better
set only sharpens it.  On Example 1 P1's adaptive path (to 1e-2) two
early levels stopped after 4 iterations (one at 0.045 of the estimate),
though their true algebraic error was below gamma x the estimate from the
first iterate (0.13-0.20): the bound was at least 4 times the error until
then.  With (A') every level ended at 0.18-0.29 (gamma 0.3), and the warm
levels took 14 iterations in all against 19.

**Discretisation error: a gradient-recovery (ZZ) estimate.**  G, the
displacement gradient recovered into continuous finite elements of the
scene's order (NGSolve's ``Set``), e = sym(grad u_h) - sym(G), and

    eta_T^2 = int_T 2 mu e:e + lambda tr(e)^2,      eta = (sum_T eta_T^2)^{1/2},

an estimate (not a bound) of ||u_h - u||_a in 2D and 3D, P1 and P2.

**With Tresca friction** (and each Tresca problem of Coulomb's fixed point)
the same construction, a feasible point and a dual lower bound on Gamma_C,
gives the bound (B_t) of :mod:`admmkit.problems.contact.solvers.estimate_friction`;
the ZZ estimate applies unchanged (it reads the displacement only).

**The balanced stop** (:class:`BalancedStop`) fires when (B) <= gamma eta;
its ``converged`` means that the algebraic error of the returned u is
certainly below gamma times the estimated discretisation error.
"""
from __future__ import annotations

import math

import ngsolve as ng
import numpy as np
import scipy.linalg as sla

from admmkit import BalancedStop as BaseBalancedStop
from admmkit.fe.balanced_stop import GAMMA

from admmkit.problems.contact.model.assembly import lame
from admmkit.problems.contact.solvers.estimate_friction import TrescaGap
from admmkit.problems.contact.solvers.estimate_residual import (check_estimator, condensed_pressure, residual_estimate,
                                                               residual_estimator, residual_indicators)

#: the most primal-dual active set steps (A') that correct the touched set of the active-set candidate
PDAS_STEPS = 3


def zz_indicators(ops, u: np.ndarray) -> np.ndarray:
    """eta_T in the energy norm for every element (u: the displacement on the free dofs)."""
    d, order = ops.mesh.dim, ops.scene.order
    gf = ops.to_gridfunction(u)
    recovered = ng.GridFunction(ng.H1(ops.mesh, order=order, dim=d * d))
    recovered.Set(ng.Grad(gf).Reshape((d * d,)))
    e = ng.Sym(ng.Grad(gf)) - ng.Sym(recovered.Reshape((d, d)))
    mu, lam = lame(ops.scene.E, ops.scene.nu)
    density = 2 * mu * ng.InnerProduct(e, e) + lam * ng.Trace(e) ** 2
    eta2 = ng.Integrate(density * ng.dx(bonus_intorder=2), ops.mesh, element_wise=True)
    return np.sqrt(np.maximum(np.asarray(eta2), 0.0))


def zz_estimate(ops, u: np.ndarray) -> float:
    """eta = (sum_T eta_T^2)^{1/2}: the ZZ estimate of the discretisation error ||u_h - u||_a."""
    return float(np.sqrt(np.sum(zz_indicators(ops, u) ** 2)))


class CondensedGap:
    """The guaranteed bound (B) of ||u - u_h||_a for the condensed frictionless mode."""

    def __init__(self, problem):
        if getattr(problem, "mode", None) != "condensed" or problem.friction is not None:
            raise ValueError("the algebraic error bound needs a frictionless contact problem in mode 'condensed' "
                             f"(got mode {getattr(problem, 'mode', None)!r}"
                             f"{', with friction: TrescaGap' if getattr(problem, 'friction', None) else ''})")
        self.problem = problem
        self._C = sla.cho_factor(problem.C)
        self._active_key, self._mu_active = None, None

    def bound(self, w: np.ndarray, p: np.ndarray, lam: np.ndarray) -> float:
        """(B) for the iterate u = u0 + K^{-1} B'w with z-iterate p and multiplier lam."""
        q = self.problem
        C, d0, g = q.C, q.d0, q.g
        tol = 1e-12 * max(1.0, float(np.max(np.abs(g), initial=0.0)))
        d = d0 + C @ w
        mu_active = self.active_set_multiplier((p >= g - tol) | (d >= g - tol), tol)       # (A), (A')
        candidates = []
        for target in (np.minimum(d, g), np.minimum(p, g), np.minimum(d0 - C @ mu_active, g)):
            w1 = sla.cho_solve(self._C, target - d0)
            candidates.append((0.5 * w1 @ (C @ w1), w1, target))      # J(u') + e0/2
        J1, w1, d1 = min(candidates, key=lambda t: t[0])
        touching = d1 >= g - tol
        dual = max(mu @ (d0 - g) - 0.5 * mu @ (C @ mu)                   # D(mu) + e0/2
                   for mu in (np.maximum(q.mc * lam, 0.0), np.where(touching, np.maximum(-w1, 0.0), 0.0),
                              mu_active))
        rounding = 8 * np.finfo(float).eps * (abs(J1) + abs(dual) + q.e0)
        distance = math.sqrt(max((w - w1) @ (C @ (w - w1)), 0.0))
        return distance + math.sqrt(2.0 * (max(J1 - dual, 0.0) + rounding))

    def active_set_multiplier(self, active: np.ndarray, tol: float = 0.0) -> np.ndarray:
        """max(mu, 0) with mu of (A) on the nodes ``active`` (a boolean mask), the set corrected by up to
        ``PDAS_STEPS`` steps (A') (``tol``: the slack a node may pass g by and stay off it); kept while the
        given set holds."""
        key = active.tobytes()
        if key != self._active_key:
            mu = self._restricted_multiplier(active)
            for _ in range(PDAS_STEPS):
                through = self.problem.d0 - self.problem.C @ mu > self.problem.g + tol
                corrected = (mu > 0.0) | (~active & through)                                              # (A')
                if np.array_equal(corrected, active) or not corrected.any():
                    break
                active, mu = corrected, self._restricted_multiplier(corrected)
            self._active_key, self._mu_active = key, np.maximum(mu, 0.0)
        return self._mu_active

    def _restricted_multiplier(self, active: np.ndarray) -> np.ndarray:
        """mu of (A): C_AA mu_A = (d0 - g)_A on the nodes ``active``, 0 elsewhere."""
        q, index = self.problem, np.flatnonzero(active)
        mu = np.zeros(q.g.shape[0])
        if index.size:
            C_AA = q.C[np.ix_(index, index)]                  # a principal block of the SPD C: SPD
            mu[index] = sla.cho_solve(sla.cho_factor(C_AA), (q.d0 - q.g)[index])
        return mu


def algebraic_gap(problem):
    """The guaranteed algebraic error bound of a condensed contact problem: ``TrescaGap`` (B_t) with friction
    (Tresca, or a Coulomb fixed point's current Tresca problem), else :class:`CondensedGap` (B)."""
    return TrescaGap(problem) if getattr(problem, "friction", None) is not None else CondensedGap(problem)


class BalancedStop(BaseBalancedStop):
    """:class:`admmkit.BalancedStop` for contact: bound (B) of u against an estimate of u's discretisation error.

    ``estimator``: ``"zz"`` (this module's, the default) or ``"residual"``
    (:mod:`admmkit.problems.contact.solvers.estimate_residual`, with the pressure
    that balances the iterate, -w / m_c).  Tested at most ``every`` iterations
    apart, first at iterations 1 and 2 (:mod:`admmkit.fe.balanced_stop`'s
    schedule): the bound costs O(n_c^2) on the condensed boundary, the estimate
    (one solve with K's factorisation) is taken only near firing, and a
    warm-started adaptive level can end after 1-6 iterations where a test every
    10 held it to 10 (Example 1's warm levels).
    """

    def __init__(self, problem, gamma: float = GAMMA, every: int = 2, estimator: str = "zz"):
        check_estimator(estimator)
        if estimator == "residual" and getattr(problem, "friction", None) is not None:
            raise ValueError("estimator 'residual' is Hild & Nicaise's frictionless residual estimator (it counts "
                             "the tangential stress on Gamma_C as error); with friction use 'zz'")
        super().__init__(gamma, every)
        self.gap = algebraic_gap(problem)           # CondensedGap (B), or TrescaGap (B_t) with friction
        self.problem = problem
        self.estimator = estimator
        if estimator != "zz":
            self.name = self.name.replace("ZZ", estimator)
            residual_estimator(problem.ops)           # the estimator's mesh data, built before the run

    def algebraic_error_bound(self, rec) -> float:
        """(B) (with friction (B_t)) for the x-iterate (s, w); inf unless s = 1, as after every x-step."""
        return self.gap.bound(rec.x[1:], rec.z, rec.lam) if rec.x[0] == 1.0 else math.inf

    def discretisation_estimate(self, rec) -> float:
        """The chosen estimate eta (ZZ or residual) of the full displacement of the x-iterate."""
        u = self.problem.finalize(rec.x)
        if self.estimator == "zz":
            return zz_estimate(self.problem.ops, u)
        return residual_estimate(self.problem.ops, u, condensed_pressure(self.problem, rec.x))


def balanced_residual_stop(scene, gamma: float):
    """(operators, stop) for ``solve_scene(operators, stop=stop, mode="condensed")``: the scene assembled and a
    balanced stop comparing with the residual estimate, on a condensed problem of these operators."""
    from admmkit.problems.contact.model.assembly import ContactOperators, assemble
    from admmkit.problems.contact.model.assembly3d import assemble3d
    from admmkit.problems.contact.model.scene3d import Scene3D
    from admmkit.problems.contact.solvers.problem import contact_problem
    if isinstance(scene, ContactOperators):
        ops = scene
    else:
        ops = assemble3d(scene) if isinstance(scene, Scene3D) else assemble(scene)
    return ops, BalancedStop(contact_problem(ops, mode="condensed"), gamma, estimator="residual")


def estimator_indicators(ops, u: np.ndarray, lam: np.ndarray, name: str = "zz") -> np.ndarray:
    """eta_T of the named estimator, ``"zz"`` or ``"residual"`` (lam, the pressure at the contact nodes, is used
    by the residual one only); ValueError for another name."""
    if check_estimator(name) == "zz":
        return zz_indicators(ops, u)
    return residual_indicators(ops, u, lam)


__all__ = ["zz_indicators", "zz_estimate", "CondensedGap", "algebraic_gap", "BalancedStop", "estimator_indicators",
           "balanced_residual_stop"]
