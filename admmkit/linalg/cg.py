"""Preconditioned conjugate gradients and the space of earlier solutions that warm-starts them.

Used by :class:`admmkit.blocks.iterative.IterativeXSolver` (see its module for the
inexact tolerance and the projection of Fischer 1998).
"""
from __future__ import annotations

import math

import numpy as np

from ..kernels import hand_written, njit


@njit(cache=True)
def _step_kernel(x, r, p, Ap, alpha):
    for i in range(x.shape[0]):
        x[i] += alpha * p[i]
        r[i] -= alpha * Ap[i]


@njit(cache=True)
def _direction_kernel(p, z, beta):
    for i in range(p.shape[0]):
        p[i] = p[i] * beta + z[i]


def cg_step(x, r, p, Ap, alpha: float) -> None:
    """x += alpha p and r -= alpha Ap in one pass (numba; numpy's values, no temporaries)."""
    if hand_written():
        _step_kernel(x, r, p, Ap, alpha)
    else:
        x += alpha * p
        r -= alpha * Ap


def cg_direction(p, z, beta: float) -> None:
    """p = beta p + z in place, in one pass (numba; the value of ``p *= beta; p += z``)."""
    if hand_written():
        _direction_kernel(p, z, beta)
    else:
        p *= beta
        p += z


# ---------------------------------------------------------------- preconditioned CG
def pcg(matvec, b: np.ndarray, x0: np.ndarray, precond, *, tol: float, maxiter: int):
    """Preconditioned conjugate gradients from ``x0``.

    Stops when sqrt(r'Pr) <= tol * sqrt(|x'b|): with P a good preconditioner
    sqrt(r'Pr) is within mesh-independent constants of the energy norm of the
    error ||x - x*||_A, and x'b -> ||x*||_A^2, so the test is a relative energy
    error.  A ``matvec`` or ``precond`` with the attribute ``writes_into`` is
    called as ``f(v, out=buffer)`` and must fill the buffer (one per solve).  Returns (x, iterations, achieved ratio, starting ratio, r) where the
    ratios are sqrt(r'Pr)/sqrt(|x'b|) at the end and the start and r = b - A x
    is CG's (recursively updated) residual.
    """
    x = np.array(x0, dtype=float)
    r = b - matvec(x) if np.any(x) else np.array(b, dtype=float)
    # products and preconditioners that write into a given array (``writes_into``) get one buffer each for
    # the whole solve: a new 8 MB array per iteration cost page faults (1e6 unknowns, 3D block: 20 % of CG)
    into_A, into_P = getattr(matvec, "writes_into", False), getattr(precond, "writes_into", False)
    Ap = np.empty_like(r) if into_A else None
    z = precond(r, out=np.empty_like(r)) if into_P else precond(r)
    rz = float(r @ z)
    scale = lambda: math.sqrt(max(abs(float(x @ b)), 1e-300))  # noqa: E731
    start_ratio = math.sqrt(max(rz, 0.0)) / scale() if np.any(x) else 1.0
    ratio = start_ratio
    its = 0
    p = z.copy()
    while its < maxiter:
        ratio = math.sqrt(max(rz, 0.0)) / scale() if np.any(x) else math.inf
        if ratio <= tol or rz <= 0.0:
            break
        Ap = matvec(p, out=Ap) if into_A else matvec(p)
        pAp = float(p @ Ap)
        if not (pAp > 0.0):
            raise np.linalg.LinAlgError(f"CG broke down: p'Ap = {pAp} (matrix or preconditioner not SPD)")
        alpha = rz / pAp
        cg_step(x, r, p, Ap, alpha)
        z = precond(r, out=z) if into_P else precond(r)
        rz_new = float(r @ z)
        cg_direction(p, z, rz_new / rz)
        rz = rz_new
        its += 1
    else:
        ratio = math.sqrt(max(rz, 0.0)) / scale()
    return x, its, ratio, start_ratio, r


# ---------------------------------------------------------------- successive right-hand sides
class SolutionSpace:
    """Fischer's projection: an orthonormal basis Q of recent solutions with Q'KQ and Q'DQ.

    ``guess(rho, b)`` returns Q y with (Q'KQ + rho Q'DQ) y = Q'b, the best
    approximation of the solution of (K + rho D) x = b from span(Q) in the
    energy norm.  When ``size`` vectors are held the basis restarts from the
    newest solution (Fischer's restart).  The basis vectors are stored as rows
    (``Q[j]``, and K Q likewise), so every product with the basis streams
    contiguous memory and reads only the vectors held: at 1e6 unknowns the
    column layout took 63 ms per ``add`` (Example 1's SADMM: 2.3 s of 35).
    """

    def __init__(self, K, D, size: int):
        self.K, self.D, self.size = K, D, size
        n = K.shape[0]
        self.Q = np.empty((size, n))
        self.KQ = np.empty_like(self.Q)   # K Q, so that adding a solution whose K x is known needs no product
        self.m = 0
        self.GK = np.zeros((size, size))
        self.GD = np.zeros((size, size))

    def guess(self, rho: float, b: np.ndarray) -> np.ndarray | None:
        """The projected initial guess, or None if the space is empty."""
        if self.m == 0:
            return None
        Q = self.Q[:self.m]
        G = self.GK[:self.m, :self.m] + rho * self.GD[:self.m, :self.m]
        c = Q @ b
        w, V = np.linalg.eigh(G)
        keep = w > 1e-12 * w.max()
        y = V[:, keep] @ ((V[:, keep].T @ c) / w[keep])
        return y @ Q

    def add(self, x: np.ndarray, Kx: np.ndarray | None = None) -> None:
        """Add a solution (orthonormalised against the basis; restart when full).

        ``Kx`` = K x, if known, saves the product with K.  The new basis vector and its K q are
        formed in their rows of Q and K Q (no copies).
        """
        if self.size == 0:
            return
        if self.m == self.size:
            self.m = 0
        j = self.m
        q = self.Q[j]
        q[:] = x
        norm0 = np.linalg.norm(q)
        if norm0 == 0:
            return
        coef = np.zeros(j)
        norm = norm0
        if j:
            Q = self.Q[:j]
            for _ in range(2):  # classical Gram-Schmidt, a second time only if the first lost digits (DGKS:
                c = Q @ q       # the norm fell below 1/sqrt(2) of the vector's; "twice is enough")
                q -= c @ Q
                coef += c
                norm = np.linalg.norm(q)
                if norm >= 0.7071 * norm0:
                    break
        if norm <= 1e-10 * norm0:
            return
        q /= norm
        Kq = self.KQ[j]
        if Kx is None:
            Kq[:] = self.K @ q
        elif j:        # K q = (K x - K Q coef) / norm
            np.subtract(Kx, coef @ self.KQ[:j], out=Kq)
            Kq /= norm
        else:
            np.divide(Kx, norm, out=Kq)
        self.GK[j, :j + 1] = self.GK[:j + 1, j] = self.Q[:j + 1] @ Kq
        self.GD[j, :j + 1] = self.GD[:j + 1, j] = self.Q[:j + 1] @ (self.D @ q)
        self.m += 1
