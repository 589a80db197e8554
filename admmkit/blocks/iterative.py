"""Iterative x-steps: CG preconditioned by smoothed-aggregation AMG (pyamg).

A finite element ADMM x-step solves

    (K + rho D) x = b,      K the stiffness, D = A'MA the penalty term,       (12)

with a right-hand side that changes every iteration and a rho that changes
now and then.  A sparse factorisation (:mod:`admmkit.linalg.linsolve`) costs
O(n^1.5) time and memory in 2D and more in 3D; this module solves the same
system iteratively in O(n) memory.  :class:`IterativeXSolver` combines

* **CG preconditioned by one V-cycle of smoothed-aggregation AMG** (Vanek,
  Mandel & Brezina 1996, as implemented by pyamg), with a near-null space
  given by the plug-in: the rigid body modes for elasticity
  (:func:`admmkit.problems.contact.solvers.iterative.rigid_body_modes`), the constants for a scalar problem;
* **warm starts**: the initial guess is the A(rho)-orthogonal projection of the
  solution onto the span of the last solutions (Fischer 1998, "Projection
  techniques for iterative solution of Ax = b with successive right-hand
  sides", Comput. Methods Appl. Mech. Engrg. 163:193-204).  Because
  V'(K + rho D)V = V'KV + rho V'DV, the projection survives a change of rho
  without a single extra product with the matrix;
* **an inexact inner tolerance tied to the outer iteration**: CG stops when
  the preconditioned residual sqrt(r'Pr), an estimate of the energy norm of
  the error, is below ``tol_k`` times the energy norm of the solution, with

      tol_k = max(tol_min, min(kappa * delta_k, tol0 / (k + 1)^1.1)),      (*)

  where delta_k = ||x^k - x^{k-1}|| / ||x^k|| is the outer relative change (the
  paper's stopping residual; rho times it bounds Boyd's dual residual) of the
  last two x-steps and k counts the solves.  Early ADMM iterations move x a
  lot and get a loose tolerance, late ones a tight one.  The cap
  tol0 (k+1)^-1.1 is summable, which is what the convergence theory of
  inexact ADMM asks for (Eckstein & Bertsekas 1992, Math. Program. 55:293-318,
  Theorem 8: ADMM converges if the errors of the subproblem solutions are
  summable);
* **reuse of the AMG hierarchy across rho** (``reuse``): when rho changes,
  ``"rebuild"`` sets the hierarchy up again, ``"galerkin"`` keeps the
  aggregates and prolongators and makes every coarse operator R A(rho) P --
  since A = K + rho D this is A_l + (rho - rho_0) D_l with D_l = R D P kept
  from the setup, one axpy per level -- ``"keep"`` keeps the preconditioner
  built for the old rho (still SPD, so CG still converges), and ``"auto"``
  keeps it until what it has cost (the extra CG iterations against the
  convergence factor of a fresh hierarchy) exceeds the price of a Galerkin
  refresh counted in CG iterations from nonzero counts -- the rent-or-buy
  rule, never more than twice the cost of the better choice made in
  hindsight; counted in work, not seconds, so the iterates never depend on
  the clock or the machine's load.

Generic: nothing here knows about contact or obstacles; a plug-in passes K,
D, the near-null space and (optionally) the dofs of each node.
"""
from __future__ import annotations

import math
import time

import numpy as np
import scipy.sparse as sp

from ..linalg.amg import AMGPreconditioner, PencilMatrix, node_blocks  # noqa: F401  (node_blocks: re-exported)
from ..linalg.cg import SolutionSpace, pcg  # noqa: F401  (re-exported)
from ..linalg.submatrix import principal_submatrix
from ..linalg.symmetric import pencil_products

#: the products R A P of a Galerkin refresh without the axpy form, in units of C nnz(A) (a smoothed
#: aggregation P has a few entries per row, so each product touches a few times the operator's entries)
GALERKIN_WORK = 4.0

REUSE = ("auto", "keep", "galerkin", "rebuild")


# ---------------------------------------------------------------- the x-step solver
class IterativeXSolver:
    """Solve (K + rho D) x = b for successive b and rho by AMG-preconditioned CG.

    Parameters
    ----------
    K, D : sparse symmetric matrices, K + rho D SPD for rho > 0.
    near_null : (n, m) near-null space of K (e.g. the rigid body modes of :mod:`admmkit.problems.contact.solvers.iterative`) or
        None (pyamg's default: the constant per block).
    blocks : (n_nodes, d) dof indices of each node (:func:`admmkit.linalg.amg.node_blocks`) or
        None.  With blocks the AMG aggregates nodes (BSR d x d blocks).
    reuse : "auto", "keep", "galerkin" or "rebuild" (module docstring).
    tol : the inner tolerance: "adaptive" for rule (*) of the module docstring
        or a fixed relative energy-norm tolerance in (0, 1).
    kappa, tol0, tol_min : the constants of rule (*).
    projection : number of recent solutions kept for the projected warm start
        (0: warm start from the last solution only).
    maxiter : CG iteration cap per solve.  Reaching it with the error estimate
        above 0.5 raises LinAlgError; below, the solve counts as ``cg_unconverged``.
    amg_options : keyword arguments of :class:`admmkit.linalg.amg.AMGPreconditioner` for speed
        (``spectral_steps``, ``cycle_values``); None keeps its defaults.

    Counters: ``setups`` (hierarchy builds), ``refreshes`` (Galerkin
    refreshes), ``solves``, ``cg_iterations``, ``unconverged``; times ``setup_time``,
    ``refresh_time``, ``solve_time``; ``last`` describes the last solve.
    """

    def __init__(self, K, D, *, near_null=None, blocks=None, reuse: str = "auto", tol="adaptive",
                 kappa: float = 0.1, tol0: float = 0.1, tol_min: float = 1e-10, projection: int = 8,
                 maxiter: int = 1000, max_coarse: int = 500, amg_options: dict | None = None):
        K, D = sp.csr_matrix(K, dtype=float), sp.csr_matrix(D, dtype=float)
        K.sum_duplicates()
        D.sum_duplicates()
        n = K.shape[0]
        if K.shape != (n, n) or D.shape != (n, n):
            raise ValueError(f"K and D must be square and of the same shape, got {K.shape} and {D.shape}")
        if reuse not in REUSE:
            raise ValueError(f"reuse must be one of {', '.join(REUSE)}, got {reuse!r}")
        if not (tol == "adaptive" or (isinstance(tol, (int, float)) and 0 < tol < 1)):
            raise ValueError(f"tol must be 'adaptive' or a number in (0, 1), got {tol!r}")
        for name, value in (("kappa", kappa), ("tol0", tol0), ("tol_min", tol_min)):
            if not (isinstance(value, (int, float)) and 0 < value < 1e3 and math.isfinite(value)):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
        if isinstance(projection, bool) or not isinstance(projection, int) or projection < 0:
            raise ValueError(f"projection must be an integer >= 0, got {projection!r}")
        if isinstance(maxiter, bool) or not isinstance(maxiter, int) or maxiter < 1:
            raise ValueError(f"maxiter must be an integer >= 1, got {maxiter!r}")
        self.n = n
        self.perm = None
        self.blocksize = 1
        if blocks is not None:
            blocks = np.asarray(blocks)
            if blocks.ndim != 2 or blocks.size != n or not np.array_equal(np.sort(blocks.ravel()), np.arange(n)):
                raise ValueError("blocks must be an (n_nodes, d) array holding every dof index once")
            self.perm, self.blocksize = blocks.ravel(), blocks.shape[1]
            self._inverse_perm = np.empty_like(self.perm)
            self._inverse_perm[self.perm] = np.arange(n)
            K, D = principal_submatrix(K, self.perm), principal_submatrix(D, self.perm)
            if near_null is not None:
                near_null = np.asarray(near_null)[self.perm]
        # CSR: its products were faster than BSR's here.  A permuted K is this solver's own copy: the pencil
        # takes it over, and K is then the pencil's pattern with K's values (one copy of K, not three)
        self.pencil = PencilMatrix(K, D, copy=self.perm is None)
        self._products = pencil_products(self.pencil, self.blocksize)
        K = self.K = self.pencil.K_matrix()
        self.D = D
        self._D_rows = np.flatnonzero(np.diff(D.indptr))
        self._D_block = D[self._D_rows]
        self.near_null = None if near_null is None else np.ascontiguousarray(near_null, dtype=float)
        self.reuse, self.tol = reuse, tol
        self.kappa, self.tol0, self.tol_min = float(kappa), float(tol0), float(tol_min)
        self.maxiter, self.max_coarse = maxiter, max_coarse
        self.amg_options = dict(amg_options or {})
        self.space = SolutionSpace(K, D, projection)
        self._rho_A = None        # rho of the current matrix A
        self._A = None
        self._amg = None
        self._rho_amg = None      # rho the preconditioner was built or refreshed for
        self._event_action = None  # what the last update_rho did, reported by the next solve
        self._fresh_factor = None  # CG convergence factor with a fresh hierarchy
        self._stale_loss = 0.0    # seconds lost to a stale hierarchy since the last refresh
        self._x_prev = None
        self._x_prev2 = None
        self._Kx: list[tuple[np.ndarray, np.ndarray]] = []
        self.setups = self.refreshes = self.solves = self.cg_iterations = self.unconverged = 0
        self.setup_time = self.refresh_time = self.solve_time = 0.0
        self.last: dict = {}

    # -- matrices and hierarchy
    def matrix(self, rho: float) -> sp.spmatrix:
        """K + rho D in the solver's (block) ordering and format."""
        return self.pencil.at(rho)

    def _prepare(self, rho: float) -> str:
        """Make A = A(rho) and a preconditioner for it; return what was done."""
        action = "none"
        if self._amg is None:
            action = "setup"
        elif self._rho_amg != rho:
            if self.reuse == "rebuild":
                action = "setup"
            elif self.reuse == "galerkin":
                action = "refresh"
            elif self.reuse == "keep":
                action = "keep"
            else:  # auto: rent (keep) until the loss reaches the price of a refresh, both in CG iterations
                action = "refresh" if self._stale_loss >= self._refresh_price() else "keep"
        if self._rho_A != rho:
            self._new_matrix(rho, in_place=action == "refresh")
        if action == "setup":
            start = time.perf_counter()
            self._amg = AMGPreconditioner(self._A, self.near_null, blocksize=self.blocksize,
                                          max_coarse=self.max_coarse, D=self.D, rho=rho, **self.amg_options)
            self.setup_time += time.perf_counter() - start
            self.setups += 1
        elif action == "refresh":
            start = time.perf_counter()
            self._amg.refresh(self._A, rho)
            self.refresh_time += time.perf_counter() - start
            self.refreshes += 1
        if action in ("setup", "refresh"):
            self._rho_amg, self._fresh_factor, self._stale_loss = rho, None, 0.0
        return action

    def _new_matrix(self, rho: float, in_place: bool) -> None:
        """A = K + rho D and CG's product with it.  With the compiled kernels and ``in_place`` (the
        preconditioner is refreshed next, so nothing else holds the old A) only D's entries of the last A and
        product are rewritten (:meth:`admmkit.linalg.amg.PencilMatrix.update`, the same values); otherwise, and
        under :func:`admmkit.kernels.library_kernels`, both are made anew (copies of all values: 0.3 s and more
        at 1e6 unknowns)."""
        from ..kernels import hand_written
        in_place = in_place and self._A is not None and hand_written()
        if in_place and self.pencil.changed_entries() is not None and sp.isspmatrix_csr(self._A):
            self.pencil.update(self._A, rho)
        else:
            self._A = self.matrix(rho)
        if in_place and getattr(self._products, "updates_in_place", False):
            self._product = self._products(rho, into=self._product)
        else:
            self._product = self._products(rho)
        self._rho_A = rho

    def update_rho(self, rho: float) -> None:
        """The event of a change of rho: A = K + rho D and the preconditioner's set-up, Galerkin refresh or keep
        (:meth:`_prepare`), made now rather than at the next solve; that solve reports the action."""
        self._event_action = self._prepare(float(rho))

    def _refresh_price(self) -> float:
        """What a Galerkin refresh costs, in CG iterations, from nonzero counts (never from the clock, so that
        the iterates do not depend on the machine's load).

        The axpy form (one axpy per level) costs a fraction of one CG iteration and any stale hierarchy
        costs at least that: price 0, a refresh at every change of rho.  The products R A P touch about
        GALERKIN_WORK C nnz(A) entries and one CG iteration about (1 + 2 C) nnz(A) (a product with A and a
        V-cycle of one forward and one backward Gauss-Seidel sweep per level; C the operator complexity).
        """
        if self._amg._pencils is not None:
            return 0.0
        c = self._amg.operator_complexity()
        return GALERKIN_WORK * c / (1.0 + 2.0 * c)

    def inner_tolerance(self) -> float:
        """The tolerance of the next solve: rule (*) or the fixed ``tol``."""
        if self.tol != "adaptive":
            return float(self.tol)
        cap = self.tol0 / (self.solves + 1) ** 1.1
        if self._x_prev is None or self._x_prev2 is None:
            return max(self.tol_min, cap)
        delta = np.linalg.norm(self._x_prev - self._x_prev2) / max(np.linalg.norm(self._x_prev), 1e-300)
        return max(self.tol_min, min(self.kappa * delta, cap))

    # -- the solve
    def solve(self, rho: float, rhs: np.ndarray, x0: np.ndarray | None = None) -> np.ndarray:
        """Approximately solve (K + rho D) x = rhs (original dof order); ``x0`` is ignored
        when the projection space holds solutions (its guess is at least as good in the energy norm
        as any of them), else used as the warm start."""
        rho = float(rho)
        if not (math.isfinite(rho) and rho > 0):
            raise ValueError(f"rho must be a finite number > 0, got {rho!r}")
        b = np.asarray(rhs, dtype=float)
        if b.shape != (self.n,):
            raise ValueError(f"rhs must have shape ({self.n},), got {b.shape}")
        if not np.isfinite(b).all():
            raise ValueError("rhs must be finite (it contains nan or inf)")
        if self.perm is not None:
            b = np.take(b, self.perm)
        action = self._prepare(rho)
        if action == "none" and self._event_action is not None:    # done at the rho event (update_rho)
            action = self._event_action
        self._event_action = None
        tol = self.inner_tolerance()
        start = time.perf_counter()
        guess = self.space.guess(rho, b)
        if guess is None:
            guess = np.zeros(self.n) if x0 is None else np.asarray(x0, dtype=float)[self.perm if self.perm is not None else slice(None)]
        x, its, ratio, start_ratio, r = pcg(self._product, b, guess, self._amg, tol=tol, maxiter=self.maxiter)
        elapsed = time.perf_counter() - start
        if ratio > tol:
            if ratio > 0.5:
                raise np.linalg.LinAlgError(f"CG did not converge in {self.maxiter} iterations "
                                            f"(error ratio {ratio:.2e}, tolerance {tol:.2e})")
            self.unconverged += 1
        self._account(its, ratio, start_ratio)
        Kx = b - r                                   # K x = A x - rho D x with A x = b - r: no product with K;
        Kx[self._D_rows] -= rho * (self._D_block @ x)  # D x is zero off D's rows (the value of Kx - rho (D @ x))
        self.space.add(x, Kx)
        self.solves += 1
        self.cg_iterations += its
        self.solve_time += elapsed
        self.last = dict(rho=rho, action=action, tol=tol, iterations=its, error_ratio=ratio,
                         start_ratio=start_ratio, seconds=elapsed)
        if self.perm is not None:
            x, Kx = self._unpermute(x), self._unpermute(Kx)
        self._x_prev2, self._x_prev = self._x_prev, x
        self._Kx = [(x, Kx)] + self._Kx[:1]
        return x

    def _unpermute(self, v: np.ndarray) -> np.ndarray:
        """v (in the solver's node order) in the original dof order."""
        return np.take(v, self._inverse_perm)

    def known_Kx(self, x: np.ndarray) -> np.ndarray | None:
        """K x for one of the last two returned solutions (the very array objects), else None.

        Lets a plug-in measure the energy norm of an iterate without a product
        with K (CG's residual gives A x, and K x = A x - rho D x).  Accurate to
        the CG residual's round-off, not to the last bit.
        """
        for obj, Kx in self._Kx:
            if obj is x:
                return Kx
        return None

    def _account(self, its: int, ratio: float, start_ratio: float) -> None:
        """Track the convergence factor; with a stale hierarchy, add up the CG iterations it lost."""
        if its == 0 or not (ratio > 0 and start_ratio > ratio):
            return
        factor = (ratio / start_ratio) ** (1.0 / its)
        if self._rho_amg == self._rho_A:
            self._fresh_factor = factor if self._fresh_factor is None else min(self._fresh_factor, factor)
        elif self._fresh_factor is not None and self._fresh_factor < 1:
            needed = math.log(ratio / start_ratio) / math.log(self._fresh_factor)  # iterations a fresh one needs
            self._stale_loss += max(its - needed, 0.0)                              # extra CG iterations

    def counters(self) -> dict[str, int]:
        """AMG setups, Galerkin refreshes, solves, CG iterations and solves that hit maxiter so far."""
        return {"amg_setups": self.setups, "amg_refreshes": self.refreshes, "solves": self.solves,
                "cg_iterations": self.cg_iterations, "cg_unconverged": self.unconverged}
