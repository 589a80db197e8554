"""A guaranteed bound of the algebraic error for Tresca friction (condensed mode): a duality gap on Gamma_C.

The discrete Tresca problem (docs/friction.md) is::

    min_u P(u) = J(u) + j(A_t u),   J(u) = 1/2 u'Ku - f'u,   subject to B u <= g,
    j(t) = sum_i mc_i s_i |t_i - w_i|      (w_i: the foundation's slide),

with A = [B; T] (normal, then tangential components, blocks of n_c) and
M = M_c on every block.  P + I_{Bu <= g} is 1-strongly convex in the energy
norm ||v||_a = (v'Kv)^{1/2}, so its minimiser u_h satisfies, for every
feasible v,

    P(v) - P(u_h) >= ||v - u_h||_a^2 / 2.                                  (S)

**The iterate.**  In the condensed mode every iterate is u = u0 + K^{-1}A'w
(u0 = K^{-1}f, d0 = A u0, C = A K^{-1}A', e0 = f'u0), so that::

    A u = d0 + C w,      J(u) = -e0/2 + w'Cw/2.

**The dual function.**  With ``|x| = sup_{|y| <= 1} y.x`` and ``I_{<=0}(x) =
sup_{y >= 0} y x``, for nodal forces mu = (mu_n, mu_t) (mu = M lam, lam the
tractions p_n, q)::

    P(u) + I(B u <= g) = sup_{mu in Lambda} J(u) + mu'(A u - h),
    Lambda = {mu_n,i >= 0, |mu_t,i| <= mc_i s_i},   h = (g, w),

and exchanging sup and min (min_u at u = u0 - K^{-1}A'mu) gives the dual
function, a lower bound of P(u_h) for every mu in Lambda (weak duality)::

    D(mu) = min_u J(u) + mu'(A u - h) = -e0/2 + mu'(d0 - h) - mu'C mu / 2 <= P(u_h).

**The bound.**  For a feasible u' = u0 + K^{-1}A'w' (its normal part
(d0 + C w')_n <= g), (S) and weak duality give J(u') + j(u') - D(mu) >=
||u' - u_h||_a^2 / 2, and by the triangle inequality::

    ||u - u_h||_a <= ||u - u'||_a + sqrt(2 (P(u') - D(mu))),              (B_t)

with ||u - u'||_a^2 = (w - w')'C(w - w') and P(u') = -e0/2 + w''Cw'/2 +
j(d0 + C w').  The e0/2 cancels in the gap.  Everything lives on Gamma_C,
d n_c unknowns: one Cholesky factorisation of C per problem (its slip bound s
is read at each evaluation, so Coulomb's fixed point, which changes s
between Tresca solves, can keep it), then O((d n_c)^2) per evaluation.

*Primal candidates* (A u' = d', w' = C^{-1}(d' - d0)): the iterate's own
A u with its normal part clipped to g; the z-iterate (z_n <= g after the
z-step, z_t the shrunk slip); and the active-set one below.  The one of
least P is kept.  *Dual candidates*, each projected onto Lambda (mu_n to
max(mu_n, 0), mu_t,i shrunk to length <= mc_i s_i): the ADMM multiplier's
nodal force M lam; the kept primal candidate's own force -w' (normal part on
the nodes it puts on the obstacle only); and the active-set multiplier.

*The active-set candidate* (as (A) of the frictionless bound, with the stick
and slip zones).  From the z-iterate: the contact nodes N (z_n = g or
(A u)_n >= g), the stick nodes S (z_t = w: the shrink put the slip to zero),
and on the other (slip) nodes the direction ``sigma_i = (z_t,i - w_i) /
|z_t,i - w_i|``.  Tresca's law fixes the forces mu_n = 0 off N and
mu_t,i = mc_i s_i sigma_i on the slip nodes (the set F); the unknown ones,
U = (normal on N, tangential on S), make the displacement meet the
obstacle and the foundation there, (d0 - C mu)_U = h_U::

    C_UU mu_U = (d0 - h)_U - C_UF mu_F.                                    (A_t)

If N, S and sigma are the solution's, mu is in Lambda and d0 - C mu = A u_h,
so P(u') = D(mu) and (B_t) is the true error.  C_UU is factorised once per
(N, S) and kept while they hold; sigma enters the right-hand side only.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.linalg as sla


class TrescaGap:
    """The guaranteed bound (B_t) of ||u - u_h||_a for the condensed Tresca mode (module docstring)."""

    def __init__(self, problem):
        friction = getattr(problem, "friction", None)
        if getattr(problem, "mode", None) != "condensed" or friction is None:
            raise ValueError("the Tresca error bound needs a contact problem with friction in mode 'condensed' "
                             f"(got mode {getattr(problem, 'mode', None)!r}"
                             f"{'' if friction is not None else ', frictionless'})")
        self.problem = problem
        self.n_c = problem.ops.n_c
        self._C = sla.cho_factor(problem.C)
        self._zones_key, self._C_UU = None, None

    def obstacle(self) -> np.ndarray:
        """h = (g, w): the obstacle of the normal block and the foundation's slide on the tangential ones."""
        q, n_c = self.problem, self.n_c
        slide = q.friction.slide
        w = np.zeros(q.C.shape[0] - n_c) if slide is None else slide.T.ravel()
        return np.concatenate((q.g, w))

    def friction_work(self, d: np.ndarray) -> float:
        """j = sum_i mc_i s_i ``|d_t,i - w_i|`` at the constraint values d = A u'."""
        q, n_c = self.problem, self.n_c
        slip = (d - self.obstacle())[n_c:].reshape(-1, n_c)
        return float(q.mc @ (q.friction.s * np.sqrt(np.sum(slip * slip, axis=0))))

    def project(self, mu: np.ndarray) -> np.ndarray:
        """mu onto Lambda: mu_n >= 0, ``|mu_t,i| <= mc_i s_i`` (the tangential force shrunk node by node)."""
        q, n_c = self.problem, self.n_c
        mu_t = mu[n_c:].reshape(-1, n_c)
        bound = q.mc * q.friction.s
        length = np.sqrt(np.sum(mu_t * mu_t, axis=0))
        factor = np.minimum(1.0, bound / np.maximum(length, 1e-300))
        return np.concatenate((np.maximum(mu[:n_c], 0.0), (mu_t * factor).ravel()))

    def bound(self, w: np.ndarray, z: np.ndarray, lam: np.ndarray) -> float:
        """(B_t) for the iterate u = u0 + K^{-1}A'w with z-iterate z and multiplier lam (module docstring)."""
        q, n_c = self.problem, self.n_c
        C, d0, g = q.C, q.d0, q.g
        h = self.obstacle()
        tol = 1e-12 * max(1.0, float(np.max(np.abs(g), initial=0.0)))
        d = d0 + C @ w                                                     # A u
        mu_active = self.active_set_multiplier(z, d, tol)                  # (A_t)
        candidates = []
        for target in (d, z, d0 - C @ mu_active):
            target = np.concatenate((np.minimum(target[:n_c], g), target[n_c:]))     # feasible: d'_n <= g
            w1 = sla.cho_solve(self._C, target - d0)
            P1 = 0.5 * w1 @ (C @ w1) + self.friction_work(d0 + C @ w1)    # P(u') + e0/2
            candidates.append((P1, w1))
        P1, w1 = min(candidates, key=lambda t: t[0])
        touching = np.concatenate(((d0 + C @ w1)[:n_c] >= g - tol, np.ones(C.shape[0] - n_c, dtype=bool)))
        dual = max(mu @ (d0 - h) - 0.5 * mu @ (C @ mu)                     # D(mu) + e0/2
                   for mu in (self.project(q.w * lam), self.project(np.where(touching, -w1, 0.0)), mu_active))
        rounding = 8 * np.finfo(float).eps * (abs(P1) + abs(dual) + q.e0)
        distance = math.sqrt(max((w - w1) @ (C @ (w - w1)), 0.0))         # ||u - u'||_a
        return distance + math.sqrt(2.0 * (max(P1 - dual, 0.0) + rounding))

    def active_set_multiplier(self, z: np.ndarray, d: np.ndarray, tol: float) -> np.ndarray:
        """mu of (A_t) projected onto Lambda, with N, S and sigma read off the z-iterate z and A u = d."""
        q, n_c = self.problem, self.n_c
        h = self.obstacle()
        slip = (z - h)[n_c:].reshape(-1, n_c)
        length = np.sqrt(np.sum(slip * slip, axis=0))
        contact = (z[:n_c] >= q.g - tol) | (d[:n_c] >= q.g - tol)          # N
        stick = length == 0.0                                              # S: the shrink's exact zero
        unknown = np.concatenate((contact, np.tile(stick, slip.shape[0])))  # U
        mu = np.zeros(q.C.shape[0])
        sigma = slip / np.maximum(length, 1e-300)
        mu[n_c:] = np.where(stick, 0.0, q.mc * q.friction.s * sigma).ravel()   # mu_F: Tresca on the slip nodes
        index = np.flatnonzero(unknown)
        if index.size:
            key = unknown.tobytes()
            if key != self._zones_key:                # C_UU: a principal block of the SPD C, SPD
                self._zones_key, self._C_UU = key, sla.cho_factor(q.C[np.ix_(index, index)])
            fixed = np.flatnonzero(~unknown)
            rhs = (q.d0 - h)[index] - q.C[np.ix_(index, fixed)] @ mu[fixed]
            mu[index] = sla.cho_solve(self._C_UU, rhs)
        return self.project(mu)


__all__ = ["TrescaGap"]
