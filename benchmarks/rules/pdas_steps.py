"""The three Newton solves of the primal-dual active set method (bounds, Schur complement, KKT), one small object each."""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from admmkit.linalg.linsolve import factorize


# ---------------------------------------------------------------- the three Newton solves
class _BoundsStep:
    """B = D S (one nonzero b_i in column j_i per row): active rows fix u_{j_i} = g_i / b_i."""

    def __init__(self, K, f, B, g, selection, compliance, backend):
        self.K, self.f, self.B, self.g, self.backend = K.tocsc(), f, B, g, backend
        self.cols, self.coef = selection
        self.n = K.shape[0]

    def unconstrained(self):
        u = factorize(self.K, self.backend)(self.f)
        return u, self.B @ u

    def solve(self, active):
        u = np.zeros(self.n)
        fixed_cols = self.cols[active]
        u[fixed_cols] = self.g[active] / self.coef[active]
        free = np.ones(self.n, dtype=bool)
        free[fixed_cols] = False
        K = self.K
        Kff = K[free][:, free]
        rhs = self.f[free] - K[free][:, fixed_cols] @ u[fixed_cols]
        u[free] = factorize(Kff, self.backend)(rhs)
        mu = np.zeros(self.g.size)
        residual = self.f - K @ u                      # = B'mu, supported on the fixed columns
        mu[active] = residual[fixed_cols] / self.coef[active]
        return u, self.B @ u, mu

    def recover(self, u, mu):
        return u


class _SchurStep:
    """Dense steps on the constraint space: C_AA mu_A = (d0 - g)_A, B u = d0 - C mu."""

    def __init__(self, K, f, B, g, selection, compliance, backend):
        self.g = g
        if compliance is not None:
            C, d0, recover = compliance
            self.C, self.d0, self._recover = np.asarray(C, dtype=float), np.asarray(d0, dtype=float), recover
            if self.C.shape != (g.size, g.size) or self.d0.shape != g.shape:
                raise ValueError(f"compliance: C must be {g.size}x{g.size} and d0 of length {g.size}, "
                                 f"got {self.C.shape} and {self.d0.shape}")
        else:
            solve = factorize(K, backend)
            Bt = B.T.tocsc()
            cols = [solve(Bt[:, j].toarray().ravel()) for j in range(g.size)]
            KiBt = np.column_stack(cols) if cols else np.zeros((K.shape[0], 0))
            self.C = np.asarray(B @ KiBt)
            self.C = 0.5 * (self.C + self.C.T)
            u0 = solve(f)
            self.d0 = B @ u0
            self._recover = lambda mu: u0 - KiBt @ mu   # noqa: E731

    def unconstrained(self):
        return None, self.d0.copy()

    def solve(self, active):
        mu = np.zeros(self.g.size)
        idx = np.flatnonzero(active)
        if idx.size:
            Caa = self.C[np.ix_(idx, idx)]
            mu[idx] = sla.cho_solve(sla.cho_factor(Caa), self.d0[idx] - self.g[idx])
        return None, self.d0 - self.C @ mu, mu

    def recover(self, u, mu):
        return np.asarray(self._recover(mu), dtype=float)


class _KKTStep:
    """Sparse LU of the saddle-point matrix [[K, B_A'], [B_A, 0]] for each active set."""

    def __init__(self, K, f, B, g, selection, compliance, backend):
        self.K, self.f, self.B, self.g, self.backend = K.tocsr(), f, B.tocsr(), g, backend

    def unconstrained(self):
        u = factorize(self.K, self.backend)(self.f)
        return u, self.B @ u

    def solve(self, active):
        idx = np.flatnonzero(active)
        BA = self.B[idx]
        n = self.K.shape[0]
        kkt = sp.bmat([[self.K, BA.T], [BA, None]], format="csc")
        sol = spla.splu(kkt).solve(np.concatenate([self.f, self.g[idx]]))
        u = sol[:n]
        mu = np.zeros(self.g.size)
        mu[idx] = sol[n:]
        return u, self.B @ u, mu

    def recover(self, u, mu):
        return u
