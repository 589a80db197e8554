"""A damped 3 x 3 block-Jacobi smoother for the finest V-cycle level of 3-D elasticity (an option, not the default).

The finest level of :mod:`admmkit.linalg.vcycle_blocks3d` is smoothed by one
forward Gauss-Seidel sweep before and one backward sweep after the
coarse-grid correction.  Each sweep is a chain of dependent block rows.
Here both smoothers are instead one step of damped block Jacobi,

    x <- x + omega D^-1 (b - A x),     D = the 3 x 3 diagonal node blocks of A,

which has no chain of rows:

- the descent from x = 0 is x = omega D^-1 b and then coarse_b = P'(b - A x),
  one product fused with the restriction;
- the ascent is y = x + P x_c (computed a bandwidth ahead), then
  x = y + omega D^-1 (b - A y), one product fused with the correction.

The same smoother before and after the correction, with a symmetric
M = D / omega, keeps the V-cycle symmetric.  It is positive definite
(what CG needs) when omega < 2 / lambda_max(D^-1 A).  omega is
:data:`OMEGA_LAMBDA` / lambda, where lambda is the largest Ritz value of
:data:`LANCZOS_STEPS` Lanczos steps on D^-1 A (self-adjoint in the D inner
product), estimated once per hierarchy and kept through refreshes for a new
rho, so that a refresh and an in-place update give the same values.

docs/scale.md (the 3-D section) holds what this smoother measured against
Gauss-Seidel.
"""
from __future__ import annotations

import numpy as np

from ..kernels import _u, njit
from .vcycle_blocks3d import FinestLevel3D

#: omega lambda_max(D^-1 A): below 2 keeps the V-cycle positive definite
OMEGA_LAMBDA = 1.5
#: Lanczos steps for lambda_max(D^-1 A) (from a fixed random start)
LANCZOS_STEPS = 20


# ---------------------------------------------------------------- kernels
@njit(cache=True, inline="always")
def _block_product_row(indptr, indices, data, x, I):
    """(A x) on block row I: the three sums over the row's blocks in stored order."""
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    for k in range(indptr[_u(I)], indptr[_u(I + 1)]):
        j = 3 * indices[_u(k)]
        x0, x1, x2 = x[_u(j)], x[_u(j + 1)], x[_u(j + 2)]
        a = 9 * k
        s0 += data[_u(a)] * x0 + data[_u(a + 1)] * x1 + data[_u(a + 2)] * x2
        s1 += data[_u(a + 3)] * x0 + data[_u(a + 4)] * x1 + data[_u(a + 5)] * x2
        s2 += data[_u(a + 6)] * x0 + data[_u(a + 7)] * x1 + data[_u(a + 8)] * x2
    return s0, s1, s2


@njit(cache=True, inline="always")
def block_times(blocks, I, r0, r1, r2):
    """The 3 x 3 block I of ``blocks`` (9 values a block, row by row) times (r0, r1, r2): here omega D_I^-1 r_I,
    in :mod:`admmkit.linalg.vcycle_blockgs3d` D_I^-1 r_I."""
    q = 9 * I
    return (blocks[_u(q)] * r0 + blocks[_u(q + 1)] * r1 + blocks[_u(q + 2)] * r2,
            blocks[_u(q + 3)] * r0 + blocks[_u(q + 4)] * r1 + blocks[_u(q + 5)] * r2,
            blocks[_u(q + 6)] * r0 + blocks[_u(q + 7)] * r1 + blocks[_u(q + 8)] * r2)


@njit(cache=True)
def jacobi_restrict(indptr, indices, data, scaled_inverse, b, x, P_indptr, P_indices, P_data, coarse_b, lag):
    """The descent: x = omega D^-1 b (block rows ``lag`` ahead), and coarse_b = P'(b - A x), row M's residual
    scattered through P's 3 x 6 blocks as soon as it is formed."""
    nb = indptr.shape[0] - 1
    coarse_b[:] = 0.0
    lag = min(lag, nb)
    for step in range(nb + lag):
        I = step
        if I < nb:
            i = 3 * I
            x[_u(i)], x[_u(i + 1)], x[_u(i + 2)] = block_times(scaled_inverse, I, b[_u(i)], b[_u(i + 1)],
                                                                 b[_u(i + 2)])
        M = step - lag
        if M >= 0:
            s0, s1, s2 = _block_product_row(indptr, indices, data, x, M)
            m = 3 * M
            r0, r1, r2 = b[_u(m)] - s0, b[_u(m + 1)] - s1, b[_u(m + 2)] - s2
            for k in range(P_indptr[_u(M)], P_indptr[_u(M + 1)]):
                j = 6 * P_indices[_u(k)]
                at = 18 * k
                for c in range(6):
                    coarse_b[_u(j + c)] += (P_data[_u(at + c)] * r0 + P_data[_u(at + 6 + c)] * r1
                                            + P_data[_u(at + 12 + c)] * r2)


@njit(cache=True)
def prolong_jacobi(indptr, indices, data, scaled_inverse, x, b, P_indptr, P_indices, P_data, coarse_x, y, lag):
    """The ascent: y = x + P coarse_x (block rows ``lag`` ahead), then x = y + omega D^-1 (b - A y)."""
    nb = indptr.shape[0] - 1
    lag = min(lag, nb)
    for step in range(nb + lag):
        I = step
        if I < nb:
            t0, t1, t2 = 0.0, 0.0, 0.0
            for k in range(P_indptr[_u(I)], P_indptr[_u(I + 1)]):
                j = 6 * P_indices[_u(k)]
                at = 18 * k
                for c in range(6):
                    xc = coarse_x[_u(j + c)]
                    t0 += P_data[_u(at + c)] * xc
                    t1 += P_data[_u(at + 6 + c)] * xc
                    t2 += P_data[_u(at + 12 + c)] * xc
            i = 3 * I
            y[_u(i)], y[_u(i + 1)], y[_u(i + 2)] = x[_u(i)] + t0, x[_u(i + 1)] + t1, x[_u(i + 2)] + t2
        M = step - lag
        if M >= 0:
            s0, s1, s2 = _block_product_row(indptr, indices, data, y, M)
            m = 3 * M
            d0, d1, d2 = block_times(scaled_inverse, M, b[_u(m)] - s0, b[_u(m + 1)] - s1, b[_u(m + 2)] - s2)
            x[_u(m)], x[_u(m + 1)], x[_u(m + 2)] = y[_u(m)] + d0, y[_u(m + 1)] + d1, y[_u(m + 2)] + d2


@njit(cache=True)
def block_product(indptr, indices, data, x, out):
    """out = A x for A in 3 x 3 blocks."""
    for I in range(indptr.shape[0] - 1):
        out[_u(3 * I)], out[_u(3 * I + 1)], out[_u(3 * I + 2)] = _block_product_row(indptr, indices, data, x, I)


# ---------------------------------------------------------------- set-up
def diagonal_block_inverses(data: np.ndarray, block_diagonal: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
    """The inverses of the diagonal 3 x 3 blocks (of block rows ``rows``, or all), as (k, 3, 3) in double
    precision, from the level's stored (possibly single-precision) values."""
    at = block_diagonal if rows is None else block_diagonal[rows]
    return np.linalg.inv(data.reshape(-1, 3, 3)[at].astype(np.float64))


def largest_eigenvalue(indptr, indices, data, inverses: np.ndarray, steps: int = LANCZOS_STEPS) -> float:
    """lambda_max(D^-1 A) estimated by ``steps`` Lanczos steps for A q = lambda D q (the largest Ritz value;
    a fixed random start, so the estimate repeats bit for bit).  D = the blocks whose ``inverses`` are given."""
    n = 3 * inverses.shape[0]
    blocks = np.linalg.inv(inverses)
    D_times = lambda v: np.einsum("irc,ic->ir", blocks, v.reshape(-1, 3)).ravel()          # noqa: E731
    D_solve = lambda v: np.einsum("irc,ic->ir", inverses, v.reshape(-1, 3)).ravel()        # noqa: E731
    q = np.random.default_rng(0).standard_normal(n)
    Dq = D_times(q)
    norm = np.sqrt(q @ Dq)
    q, Dq = q / norm, Dq / norm                          # q' D q = 1
    Dq_prev, beta = np.zeros(n), 0.0                    # D q_prev (q_prev itself is not needed)
    Aq = np.empty(n)
    alphas, betas = [], []
    for _ in range(min(steps, n)):
        block_product(indptr, indices, data, q, Aq)
        alpha = float(q @ Aq)
        alphas.append(alpha)
        Dw = Aq - alpha * Dq - beta * Dq_prev            # D w, w = D^-1 A q - alpha q - beta q_prev
        w = D_solve(Dw)
        beta = float(np.sqrt(max(w @ Dw, 0.0)))
        if beta <= 1e-12 * abs(alpha):
            break
        betas.append(beta)
        Dq_prev, q, Dq = Dq, w / beta, Dw / beta
    k = len(alphas)
    T = np.diag(alphas) + np.diag(betas[:k - 1], 1) + np.diag(betas[:k - 1], -1)
    return float(np.linalg.eigvalsh(T)[-1])


# ---------------------------------------------------------------- the level
class FinestLevel3DJacobi(FinestLevel3D):
    """:class:`admmkit.linalg.vcycle_blocks3d.FinestLevel3D` smoothed by damped 3 x 3 block Jacobi (see the module).

    ``omega`` is found at the first construction and kept by :meth:`refreshed`
    (a new rho changes only the contact rows' diagonal blocks).
    """

    def __init__(self, A, P, values, pattern: FinestLevel3DJacobi | None = None):
        super().__init__(A, P, values, pattern=pattern)
        inverses = diagonal_block_inverses(self.data, self.block_diagonal)
        if pattern is None:
            lam = largest_eigenvalue(self.indptr, self.indices, self.data, inverses)
            self.omega = OMEGA_LAMBDA / lam
            self._y = np.empty(self.shape[0])
        else:
            self.omega, self._y = pattern.omega, pattern._y
        self.scaled_inverse = (self.omega * inverses).ravel()

    def update_rows(self, rows: np.ndarray) -> None:
        """omega D_I^-1 again for the block rows ``rows`` after their values changed (in :attr:`data`)."""
        rows = np.unique(rows)
        if rows.size:
            self.scaled_inverse.reshape(-1, 3, 3)[rows] = self.omega * diagonal_block_inverses(
                self.data, self.block_diagonal, rows)

    def cycle(self, b: np.ndarray, inverse: np.ndarray, bandwidth: int, correction, x: np.ndarray | None = None,
              coarse_b: np.ndarray | None = None) -> np.ndarray:
        """The level's part of a V-cycle from zero: Jacobi and restriction, ``correction(coarse_b)``, prolongation
        and Jacobi (``inverse``, 1 / a_ii, is not used)."""
        lag = (bandwidth + self.R - 1) // self.R
        x = np.empty(self.shape[0]) if x is None else x
        coarse_b = np.empty(self.P_shape[1]) if coarse_b is None else coarse_b
        jacobi_restrict(self.indptr, self.indices, self.data, self.scaled_inverse, b, x,
                        self.P_indptr, self.P_indices, self.P_data, coarse_b, lag)
        coarse_x = correction(coarse_b)
        prolong_jacobi(self.indptr, self.indices, self.data, self.scaled_inverse, x, b,
                       self.P_indptr, self.P_indices, self.P_data, coarse_x, self._y, lag)
        return x


__all__ = ["FinestLevel3DJacobi", "jacobi_restrict", "prolong_jacobi", "largest_eigenvalue", "OMEGA_LAMBDA"]
