"""The obstacle's x-step (K + rho M) u = b by Jacobi-preconditioned CG, with a factorisation where CG is dear.

M is the lumped mass (diagonal), so the diagonal of K + rho M is diag(K) + rho m
and Jacobi-preconditioned CG costs one product with K per iteration, with no
set-up.  Its speed depends on rho: where rho m_i dominates K's diagonal (large
rho on a fine mesh, as on the late levels of an adaptive run) the matrix is
close to its diagonal and CG needs some twenty iterations (to a relative
residual 1e-10 of the x-step written for x); where rho is small against the
stiffness, hundreds.  The x-step is solved for its correction x - z, to a
relative residual ``TOL`` of z's own residual (:meth:`JacobiCG.__call__`).  So, per
value of rho, CG runs until it has cost ``price`` iterations in all (the
rent), then K + rho M is factorised (:class:`admmkit.linalg.linsolve.CachedFactorization`,
the buy) and used for every later solve at that rho: never more than twice
what the better of the two would have cost in hindsight (the rent-or-buy
rule), counted in iterations, not seconds, so the iterates do not depend on
the machine's load.  CG starts at the previous x-iterate (a warm level's
prolongated solution on its first step).

Measured on the adaptive radial obstacle (2.2e5 unknowns, rho 2e4): ten
x-steps by CG in 0.6 s in all, where one factorisation took 1.6 s.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from admmkit.linalg.linsolve import CachedFactorization

#: the x-step of the adaptive levels (admmkit.problems.obstacle.adaptive): this one
ADAPTIVE_BACKEND = "jacobi"
#: CG iterations at one rho before K + rho M is factorised; one SuperLU factorisation of the obstacle's
#: K + rho M cost about as much as 400-600 Jacobi-CG iterations from 4e4 to 2.2e5 unknowns (this machine)
PRICE = 400
#: CG's relative residual, against the correction's right-hand side F - K z - M lam (z's own residual).  Radial
#: P1 to 5e-3, CG iterations over the run: 2,413 at 1e-6, 3,125 at 1e-8, 3,710 and one more factorisation at
#: 1e-10, and the same ADMM iterations on every level; before (x itself, 1e-10 of F + M (rho z - lam)) 2,936
TOL = 1e-6


class JacobiCG:
    """The x-step (K + rho M) u = F + M (rho z - lam), M = diag(m): Jacobi-preconditioned CG, rent-or-buy
    factorisation per rho (module docstring)."""

    def __init__(self, K: sp.spmatrix, F: np.ndarray, m: np.ndarray, backend: str = "superlu",
                 price: int = PRICE, tol: float = TOL):
        self.K, self.F, self.m = sp.csr_matrix(K), np.asarray(F, dtype=float), np.asarray(m, dtype=float)
        self.diagonal = self.K.diagonal()
        self.price, self.tol = int(price), float(tol)
        self._factors = CachedFactorization(lambda rho: (self.K + rho * sp.diags(self.m)).tocsc(), backend=backend)
        self._spent: dict[float, int] = {}           # CG iterations per rho so far
        self.begin_run()

    def begin_run(self) -> None:
        """Start counting a run's work."""
        self.solves = self.cg_iterations = 0
        self._rhos: set[float] = set()
        self._at_start = self._factors.factorizations

    def __call__(self, z: np.ndarray, lam: np.ndarray, rho: float, x: np.ndarray) -> np.ndarray:
        """The x-step from the previous x-iterate x, solved for its correction d = x - z:
        (K + rho M) d = F - K z - M lam.

        The right-hand side is z's own residual, so CG's relative tolerance measures the correction.  Written
        for x itself, the right-hand side F + M (rho z - lam) grows with rho, and at large rho the tolerance
        came above the correction: CG left x where it was, and the summable rule, which reads x's change,
        raised rho 3x an iteration until it left admmkit's range (docs/obstacle.md, the pyramid scene).
        """
        return z + self.solve(rho, self.F - self.K @ z - self.m * lam, x - z)

    def update_rho(self, rho: float) -> None:
        """A change of rho: nothing to redo here (rent or buy is decided at each solve, from the CG
        iterations spent at that rho)."""

    def solve(self, rho: float, b: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """The solution of (K + rho M) u = b, from x0."""
        rho = float(rho)
        self.solves += 1
        if self._spent.get(rho, 0) >= self.price:
            self._rhos.add(rho)
            return self._factors.solve(rho, b)
        u, its = self._cg(rho, b, x0)
        self._spent[rho] = self._spent.get(rho, 0) + its
        self.cg_iterations += its
        return u

    def _cg(self, rho: float, b: np.ndarray, x0: np.ndarray) -> tuple[np.ndarray, int]:
        """CG with the inverse diagonal of K + rho M as preconditioner, to ||r|| <= tol ||b||; at most the price."""
        inverse = 1.0 / (self.diagonal + rho * self.m)
        x = np.array(x0, dtype=float)
        r = b - (self.K @ x + rho * self.m * x)
        z = inverse * r
        p, rz = z.copy(), float(r @ z)
        goal = self.tol * float(np.linalg.norm(b))
        its = 0
        while float(np.linalg.norm(r)) > goal:
            if its >= self.price - self._spent.get(rho, 0):        # the rent is paid: factorise and finish
                self._spent[rho] = self.price
                self._rhos.add(rho)
                return self._factors.solve(rho, b), its
            Ap = self.K @ p + rho * self.m * p
            alpha = rz / float(p @ Ap)
            x += alpha * p
            r -= alpha * Ap
            z = inverse * r
            rz, rz_old = float(r @ z), rz
            p = z + (rz / rz_old) * p
            its += 1
        return x, its

    def counters(self) -> dict[str, int]:
        """Solves, CG iterations and factorisations (used, computed) of this run."""
        return {"solves": self.solves, "cg_iterations": self.cg_iterations, "factorizations": len(self._rhos),
                "factorizations_computed": self._factors.factorizations - self._at_start}
