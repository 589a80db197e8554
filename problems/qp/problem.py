"""The QP plug-in: min 1/2 x'Px + q'x + r subject to l <= A x <= u (OSQP's form).

Splitting: f(x) = 1/2 x'Px + q'x, g(z) = indicator of the box [l, u],
constraint A x - z = 0 with the inner product (a, b)_M = sum_i w_i a_i b_i
(M = diag(w); w = 1 by default, OSQP's per-row penalty with
``row_weights="osqp"``: w_i = RHO_EQ_OVER_RHO_INEQ = 1e3 on equality rows,
FREE_ROW_WEIGHT on rows with both bounds infinite, 1 otherwise, so that
rho w_i is OSQP's rho_vec).

    x-step: (P + sigma I + rho A'MA) x = sigma x^k - q + A'M(rho z - lam)   (Q1)
            (with row_weights "osqp", a free row enters with penalty 1e-6 instead of rho w_i (Q5))
    z-step: z = clip(A x + lam/rho, l, u)                                   (Q2)

lam is stored in M's inner product; the QP's multiplier is y = M lam (Q3)
(docs/qp.md derives it).  With ``scaling=k`` the loop iterates on the
Ruiz-equilibrated problem (:mod:`admmkit.problems.qp.scaling`) and ``finalize``,
``objective``, ``kkt`` and :meth:`QP.unscaled` give the user's numbers:
x = D xb, z = E^-1 zb, y = E M lam / c.

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

from .convexity import check_convex

XSTEPS = ("auto", "reduced", "kkt")
#: "auto" uses the KKT form when A'A could have more entries than this (bound: nnz(P) + sum_i nnz(row_i of A)^2)
REDUCED_MAX_NNZ = 2e7
#: sparse solvers that factorise the indefinite KKT matrix (CHOLMOD's L L' and PARDISO's SPD mode cannot)
KKT_BACKENDS = ("qdldl", "superlu")


def reduced_nnz_bound(P: sp.spmatrix, A: sp.spmatrix) -> float:
    """An upper bound on the entries of P + rho A'A: nnz(P) + sum over rows of A of nnz(row)^2."""
    rows = np.diff(sp.csr_matrix(A).indptr).astype(float)
    return float(sp.csc_matrix(P).nnz + (rows ** 2).sum())


#: OSQP_RHO_EQ_OVER_RHO_INEQ: weight of an equality row
EQ_ROW_WEIGHT = 1e3
#: weight in M of a row with both bounds infinite (its residual and lam are 0 after one iteration)
FREE_ROW_WEIGHT = 1e-5
#: OSQP_RHO_MIN: the x-step's penalty of a free row, whatever rho is (Q5)
FREE_ROW_PENALTY = 1e-6
#: OSQP_RHO_TOL: a row with u - l below this (in the scaled problem) is an equality row
EQ_TOL = 1e-4
ROW_WEIGHTS = ("uniform", "osqp")


def row_weights(l: np.ndarray, u: np.ndarray, kind: str = "osqp") -> np.ndarray | None:
    """The diagonal w of M: None for "uniform"; for "osqp" 1e3 on equality rows, FREE_ROW_WEIGHT on free rows, else 1."""
    if kind not in ROW_WEIGHTS:
        raise ValueError(f"row_weights must be one of {', '.join(ROW_WEIGHTS)}, got {kind!r}")
    if kind == "uniform":
        return None
    free = np.isinf(l) & np.isinf(u)
    with np.errstate(invalid="ignore"):
        eq = ~free & (u - l < EQ_TOL)
    w = np.ones(l.size)
    w[eq], w[free] = EQ_ROW_WEIGHT, FREE_ROW_WEIGHT
    return w


class QP(Problem):
    """A convex QP, validated on construction.

    Parameters: P (n x n, symmetric PSD), q (n,), A (m x n), l, u (m,) with
    l <= u (infinite bounds allowed, equal bounds are equality rows), r a
    constant, sigma >= 0 the proximal weight, backend the sparse solver,
    xstep the form of the x-step system ("auto", "reduced" or "kkt"; see the
    module docstring), scaling the number of Ruiz iterations (0: none;
    OSQP uses 10), row_weights "uniform" (M = I) or "osqp" (OSQP's penalty
    per row, see ``admmkit.problems.qp.problem.row_weights``).  ``P, q, A, l, u`` stay the user's
    data; the loop works on ``Ps, qs, As, ls, us`` (the same objects when
    scaling = 0).
    """

    def __init__(self, P, q, A, l, u, r: float = 0.0, *, sigma: float = 1e-6, backend: str = "auto",
                 name: str = "qp", xstep: str = "auto", scaling: int = 0, row_weights: str = "uniform",
                 x_relaxation: float = 1.0):
        from .scaling import ruiz
        self.P, self.q, self.A, self.l, self.u = _validate(P, q, A, l, u)
        self.r = _real("r", r)
        if self.r.shape not in ((), (1,)) or not math.isfinite(self.r.item()):
            raise ValueError(f"r (the constant of the objective) must be one finite number, got {r!r:.60}")
        self.r = float(self.r.item())
        if isinstance(sigma, (bool, str, bytes)) or not isinstance(sigma, (int, float, np.integer, np.floating)) \
                or not (math.isfinite(sigma) and sigma >= 0):
            raise ValueError(f"sigma must be a finite number >= 0, got {sigma!r}")
        if xstep not in XSTEPS:
            raise ValueError(f"xstep must be one of {', '.join(XSTEPS)}, got {xstep!r}")
        self.sigma = float(sigma)
        self.name = name
        self.n = self.P.shape[0]
        self.m = self.A.shape[0]
        self.c = 0.0
        if not (isinstance(x_relaxation, (int, float)) and 0 < x_relaxation < 2):
            raise ValueError(f"x_relaxation must be a number in (0, 2), got {x_relaxation!r}")
        self.x_relaxation = float(x_relaxation)
        self.options = dict(sigma=self.sigma, backend=backend, xstep=xstep, scaling=scaling, row_weights=row_weights,
                            x_relaxation=self.x_relaxation)
        self.scaling, Ps, qs, As = ruiz(self.P, self.q, self.A, scaling)                          # (S1)
        self.scaled = scaling > 0
        if self.scaled:
            self.Ps, self.qs, self.As = Ps, qs, As
            self.ls, self.us = self.scaling.E * self.l, self.scaling.E * self.u
        else:
            self.Ps, self.qs, self.As, self.ls, self.us = self.P, self.q, self.A, self.l, self.u
        self.w = globals()["row_weights"](self.ls, self.us, row_weights)
        self.At = self.A.T.tocsr()      # A' once: scipy builds a new matrix on every A.T (~40 us)
        self.Ats = self.As.T.tocsr() if self.scaled else self.At
        if xstep == "auto":
            xstep = "kkt" if reduced_nnz_bound(self.P, self.A) > REDUCED_MAX_NNZ else "reduced"
        self.xstep = xstep
        self.begin_run()
        base = (self.Ps + self.sigma * sp.identity(self.n, format="csc")).tocsc()
        w = np.ones(self.m) if self.w is None else self.w
        # free rows (both bounds infinite) under "osqp": the x-step's penalty is RHO_MIN whatever rho is, as OSQP's
        # rho_vec; their lam and residual are 0 from the first iteration on, so only the x-step sees it (Q5)
        self._free = np.flatnonzero(np.isinf(self.ls) & np.isinf(self.us)) if self.w is not None else np.empty(0, int)
        w_nf = w.copy()
        w_nf[self._free] = 0.0
        self._w_nf = w_nf
        self._w_free_over_penalty = w[self._free] / FREE_ROW_PENALTY
        if xstep == "reduced":
            G = (self.Ats @ sp.diags(w_nf) @ self.As).tocsc() if self.w is not None else (self.Ats @ self.As).tocsc()
            if self._free.size:
                Af = self.As[self._free]
                base = (base + FREE_ROW_PENALTY * (Af.T @ Af)).tocsc()
            self._solver = CachedFactorization(lambda rho: (base + rho * G).tocsc(), backend=backend)
        else:
            kkt_backend = _kkt_backend(backend)
            top = sp.bmat([[base, self.As.T], [self.As, None]], format="csc")
            # qdldl reads the upper triangle; given only that, its solves are several times faster (its ordering
            # then sees the symmetric pattern once): 51 us against 302 us on PRIMAL4's KKT matrix
            part = (lambda K: sp.triu(K, format="csc")) if kkt_backend == "qdldl" else (lambda K: K.tocsc())
            self._solver = CachedFactorization(
                lambda rho: part(top + sp.diags(np.r_[np.zeros(self.n), -1.0 / self.penalty(rho)], format="csc")),
                backend=kkt_backend)

    def setup(self, rho: float) -> int:
        """Factorise the x-step matrix for ``rho`` now (OSQP's setup), unless cached; return the factorisations made.

        The factorisation is not counted as a solve.
        """
        if float(rho) in self._solver:
            return 0
        size = self.n if self.xstep == "reduced" else self.n + self.m
        self._solver.solve(rho, np.zeros(size))
        self._solver.solves -= 1
        return 1

    def penalty(self, rho: float) -> np.ndarray:
        """OSQP's rho_vec: rho w_i, and RHO_MIN on free rows under row_weights "osqp" (Q5)."""
        R = rho * (np.ones(self.m) if self.w is None else self.w)
        R[self._free] = FREE_ROW_PENALTY
        return R

    def with_options(self, **options) -> "QP":
        """The same data with some constructor options changed (a new QP, its own factorisations)."""
        merged = {**self.options, **options}
        return QP(self.P, self.q, self.A, self.l, self.u, self.r, name=self.name, **merged)

    # -- the splitting --------------------------------------------------------
    def begin_run(self):
        """Forget the iterates of a previous run (called by :func:`admmkit.solve` at the start)."""
        self._x_in = self._x_last = self._x_rel = self._x_rel_prev = None

    def x_step(self, z, lam, rho, x):
        """Solve (Q1), in either form (KKT: [P + sigma I, A'; A, -R^-1] [x; v] = [sigma x^k - q; z - R^-1 M lam],
        R = :meth:`penalty` (rho), which is rho M but for the free rows (Q5)).

        With ``x_relaxation`` a != 1 (OSQP relaxes x too), x^k in the proximal
        term is OSQP's x^k = a xt^k + (1 - a) x^{k-1}, kept here (Q4); the loop's
        iterate stays xt (the x-step's solution).
        """
        self._x_in = x
        relax = self.x_relaxation != 1.0
        xp = self._x_rel if relax and self._x_rel is not None else x
        if self.xstep == "kkt":
            rhs = np.empty(self.n + self.m)
            np.subtract(self.sigma * xp, self.qs, out=rhs[:self.n])
            np.subtract(z, lam / rho, out=rhs[self.n:])
            if self._free.size:
                f = self._free
                rhs[self.n + f] = z[f] - self._w_free_over_penalty * lam[f]
            x_new = self._solver.solve(rho, rhs)[:self.n]
        else:
            v = rho * z - lam
            v = v if self.w is None else self.w * v
            if self._free.size:
                f = self._free
                v[f] = FREE_ROW_PENALTY * z[f] - self.w[f] * lam[f]
            x_new = self._solver.solve(rho, self.sigma * xp - self.qs + self.Ats @ v)
        if relax:
            a = self.x_relaxation
            self._x_rel_prev, self._x_rel, self._x_last = xp, a * x_new + (1.0 - a) * xp, x_new      # (Q4)
        return x_new

    def relaxed_x(self, x):
        """OSQP's x for the loop's iterate ``x`` (the relaxed one of (Q4) when ``x`` is the last x-step's, else x)."""
        if self._is_last(x):
            return self._x_rel
        return x

    def _is_last(self, x) -> bool:
        """``x`` is the last x-step's output (or a view of it, as a record's ``x``)."""
        last = self._x_last
        return last is not None and (x is last or (x.shape == last.shape and x.ctypes.data == last.ctypes.data))

    def delta_x(self, x):
        """x^{k+1} - x^k of the loop's last iterate ``x`` (OSQP's relaxed x under (Q4)), or None if unknown."""
        if self._is_last(x):
            return self._x_rel - self._x_rel_prev
        return None if self._x_in is None else x - self._x_in

    def z_step(self, Ax, lam, rho, z):
        """Project A x + lam/rho onto the box [l, u] (Q2; M is diagonal, so it does not enter)."""
        v = Ax + lam / rho
        np.maximum(v, self.ls, out=v)
        return np.minimum(v, self.us, out=v)

    def apply_A(self, x):
        """A x (the scaled A when scaling)."""
        return self.As @ x

    def inner(self, a, b):
        """(a, b)_M = sum_i w_i a_i b_i."""
        return float(np.dot(a, b)) if self.w is None else float(np.dot(self.w * a, b))

    def norm(self, y):
        """||y||_M."""
        return math.sqrt(max(self.inner(y, y), 0.0))

    def adjoint_norm(self, y):
        """||A' M y||_2 (Boyd's dual residual for order xz)."""
        return float(np.linalg.norm(self.Ats @ (y if self.w is None else self.w * y)))

    def finalize(self, x):
        """The user's x = D xb (xb OSQP's relaxed x under (Q4))."""
        x = self.relaxed_x(x)
        return self.scaling.unscale_x(x) if self.scaled else x

    # -- between the loop's iterates and the user's numbers -------------------
    def multiplier(self, lam):
        """The QP's multiplier of the loop's lam in the user's problem: y = E M lam / c (Q3)."""
        yb = lam if self.w is None else self.w * lam
        return self.scaling.unscale_y(yb) if self.scaled else yb

    def unscaled(self, x, z, lam):
        """(x, z, y) of the user's problem from the loop's iterate (x, z, lam)."""
        x = self.relaxed_x(x)
        if not self.scaled:
            return x, z, self.multiplier(lam)
        return self.scaling.unscale_x(x), self.scaling.unscale_z(z), self.multiplier(lam)

    def iterate_from(self, x, y):
        """The loop's (x, z, lam) for a user's (x, y), as OSQP's warm start: xb = D^-1 x, z = A xb, lam = M^-1 c E^-1 y."""
        xb = self.scaling.scale_x(x) if self.scaled else np.asarray(x, dtype=float)
        yb = self.scaling.scale_y(y) if self.scaled else np.asarray(y, dtype=float)
        lam = yb if self.w is None else yb / self.w
        return xb, self.As @ xb, lam

    # -- diagnostics ----------------------------------------------------------
    def objective(self, x, z):
        """1/2 x'Px + q'x + r at the user's x."""
        return float(0.5 * x @ (self.P @ x) + self.q @ x + self.r)

    def kkt(self, x, z, lam):
        """KKT residuals (inf-norms) of the user's QP at the user's x and the loop's (z, lam), OSQP's definitions and more.

        primal: ||A x - z||_inf (OSQP), infeasibility: distance of A x to the box,
        dual: ||P x + q + A' y||_inf, complementarity: max of y_i times the
        slack of the bound it pushes against, sign: max ``|y_i|`` pushing against
        an infinite bound; y = E M lam / c and z = E^-1 zb are the user's.
        """
        if self.scaled:
            z = self.scaling.unscale_z(z)
        y = self.multiplier(lam)
        Ax = self.A @ x
        y_pos, y_neg = np.maximum(y, 0.0), np.maximum(-y, 0.0)
        fin_u, fin_l = np.isfinite(self.u), np.isfinite(self.l)
        comp_u = y_pos[fin_u] * np.abs(self.u[fin_u] - Ax[fin_u])
        comp_l = y_neg[fin_l] * np.abs(Ax[fin_l] - self.l[fin_l])
        return {
            "primal": _inf(Ax - z),
            "infeasibility": _inf(Ax - np.clip(Ax, self.l, self.u)),
            "dual": _inf(self.P @ x + self.q + self.At @ y),
            "complementarity": max(_inf(comp_u), _inf(comp_l)),
            "sign": max(_inf(y_pos[~fin_u]), _inf(y_neg[~fin_l])),
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


def _real(name: str, value, sparse_ok: bool = False):
    """``value`` as a real float array (or sparse matrix); ValueError naming ``name`` for text or complex values."""
    if sparse_ok and sp.issparse(value):
        if np.iscomplexobj(value.data):
            raise ValueError(f"{name} must be real, got complex entries")
        return value
    if np.iscomplexobj(value):
        raise ValueError(f"{name} must be real, got complex values")
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an array of numbers, got {value!r:.60}") from None


def _validate(P, q, A, l, u):
    """Check types, shapes, symmetry, convexity, finiteness and l <= u; return (P, q, A, l, u) as csc/arrays."""
    P = _real("P", P, sparse_ok=True)
    if not sp.issparse(P) and P.ndim != 2:
        raise ValueError(f"P must be a square matrix, got an array of shape {P.shape}")
    P = sp.csc_matrix(P, dtype=float)
    n = P.shape[0]
    if P.shape != (n, n):
        raise ValueError(f"P must be square (n x n), got shape {P.shape}")
    if n == 0:
        raise ValueError("the QP needs at least one variable: P, q and A must have n >= 1 columns, got n = 0")
    if not np.all(np.isfinite(P.data)):
        raise ValueError("P must have finite entries")
    asym = abs(P - P.T).max() if P.nnz else 0.0
    if asym > 1e-10 * max(1.0, abs(P).max()):
        raise ValueError(f"P must be symmetric; max |P - P'| = {asym:.3g}")
    check_convex(P)
    q = _real("q", q).ravel()
    if q.shape != (n,):
        raise ValueError(f"q must have length n = {n} (from P), got shape {q.shape}")
    if not np.all(np.isfinite(q)):
        raise ValueError("q must be finite")
    A = _real("A", A, sparse_ok=True)
    if not sp.issparse(A):
        A = np.atleast_2d(A)
    A = sp.csc_matrix(A, dtype=float)
    if A.shape[1] != n:
        raise ValueError(f"A must have n = {n} columns (from P), got shape {A.shape}")
    if not np.all(np.isfinite(A.data)):
        raise ValueError("A must have finite entries")
    m = A.shape[0]
    l = _real("l", l).ravel()
    u = _real("u", u).ravel()
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
