"""The quadratic x-step: f(x) = 1/2 x'Px + q'x, with a proximal term sigma/2 ||x - x^k||^2.

The x-step of ADMM minimises f(x) + (lam, Ax - z - c)_M + rho/2 ||Ax - z - c||_M^2
(+ sigma/2 ||x - x^k||^2, OSQP's regularisation), i.e. it solves

    (P + sigma I + rho A'MA) x = -q + sigma x^k + A'M (rho (z + c) - lam).     (12)

:class:`QuadraticXStep` does this for any rho, with the matrix handled once per rho:

- ``solver="direct"``: a sparse factorisation per rho value
  (:class:`admmkit.linalg.linsolve.CachedFactorization`, any of its backends);
- ``"diagonal"``: P and A'MA diagonal (A the identity or diagonal): a division;
- ``"amg"``: CG preconditioned by smoothed-aggregation AMG with projected warm
  starts and an inner tolerance tied to the outer iteration
  (:class:`admmkit.blocks.iterative.IterativeXSolver`; for large finite element
  problems);
- ``"cg"``: plain CG warm-started at x^k to a relative tolerance ``cg_tol``,
  for matrix-free P or A (scipy LinearOperators);
- ``"auto"``: diagonal if possible, else direct for matrices, cg for operators.

Counters (:meth:`counters`) count the work since :meth:`begin_run` (which
:func:`admmkit.solve` calls at the start of every run): ``factorizations`` is
the number of rho values whose factorisation the run used (computed now or
found in the cache: the work a cold run does, whatever an earlier run left),
``factorizations_computed`` the ones computed in this run.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..linalg.linsolve import CachedFactorization
from .operators import LinearMap

SOLVERS = ("auto", "direct", "diagonal", "amg", "cg")


class QuadraticXStep:
    """Solve (P + sigma I + rho A'MA) x = -q + sigma x^k + A'M (rho (z + c) - lam), cached per rho.

    ``P`` is the Hessian of f (a dense array, a sparse matrix, a scipy
    LinearOperator, or None for 0), symmetric positive semidefinite; ``q``
    the linear term (None: 0).  ``A`` is the constraint map: an
    :class:`admmkit.LinearMap`, or anything ``LinearMap`` accepts (None: the
    identity of size ``n``), with ``M`` the weights of its range.  ``sigma``
    >= 0 is the proximal weight (OSQP uses 1e-6; needed when P + rho A'MA is
    singular).  ``solver`` is one of ``"auto"``, ``"direct"``,
    ``"diagonal"``, ``"amg"`` or ``"cg"`` (see the module docstring);
    ``backend`` the factorisation backend of the direct solver; ``cg_tol`` and
    ``cg_maxiter`` the relative tolerance and cap of CG, ``cg_preconditioner``
    its preconditioner (None, a LinearOperator approximating the inverse, or a
    function rho -> such an operator, e.g. a Jacobi diagonal); ``near_null``
    the near-null space given to the AMG.
    """

    def __init__(self, P=None, q=None, A=None, *, M=None, n: int | None = None, sigma: float = 0.0,
                 solver: str = "auto", backend: str = "auto", cg_tol: float = 1e-12, cg_maxiter: int = 10_000,
                 cg_preconditioner=None, near_null=None):
        if solver not in SOLVERS:
            raise ValueError(f"solver must be one of {', '.join(SOLVERS)}, got {solver!r}")
        if A is None and n is None:
            n = P.shape[0] if P is not None else (np.size(q) if q is not None else None)
        self.A = LinearMap.of(A, M=M, n=n)
        self.n = self.A.n
        self.sigma = float(sigma)
        if not self.sigma >= 0:
            raise ValueError(f"sigma must be >= 0, got {sigma!r}")
        self.q = np.zeros(self.n) if q is None else np.asarray(q, dtype=float).ravel()
        if self.q.shape != (self.n,):
            raise ValueError(f"q must have shape ({self.n},), got {self.q.shape}")
        self.P = _matrix(P, self.n)
        self.cg_tol, self.cg_maxiter = float(cg_tol), int(cg_maxiter)
        self.cg_preconditioner = cg_preconditioner
        diag = self._diagonal() if solver in ("auto", "diagonal") else None
        if solver == "diagonal" and diag is None:
            raise ValueError("solver='diagonal' needs P and A'MA diagonal (A the identity or diagonal)")
        if solver == "auto":
            solver = "diagonal" if diag is not None else ("direct" if self._matrices() else "cg")
        if solver in ("direct", "amg") and not self._matrices():
            raise ValueError(f"solver={solver!r} needs P and A as matrices; use solver='cg' for LinearOperators")
        self.solver = solver
        self.solves = self.cg_iterations = 0
        self._run_rhos: set[float] = set()
        self._factorizations_at_start = 0
        if solver == "diagonal":
            self._P_diag, self._G_diag = diag
        elif solver == "direct":
            K, G = self._K(), self.A.gram()
            self._cache = CachedFactorization(lambda rho: (K + rho * G).tocsc(), backend=backend)
        elif solver == "amg":
            from .iterative import IterativeXSolver
            self._amg = IterativeXSolver(self._K(), self.A.gram(), near_null=near_null)

    # -- set-up helpers
    def _matrices(self) -> bool:
        return self.A.is_matrix() and not isinstance(self.P, spla.LinearOperator)

    def _K(self) -> sp.csr_matrix:
        """P + sigma I as a sparse matrix."""
        P = sp.csr_matrix((self.n, self.n)) if self.P is None else sp.csr_matrix(self.P)
        return P if self.sigma == 0 else sp.csr_matrix(P + self.sigma * sp.identity(self.n, format="csr"))

    def _diagonal(self):
        g = self.A.diagonal_gram()
        if g is None:
            return None
        if self.P is None:
            return np.zeros(self.n), g
        if isinstance(self.P, spla.LinearOperator):
            return None
        P = sp.csr_matrix(self.P)
        if P.nnz and not np.array_equal(*P.nonzero()):
            return None
        return P.diagonal().astype(float), g

    # -- the x-step
    def rhs(self, z: np.ndarray, lam: np.ndarray, rho: float, x: np.ndarray, c=0.0) -> np.ndarray:
        """-q + sigma x^k + A'M (rho (z + c) - lam)."""
        w = rho * (z if np.isscalar(c) and c == 0 else z + c) - lam
        b = self.A.adjoint_M(w) - self.q
        if self.sigma:
            b = b + self.sigma * x
        return b

    def __call__(self, z: np.ndarray, lam: np.ndarray, rho: float, x: np.ndarray, c=0.0) -> np.ndarray:
        """argmin_x f(x) + sigma/2||x - x^k||^2 + (lam, Ax - z - c)_M + rho/2 ||Ax - z - c||_M^2 (eq. (12))."""
        b = self.rhs(z, lam, rho, x, c)
        self.solves += 1
        if self.solver == "diagonal":
            self._run_rhos.add(float(rho))
            return b / (self._P_diag + self.sigma + rho * self._G_diag)
        if self.solver == "direct":
            self._run_rhos.add(float(rho))
            return self._cache.solve(rho, b)
        if self.solver == "amg":
            return self._amg.solve(rho, b, x)
        return self._cg(rho, b, x)

    def update_rho(self, rho: float) -> None:
        """The event of a change of rho: ``"direct"`` factorises K + rho A'MA now (held per rho, so a return to
        an earlier rho costs nothing), ``"amg"`` makes its set-up, Galerkin refresh or keep decision now
        (``admmkit.blocks.iterative.IterativeXSolver.update_rho``); ``"diagonal"`` and ``"cg"`` have nothing to redo."""
        if self.solver == "direct":
            self._cache.prepare(rho)
        elif self.solver == "amg":
            self._amg.update_rho(rho)

    def _cg(self, rho, b, x):
        n, P, sigma, A = self.n, self.P, self.sigma, self.A

        def matvec(v):
            v = np.ravel(v)
            out = rho * A.adjoint_M(A.apply(v))
            if P is not None:
                out = out + P @ v
            return out + sigma * v if sigma else out
        iterations = [0]

        def count(_):
            iterations[0] += 1
        op = spla.LinearOperator((n, n), matvec=matvec, dtype=float)
        pre = self.cg_preconditioner(rho) if callable(self.cg_preconditioner) else self.cg_preconditioner
        sol, info = spla.cg(op, b, x0=x, rtol=self.cg_tol, atol=0.0, maxiter=self.cg_maxiter, callback=count, M=pre)
        self.cg_iterations += iterations[0]
        if info > 0 and np.linalg.norm(matvec(sol) - b) > 1e3 * self.cg_tol * np.linalg.norm(b):
            raise np.linalg.LinAlgError(f"CG did not converge in {self.cg_maxiter} iterations")
        return sol

    # -- for a compiled segment (admmkit.blocks.split_segment)
    def kernel_form(self, rho: float):
        """What a compiled x-step needs at this rho: ("direct", qdldl's factors (Lp, Li, Lx, Dinv, perm)) or
        ("diagonal", the denominators P + sigma + rho A'MA); None for other solvers and backends."""
        if self.solver == "diagonal":
            return "diagonal", self._P_diag + self.sigma + rho * self._G_diag     # as __call__ divides by it
        if self.solver == "direct" and self._cache.backend == "qdldl":
            return "direct", self._cache.ldl(rho)
        return None

    def count_solves(self, rho: float, solves: int) -> None:
        """Count ``solves`` x-steps at ``rho`` done outside the call (by a compiled segment)."""
        if solves:
            self.solves += solves
            self._run_rhos.add(float(rho))
            if self.solver == "direct":
                self._cache.solves += solves

    # -- f and the counters
    def f(self, x: np.ndarray) -> float:
        """1/2 x'Px + q'x."""
        return float(0.5 * np.dot(x, self.P @ x) + np.dot(self.q, x)) if self.P is not None else float(np.dot(self.q, x))

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """P x + q."""
        return self.q.copy() if self.P is None else self.P @ x + self.q

    def begin_run(self) -> None:
        """Start counting the work of a new run."""
        self._run_rhos = set()
        self._factorizations_at_start = self._cache.factorizations if self.solver == "direct" else 0
        self.solves = self.cg_iterations = 0
        if self.solver == "amg":
            a = self._amg
            a.setups = a.refreshes = a.solves = a.cg_iterations = a.unconverged = 0

    def counters(self) -> dict[str, int]:
        """The work of this run (since :meth:`begin_run`)."""
        if self.solver == "amg":
            return self._amg.counters()
        out = {"solves": self.solves}
        if self.solver == "direct":
            out["factorizations"] = len(self._run_rhos)
            out["factorizations_computed"] = self._cache.factorizations - self._factorizations_at_start
        if self.solver == "cg":
            out["cg_iterations"] = self.cg_iterations
        return out

    def __repr__(self) -> str:
        return f"QuadraticXStep(n={self.n}, solver={self.solver!r}, sigma={self.sigma:g}, A={self.A!r})"


def _matrix(P, n: int):
    if P is None:
        return None
    if isinstance(P, spla.LinearOperator):
        if P.shape != (n, n):
            raise ValueError(f"P must be {n}x{n}, got {P.shape}")
        return P
    M = sp.csr_matrix(P, dtype=float) if sp.issparse(P) else np.asarray(P, dtype=float)
    if M.shape != (n, n):
        raise ValueError(f"P must be {n}x{n}, got {M.shape}")
    return M
