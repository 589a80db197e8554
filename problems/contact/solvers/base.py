"""What every mode of the contact problem shares: the z-step, the inner product of Gamma_C, KKT.

The three modes (:mod:`admmkit.problems.contact.solvers.problem`: full, condensed,
iterative) differ only in their x-step and in what x is; the constraint
space, the z-step (a projection, or the friction law's), the objective and
the KKT residuals are the same, written here once.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from admmkit import Problem

from admmkit.problems.contact.model.operators import ContactOperators
from admmkit.problems.contact.solvers.friction import friction_z_step, stick_slip


def constraint_matrix(ops: ContactOperators) -> sp.spmatrix:
    """A: B frictionless (or stick), [B; T] with friction."""
    return ops.B if ops.friction is None else sp.vstack([ops.B, ops.T]).tocsr()


class _ContactBase(Problem):
    """What all modes share: the z-step, the M_c inner product, diagnostics.

    Frictionless (or stick): A = B, the constraint space is R^{n_c} with M_c.
    With friction: A = [B; T] (normal, then the tangential components, each a
    block of n_c), the inner product M_c on every block, and the z-step is the
    projection plus Tresca's shrink (:func:`admmkit.problems.contact.solvers.friction.friction_z_step`).
    """

    c = 0.0

    def __init__(self, ops: ContactOperators):
        self.ops = ops
        self.mc, self.g = ops.mc, ops.g
        self.friction = ops.friction
        self.A = constraint_matrix(ops)
        self.w = ops.mc if self.friction is None else np.tile(ops.mc, self.A.shape[0] // ops.n_c)
        self._AAt = None   # A A', built on the first adjoint_norm (only order xz needs it)

    def z_step(self, Ax, lam, rho, z):
        """p = min(g, u_n + lam/rho), eq. (11); with friction also the shrink (11t) of the tangential part."""
        if self.friction is None:
            return np.minimum(self.g, Ax + lam / rho)
        return friction_z_step(Ax + lam / rho, self.g, self.friction.s, rho, self.friction.slide)

    def inner(self, a, b):
        """(a, b)_Gc with the lumped boundary mass (on every component block)."""
        return float(np.dot(self.w * a, b))

    def adjoint_norm(self, y):
        """||A' M y||_2 (Boyd's dual residual for order xz)."""
        if self._AAt is None:
            self._AAt = (self.A @ self.A.T).tocsr()   # ||A'v||^2 = v'AA'v
        v = self.w * y
        return float(np.sqrt(max(v @ (self._AAt @ v), 0.0)))

    def _product(self, name: str, M, v: np.ndarray) -> np.ndarray:
        """M @ v, kept per ``name`` for the last v (compared entry for entry): the objective, kkt and kkt_relative
        of one result ask for K u and A'M lam at the same u and lam, one sparse product each instead of three."""
        held = self.__dict__.setdefault("_products", {})
        last = held.get(name)
        if last is not None and last[0].dtype == v.dtype and np.array_equal(last[0], v):
            return last[1]
        product = M @ v
        held[name] = (np.array(v, copy=True), product)
        return product

    def _adjoint(self):
        """A' (scipy's transpose of A, made once: each ``A.T`` builds a new matrix, 0.1-0.2 ms of the four that
        a result's kkt and kkt_relative took at Example 1, h = 1/40)."""
        held = self.__dict__.get("_At")
        if held is None or held[0] is not self.A:
            held = self.__dict__["_At"] = (self.A, self.A.T)
        return held[1]

    def objective(self, u, z):
        """J(u) = 1/2 u'Ku - f'u, plus the Tresca term sum_i mc_i s_i |u_t,i - w_i| with friction."""
        J = float(0.5 * u @ self._product("Ku", self.ops.K, u) - self.ops.f @ u)
        if self.friction is not None:
            J += float(self.mc @ (self.friction.s * np.linalg.norm(self.slip(u), axis=0)))
        return J

    def slip(self, u) -> np.ndarray:
        """(d-1, n_c): the tangential displacement relative to the foundation, T u - w."""
        n_c = self.ops.n_c
        w = 0.0 if self.friction.slide is None else self.friction.slide.T
        return (self.ops.T @ u).reshape(-1, n_c) - w

    def kkt(self, u, z, lam):
        """KKT residuals of the discrete problem at the full displacement u.

        stationarity ||K u - f + A'M lam||_inf / ||f||_inf, penetration
        max (B u - g)^+, negative pressure max (-lam_n)^+, complementarity
        max |lam_n (g - B u)|; also the total contact force sum M_c lam_n and the
        number of active nodes (where the last z-step put p on the obstacle, p = g).
        With friction also: the friction bound max (|q| - s)^+ and the slip
        complementarity max |s |u_t - w| - q.(u_t - w)| (q = lam_t, the tangential
        traction), the tangential force sum M_c q and the stick and slip node counts.
        """
        ops, n_c = self.ops, self.ops.n_c
        un = ops.B @ u
        lam_n = lam[:n_c]
        stat = self._product("Ku", ops.K, u) - ops.f + self._product("A'M lam", self._adjoint(), self.w * lam)
        out = {
            "stationarity": float(np.abs(stat).max() / max(np.abs(ops.f).max(), 1e-300)),
            "penetration": float(np.maximum(un - self.g, 0.0).max(initial=0.0)),
            "negative_pressure": float(np.maximum(-lam_n, 0.0).max(initial=0.0)),
            "complementarity": float(np.abs(lam_n * (self.g - un)).max(initial=0.0)),
            "contact_force": float(self.mc @ lam_n),
            "active_nodes": int(np.count_nonzero(z[:n_c] >= self.g)),
        }
        if self.friction is not None:
            q = lam[n_c:].reshape(-1, n_c)
            s, slip = self.friction.s, self.slip(u)
            zone = stick_slip(z, self.g, self.friction.slide)
            out |= {"friction_bound": float(np.maximum(np.linalg.norm(q, axis=0) - s, 0.0).max(initial=0.0)),
                    "slip_complementarity": float(np.abs(s * np.linalg.norm(slip, axis=0)
                                                         - np.sum(q * slip, axis=0)).max(initial=0.0)),
                    **({"tangential_force": float(self.mc @ q[0])} if len(q) == 1 else
                       {f"tangential_force_{j + 1}": float(self.mc @ qj) for j, qj in enumerate(q)}),
                    "stick_nodes": int(np.count_nonzero(zone == 1)),
                    "slip_nodes": int(np.count_nonzero(zone == 2))}
        return out

    def kkt_relative(self, u, z, lam):
        """The KKT residuals relative to the problem's scales (inf-norms), which admmkit compares with the
        stopping rule's tolerance (a run whose worst measure is above 10x that is ``converged_inaccurate``).

        penetration / max(|g|, |B u|), stationarity / max(|f|, |K u|, |A'M lam|), negative pressure
        / |lam_n|, complementarity / (|lam_n| max(|g|, |B u|)); with friction also the friction bound
        / S and the slip complementarity / (S max |u_t - w|), S = max(max s, |lam_n|).
        """
        ops, n_c = self.ops, self.ops.n_c
        inf = lambda v: float(np.abs(v).max(initial=0.0))  # noqa: E731
        un, lam_n = ops.B @ u, lam[:n_c]
        Ku, Alam = self._product("Ku", ops.K, u), self._product("A'M lam", self._adjoint(), self.w * lam)
        u_scale = max(inf(self.g), inf(un), 1e-300)
        lam_scale = max(inf(lam_n), 1e-300)
        out = {
            "penetration": inf(np.maximum(un - self.g, 0.0)) / u_scale,
            "stationarity": inf(Ku - ops.f + Alam) / max(inf(ops.f), inf(Ku), inf(Alam), 1e-300),
            "negative_pressure": inf(np.maximum(-lam_n, 0.0)) / lam_scale,
            "complementarity": inf(lam_n * (self.g - un)) / (lam_scale * u_scale),
        }
        if self.friction is not None:
            q, s, slip = lam[n_c:].reshape(-1, n_c), self.friction.s, self.slip(u)
            s_scale = max(inf(s), lam_scale)   # the pressure's scale when s = 0 (frictionless Tresca)
            length = np.linalg.norm(slip, axis=0)
            out["friction_bound"] = inf(np.maximum(np.linalg.norm(q, axis=0) - s, 0.0)) / s_scale
            out["slip_complementarity"] = inf(s * length - np.sum(q * slip, axis=0)) / (s_scale * max(inf(length), 1e-300))
        return out
