"""The LASSO as an admmkit plug-in: the model to copy for a new problem.

The LASSO fits a sparse linear model,

    minimise  1/2 ||A x - b||^2 + lam ||x||_1 .

Split as x - z = 0 (the constraint map of the loop is the identity, c = 0;
docs/framework.md writes it A x - z = c) with

    f(x) = 1/2 x'(A'A)x - (A'b)'x     (1/2 ||A x - b||^2 up to the constant 1/2 ||b||^2)
    g(z) = lam ||z||_1 .

With the multiplier written y (the loop calls it ``lam``; here lam is the
LASSO's weight), order "zx" of :func:`admmkit.solve` is the paper's
Algorithm 1 (order "xz" the same three steps with x first):

    z^{k+1} = soft(x^k + y^k / rho_k,  lam / rho_k)                 (11)/(14)
    (A'A + rho_k I) x^{k+1} = A'b + rho_k z^{k+1} - y^k             (12)/(15)
    y^{k+1} = y^k + rho_k (x^{k+1} - z^{k+1})                       (13)/(16)

and the penalty rule gives rho_{k+1} (17).  soft(v, t) = sign(v) max(|v| - t, 0)
is the proximal operator of t ||.||_1.  The building blocks do the work:
:class:`admmkit.QuadraticXStep` is the x-step (one factorisation of
A'A + rho I per value of rho, cached), :class:`admmkit.blocks.prox.L1` the z-step, and
:class:`admmkit.SplitProblem` derives the rest (the adjoint norm for Boyd's
dual residual, the counters, the compiled segments).  This class adds the
input checks, the LASSO's own objective and its optimality measure.

Optimality: x is a solution iff 0 in A'(A x - b) + lam d||x||_1, i.e. for each i
g_i + lam sign(x_i) = 0 where x_i != 0 and |g_i| <= lam where x_i = 0
(g = A'(A x - b)).  Above ``lam_max(A, b) = ||A'b||_inf`` the solution is x = 0.
:meth:`Lasso.kkt_relative` measures this condition at the iterate; it is what
the result's ``converged`` is checked against (``converged_inaccurate`` when it
is more than 10 x the stop's tolerance).  Where A has full column rank it
stays within a factor 2 of the relative error of x (tests/problems/test_lasso.py).
"""
from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp

import admmkit


def lam_max(A, b) -> float:
    """||A'b||_inf: the smallest lam whose LASSO solution is x = 0 (0 in -A'b + lam d||0||_1)."""
    A, b = _data(A, b)
    return float(np.abs(A.T @ b).max())


class Lasso(admmkit.SplitProblem):
    """min 1/2 ||A x - b||^2 + lam ||x||_1: ``admmkit.solve(Lasso(A, b, lam))``.

    ``A`` is an m x n array or scipy sparse matrix, ``b`` a vector of m
    entries and ``lam`` >= 0 the weight of the l1 term.  ``result.z`` is the
    soft-thresholded copy of ``result.x``: the same point at convergence, with
    exact zeros.
    """

    def __init__(self, A, b, lam: float):
        self.A, self.b, self.lam = _checked(A, b, lam)
        x_step = admmkit.QuadraticXStep(self.A.T @ self.A, -(self.A.T @ self.b))   # eq. (12): (A'A + rho I) x = ...
        super().__init__(x_step, admmkit.blocks.prox.L1(self.lam))                         # eq. (11): soft-thresholding

    def objective(self, x, z=None):
        """1/2 ||A x - b||^2 + lam ||x||_1 at x (the LASSO's objective; z is not used)."""
        return 0.5 * float(np.sum((self.A @ x - self.b) ** 2)) + self.lam * float(np.abs(x).sum())

    def subgradient_residual(self, x) -> np.ndarray:
        """The distance of 0 to A'(A x - b) + lam d||x||_1, entry by entry."""
        g = self.A.T @ (self.A @ x - self.b)
        return np.where(x != 0, g + self.lam * np.sign(x), np.maximum(np.abs(g) - self.lam, 0.0))

    def kkt_relative(self, x, z, lam) -> dict[str, float]:
        """The LASSO's optimality at the ADMM iterate, relative (what ``converged`` is checked against).

        primal:      ||A'A (x - z)|| / scale: x and its sparse copy z agree, in the units of the gradient
                     (||x - z|| / ||x|| would be 1 wherever the solution is x = 0, as above lam_max);
        subgradient: ||subgradient_residual(z)|| / scale, at z, whose zeros are exact (x has entries of the
                     size of the tolerance where the solution is 0);
        scale = max(||A'A x||, ||A'A z||, ||A'b||), 0/0 counted as 0.  Their sum bounds the distance of 0 to
        A'(A x - b) + lam d||z||_1: x solves the LASSO with the signs of z.
        """
        AtAx, AtAz = self.A.T @ (self.A @ x), self.A.T @ (self.A @ z)
        scale = max(np.linalg.norm(AtAx), np.linalg.norm(AtAz), np.linalg.norm(self.A.T @ self.b))
        return {"primal": _ratio(np.linalg.norm(AtAx - AtAz), scale),
                "subgradient": _ratio(np.linalg.norm(self.subgradient_residual(z)), scale)}

    def kkt(self, x, z, lam) -> dict[str, float]:
        """The relative optimality measures (:meth:`kkt_relative`)."""
        return self.kkt_relative(x, z, lam)

    def __repr__(self) -> str:
        return f"Lasso(A: {self.A.shape[0]} x {self.A.shape[1]}, lam={self.lam:g})"


def solve_with_cvxpy(A, b, lam: float, **options) -> np.ndarray:
    """The reference solution by cvxpy (Clarabel to 1e-12 unless ``options`` say otherwise)."""
    import cvxpy as cp
    A, b, lam = _checked(A, b, lam)
    x = cp.Variable(A.shape[1])
    problem = cp.Problem(cp.Minimize(0.5 * cp.sum_squares(A @ x - b) + lam * cp.norm1(x)))
    settings = dict(solver=cp.CLARABEL, tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12) | options
    problem.solve(**settings)
    if problem.status != cp.OPTIMAL:
        raise RuntimeError(f"cvxpy did not solve the LASSO: status {problem.status}")
    return np.asarray(x.value, dtype=float)


def _checked(A, b, lam):
    """(A, b, lam) as float arrays and a float, or a ValueError naming the parameter."""
    A, b = _data(A, b)
    if isinstance(lam, bool) or not isinstance(lam, (int, float, np.integer, np.floating)) or not 0 <= lam < math.inf:
        raise ValueError(f"lam must be a finite number >= 0, got {lam!r}")
    return A, b, float(lam)


def _data(A, b):
    """(A, b) as a float matrix (dense or CSR) and a float vector, or a ValueError naming the parameter."""
    A = sp.csr_matrix(A, dtype=float) if sp.issparse(A) else np.asarray(A, dtype=float)
    if A.ndim != 2 or min(A.shape) == 0:
        raise ValueError(f"A must be a 2-D array with at least one row and column, got shape {A.shape}")
    if not np.all(np.isfinite(A.data if sp.issparse(A) else A)):
        raise ValueError("A must have finite entries")
    b = np.asarray(b, dtype=float)
    if b.shape != (A.shape[0],):
        raise ValueError(f"b must be a vector of {A.shape[0]} entries (one per row of A), got shape {b.shape}")
    if not np.all(np.isfinite(b)):
        raise ValueError("b must have finite entries")
    return A, b


def _ratio(value: float, scale: float) -> float:
    """value / scale, with 0/0 = 0 and value/0 = inf."""
    if scale > 1e-30:
        return float(value) / scale
    return 0.0 if value == 0 else math.inf
