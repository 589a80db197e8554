"""The QP plug-in: min 1/2 x'Px + q'x + r subject to l <= A x <= u (OSQP's form).

Splitting: f(x) = 1/2 x'Px + q'x, g(z) = indicator of the box [l, u],
constraint A x - z = 0 with the Euclidean inner product (M = I).

    x-step: (P + sigma I + rho A'A) x = sigma x^k - q + A'(rho z - lam)
    z-step: z = clip(A x + lam/rho, l, u)

The proximal term sigma/2 ||x - x^k||^2 (OSQP's sigma, default 1e-6) keeps the
x-step uniquely solvable when P + rho A'A is singular (an LP-like QP); with
sigma = 0 the iterates are those of plain ADMM.  The x-step matrix is
factorised once per rho value and cached.

Two forms of the same x-step (``xstep=``):

- ``"reduced"``: the SPD matrix P + sigma I + rho A'A above (Cholesky-able,
  n x n), the default while A'A stays sparse;
- ``"kkt"``: the quasi-definite system OSQP solves,

      [P + sigma I    A'    ] [x]   [sigma x^k - q ]
      [A           -I / rho ] [v] = [z - lam / rho ],

  whose second row gives v = rho (A x - z) + lam, so that its first row is
  the reduced equation.  It has nnz(P) + 2 nnz(A) + n + m entries however
  dense the rows of A are, and is factorised by an LDL' (qdldl) or an LU
  (SuperLU).  ``"auto"`` takes it when A'A could have more than
  REDUCED_MAX_NNZ entries (one dense row of A makes A'A dense).
"""
from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp

from admmkit import Problem
from admmkit.linsolve import CachedFactorization, available_backends

XSTEPS = ("auto", "reduced", "kkt")
#: "auto" uses the KKT form when A'A could have more entries than this (bound: nnz(P) + sum_i nnz(row_i of A)^2)
REDUCED_MAX_NNZ = 2e7
#: sparse solvers that factorise the indefinite KKT matrix (CHOLMOD's L L' and PARDISO's SPD mode cannot)
KKT_BACKENDS = ("qdldl", "superlu")


def reduced_nnz_bound(P: sp.spmatrix, A: sp.spmatrix) -> float:
    """An upper bound on the entries of P + rho A'A: nnz(P) + sum over rows of A of nnz(row)^2."""
    rows = np.diff(sp.csr_matrix(A).indptr).astype(float)
    return float(sp.csc_matrix(P).nnz + (rows ** 2).sum())


class QP(Problem):
    """A convex QP, validated on construction.

    Parameters: P (n x n, symmetric PSD), q (n,), A (m x n), l, u (m,) with
    l <= u (infinite bounds allowed, equal bounds are equality rows), r a
    constant, sigma >= 0 the proximal weight, backend the sparse solver,
    xstep the form of the x-step system ("auto", "reduced" or "kkt"; see the
    module docstring).
    """

    def __init__(self, P, q, A, l, u, r: float = 0.0, *, sigma: float = 1e-6, backend: str = "auto",
                 name: str = "qp", xstep: str = "auto"):
        self.P, self.q, self.A, self.l, self.u = _validate(P, q, A, l, u)
        self.r = float(r)
        if not (math.isfinite(sigma) and sigma >= 0):
            raise ValueError(f"sigma must be a finite number >= 0, got {sigma!r}")
        if xstep not in XSTEPS:
            raise ValueError(f"xstep must be one of {', '.join(XSTEPS)}, got {xstep!r}")
        self.sigma = float(sigma)
        self.name = name
        self.n = self.P.shape[0]
        self.m = self.A.shape[0]
        self.c = 0.0
        self.At = self.A.T.tocsr()      # A' once: scipy builds a new matrix on every A.T (~40 us)
        if xstep == "auto":
            xstep = "kkt" if reduced_nnz_bound(self.P, self.A) > REDUCED_MAX_NNZ else "reduced"
        self.xstep = xstep
        base = (self.P + self.sigma * sp.identity(self.n, format="csc")).tocsc()
        if xstep == "reduced":
            AtA = (self.At @ self.A).tocsc()
            self._solver = CachedFactorization(lambda rho: (base + rho * AtA).tocsc(), backend=backend)
        else:
            kkt_backend = _kkt_backend(backend)
            top = sp.bmat([[base, self.A.T], [self.A, None]], format="csc")
            minus_I = sp.diags(np.r_[np.zeros(self.n), -np.ones(self.m)], format="csc")
            self._solver = CachedFactorization(lambda rho: (top + minus_I / rho).tocsc(), backend=kkt_backend)

    # -- the splitting --------------------------------------------------------
    def x_step(self, z, lam, rho, x):
        """Solve (P + sigma I + rho A'A) x = sigma x^k - q + A'(rho z - lam), in either form."""
        if self.xstep == "kkt":
            rhs = np.concatenate([self.sigma * x - self.q, z - lam / rho])
            return self._solver.solve(rho, rhs)[:self.n]
        rhs = self.sigma * x - self.q + self.At @ (rho * z - lam)
        return self._solver.solve(rho, rhs)

    def z_step(self, Ax, lam, rho, z):
        """Project A x + lam/rho onto the box [l, u]."""
        return np.clip(Ax + lam / rho, self.l, self.u)

    def apply_A(self, x):
        """A x."""
        return self.A @ x

    def adjoint_norm(self, y):
        """||A' y||_2 (Boyd's dual residual for order xz)."""
        return float(np.linalg.norm(self.At @ y))

    # -- diagnostics ----------------------------------------------------------
    def objective(self, x, z):
        """1/2 x'Px + q'x + r."""
        return float(0.5 * x @ (self.P @ x) + self.q @ x + self.r)

    def kkt(self, x, z, lam):
        """KKT residuals (inf-norms) of the QP at (x, lam), OSQP's definitions and more.

        primal: ||A x - z||_inf (OSQP), infeasibility: distance of A x to the box,
        dual: ||P x + q + A' lam||_inf, complementarity: max of lam_i times the
        slack of the bound it pushes against, sign: max ``|lam_i|`` pushing against
        an infinite bound.
        """
        Ax = self.A @ x
        lam_pos, lam_neg = np.maximum(lam, 0.0), np.maximum(-lam, 0.0)
        fin_u, fin_l = np.isfinite(self.u), np.isfinite(self.l)
        comp_u = lam_pos[fin_u] * np.abs(self.u[fin_u] - Ax[fin_u])
        comp_l = lam_neg[fin_l] * np.abs(Ax[fin_l] - self.l[fin_l])
        return {
            "primal": _inf(Ax - z),
            "infeasibility": _inf(Ax - np.clip(Ax, self.l, self.u)),
            "dual": _inf(self.P @ x + self.q + self.At @ lam),
            "complementarity": max(_inf(comp_u), _inf(comp_l)),
            "sign": max(_inf(lam_pos[~fin_u]), _inf(lam_neg[~fin_l])),
        }

    def counters(self):
        """Factorisations and solves of the x-step matrix so far."""
        return {"factorizations": self._solver.factorizations, "solves": self._solver.solves}


def _kkt_backend(backend: str) -> str:
    """The solver for the KKT form: qdldl if installed, else SuperLU, unless one of them is asked for."""
    if backend == "auto":
        return next(b for b in KKT_BACKENDS if b in available_backends())
    if backend not in KKT_BACKENDS:
        raise ValueError(f"backend for xstep 'kkt' must be 'auto' or one of {', '.join(KKT_BACKENDS)} "
                         f"(the KKT matrix is indefinite), got {backend!r}")
    return backend


def _inf(v) -> float:
    return float(np.max(np.abs(v), initial=0.0))


def _validate(P, q, A, l, u):
    """Check shapes, symmetry, finiteness and l <= u; return (P, q, A, l, u) as csc/arrays."""
    if not sp.issparse(P):
        P = np.asarray(P, dtype=float)
        if P.ndim != 2:
            raise ValueError(f"P must be a square matrix, got an array of shape {P.shape}")
    P = sp.csc_matrix(P, dtype=float)
    n = P.shape[0]
    if P.shape != (n, n):
        raise ValueError(f"P must be square (n x n), got shape {P.shape}")
    if not np.all(np.isfinite(P.data)):
        raise ValueError("P must have finite entries")
    asym = abs(P - P.T).max() if P.nnz else 0.0
    if asym > 1e-10 * max(1.0, abs(P).max()):
        raise ValueError(f"P must be symmetric; max |P - P'| = {asym:.3g}")
    q = np.asarray(q, dtype=float).ravel()
    if q.shape != (n,):
        raise ValueError(f"q must have length n = {n} (from P), got shape {q.shape}")
    if not np.all(np.isfinite(q)):
        raise ValueError("q must be finite")
    if not sp.issparse(A):
        A = np.atleast_2d(np.asarray(A, dtype=float))
    A = sp.csc_matrix(A, dtype=float)
    if A.shape[1] != n:
        raise ValueError(f"A must have n = {n} columns (from P), got shape {A.shape}")
    if not np.all(np.isfinite(A.data)):
        raise ValueError("A must have finite entries")
    m = A.shape[0]
    l = np.asarray(l, dtype=float).ravel()
    u = np.asarray(u, dtype=float).ravel()
    for name, v in (("l", l), ("u", u)):
        if v.shape != (m,):
            raise ValueError(f"{name} must have length m = {m} (rows of A), got shape {v.shape}")
        if np.any(np.isnan(v)):
            raise ValueError(f"{name} must not contain NaN")
    if np.any(l == np.inf) or np.any(u == -np.inf):
        raise ValueError("bounds must satisfy l < +inf and u > -inf")
    bad = np.flatnonzero(l > u)
    if bad.size:
        i = bad[0]
        raise ValueError(f"l must be <= u; row {i} has l = {l[i]:g} > u = {u[i]:g} ({bad.size} such rows)")
    return P, q, A, l, u
