"""Iterative x-steps: CG preconditioned by smoothed-aggregation AMG (pyamg).

A finite element ADMM x-step solves

    (K + rho D) x = b,      K the stiffness, D = A'MA the penalty term,       (12)

with a right-hand side that changes every iteration and a rho that changes
now and then.  A sparse factorisation (:mod:`admmkit.linsolve`) costs
O(n^1.5) time and memory in 2D and more in 3D; this module solves the same
system iteratively in O(n) memory.  :class:`IterativeXSolver` combines

* **CG preconditioned by one V-cycle of smoothed-aggregation AMG** (Vanek,
  Mandel & Brezina 1996, as implemented by pyamg), with a near-null space
  given by the plug-in: the rigid body modes for elasticity
  (:func:`problems.contact.iterative.rigid_body_modes`), the constants for a scalar problem;
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
  keeps it until the time it has measurably cost (the extra CG iterations
  against the convergence factor of a fresh hierarchy, times the measured
  time of one) exceeds the measured time of a Galerkin refresh -- the
  rent-or-buy rule, never more than twice the cost of the better choice made
  in hindsight.

Generic: nothing here knows about contact or obstacles; a plug-in passes K,
D, the near-null space and (optionally) the dofs of each node.
"""
from __future__ import annotations

import math
import time

import numpy as np
import scipy.sparse as sp

REUSE = ("auto", "keep", "galerkin", "rebuild")


# ---------------------------------------------------------------- node blocks of the AMG
def node_blocks(node: np.ndarray, component: np.ndarray, d: int) -> np.ndarray | None:
    """(n_nodes, d) dof indices grouped by node, or None if some node misses a component.

    With blocks, the AMG works on the node graph (BSR matrices with d x d
    blocks), which is how smoothed aggregation is meant to treat a vector
    problem; without them it works dof by dof.
    """
    node, component = np.asarray(node), np.asarray(component)
    order = np.lexsort((component, node))
    n_nodes = np.unique(node).size
    if n_nodes * d != node.size:
        return None
    blocks = order.reshape(n_nodes, d)
    if not (np.all(component[blocks] == np.arange(d)) and np.all(node[blocks] == node[blocks[:, :1]])):
        return None
    return blocks


# ---------------------------------------------------------------- the AMG preconditioner
class AMGPreconditioner:
    """One V-cycle of a pyamg smoothed-aggregation hierarchy for an SPD matrix.

    With ``blocksize`` d > 1 the hierarchy is built from the BSR form of A (d x d
    node blocks: aggregation on the node graph), then every level is stored in
    CSR and smoothed by pointwise Gauss-Seidel: one forward sweep before and one
    backward sweep after the coarse-grid correction, so the V-cycle is a
    symmetric positive definite operator (needed by CG) at half the cost of
    pyamg's default symmetric sweeps.  pyamg's block Gauss-Seidel on BSR took
    2-3 times as long per V-cycle for the same CG iterations (Example 1,
    4.1e5 unknowns: 310-340 ms against 100-155 ms, 23 iterations each).  The
    coarsest level is solved by sparse LU.
    """

    SMOOTHERS = (("gauss_seidel", {"sweep": "forward"}), ("gauss_seidel", {"sweep": "backward"}))
    #: sparse LU on the coarsest level: pyamg's default, a dense pseudo-inverse (SVD), took
    #: 0.1 s for 500 x 500 on one thread and 0.6-2.3 s on two threads of this loaded machine
    COARSE = "splu"
    #: no relaxation of the near-null space before fitting the prolongators: the rigid body modes are
    #: exact null vectors of K already.  pyamg's default (4 block Gauss-Seidel sweeps) took 40 % of the
    #: setup (Example 1, 4.1e5 unknowns: 2.9-3.3 s against 1.7-1.8 s) for the same 23 CG iterations
    IMPROVE = None

    def __init__(self, A: sp.spmatrix, near_null: np.ndarray | None, *, blocksize: int = 1, max_coarse: int = 500,
                 D: sp.spmatrix | None = None, rho: float | None = None):
        import pyamg
        from pyamg.relaxation.smoothing import change_smoothers
        start = time.perf_counter()
        A = sp.csr_matrix(A)
        An = A.tobsr(blocksize=(blocksize, blocksize)) if blocksize > 1 else A
        self.ml = pyamg.smoothed_aggregation_solver(
            An, B=near_null, symmetry="symmetric", max_coarse=max_coarse,
            presmoother=self.SMOOTHERS[0], postsmoother=self.SMOOTHERS[1], keep=False,
            coarse_solver=self.COARSE, improve_candidates=self.IMPROVE)
        if blocksize > 1:
            for level in self.ml.levels:
                level.A = _symmetric_csr(level.A)
            change_smoothers(self.ml, self.SMOOTHERS[0], self.SMOOTHERS[1])
        # A = K + rho D gives A_l = K_l + rho D_l on every level with D_l = R D_{l-1} P: keep the coarse
        # D_l on the coarse patterns, so that a Galerkin refresh for another rho is one axpy per level
        self._rho, self._pencils = rho, None
        if D is not None and rho is not None:
            pencils, Dl = [], sp.csr_matrix(D)
            for fine, coarse in zip(self.ml.levels[:-1], self.ml.levels[1:]):
                Dl = sp.csr_matrix(fine.R @ Dl @ fine.P)
                pencils.append(PencilMatrix(coarse.A, Dl))
            self._pencils = pencils
        self.setup_time = time.perf_counter() - start
        self.refresh_time = math.nan

    @property
    def levels(self) -> int:
        """Number of levels of the hierarchy."""
        return len(self.ml.levels)

    def operator_complexity(self) -> float:
        """Sum of the nonzeros of all levels over those of the finest."""
        return float(self.ml.operator_complexity())

    def refresh(self, A: sp.spmatrix, rho: float | None = None) -> None:
        """Galerkin refresh: keep the prolongators, make every level R A P for the new A and the smoothers.

        With the D and rho of the construction and the new ``rho``, the coarse
        operators are updated as A_l + (rho - rho_0) D_l (exact, one axpy per
        level); otherwise R A P is recomputed level by level.
        """
        from pyamg.multilevel import coarse_grid_solver
        from pyamg.relaxation.smoothing import change_smoothers
        start = time.perf_counter()
        levels = self.ml.levels
        levels[0].A = _symmetric_csr(A)
        if self._pencils is not None and rho is not None:
            for coarse, pencil in zip(levels[1:], self._pencils):
                coarse.A = _symmetric_csr(pencil.at(rho - self._rho))
        else:
            for fine, coarse in zip(levels[:-1], levels[1:]):
                coarse.A = _symmetric_csr(fine.R @ fine.A @ fine.P)
        change_smoothers(self.ml, self.SMOOTHERS[0], self.SMOOTHERS[1])
        self.ml.coarse_solver = coarse_grid_solver(self.COARSE)  # its cached factors belonged to the old A
        self.refresh_time = time.perf_counter() - start

    def __call__(self, r: np.ndarray) -> np.ndarray:
        """z = V-cycle(r), starting from zero (no residual norms, unlike ml.solve)."""
        z = np.zeros_like(r)
        if len(self.ml.levels) == 1:
            return self.ml.coarse_solver(self.ml.levels[0].A, r)
        self.ml._MultilevelSolver__solve(0, z, r, "V")  # pyamg's cycle, without ml.solve's two residual norms
        return z


def _symmetric_csr(A) -> sp.csr_matrix:
    """A as CSR, flagged symmetric for pyamg."""
    A = sp.csr_matrix(A)
    A.symmetry = "symmetric"
    return A


# ---------------------------------------------------------------- preconditioned CG
def pcg(matvec, b: np.ndarray, x0: np.ndarray, precond, *, tol: float, maxiter: int):
    """Preconditioned conjugate gradients from ``x0``.

    Stops when sqrt(r'Pr) <= tol * sqrt(|x'b|): with P a good preconditioner
    sqrt(r'Pr) is within mesh-independent constants of the energy norm of the
    error ||x - x*||_A, and x'b -> ||x*||_A^2, so the test is a relative energy
    error.  Returns (x, iterations, achieved ratio, starting ratio, r) where the
    ratios are sqrt(r'Pr)/sqrt(|x'b|) at the end and the start and r = b - A x
    is CG's (recursively updated) residual.
    """
    x = np.array(x0, dtype=float)
    r = b - matvec(x) if np.any(x) else np.array(b, dtype=float)
    z = precond(r)
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
        Ap = matvec(p)
        pAp = float(p @ Ap)
        if not (pAp > 0.0):
            raise np.linalg.LinAlgError(f"CG broke down: p'Ap = {pAp} (matrix or preconditioner not SPD)")
        alpha = rz / pAp
        x += alpha * p
        r -= alpha * Ap
        z = precond(r)
        rz_new = float(r @ z)
        p *= rz_new / rz
        p += z
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
    newest solution (Fischer's restart).
    """

    def __init__(self, K, D, size: int):
        self.K, self.D, self.size = K, D, size
        n = K.shape[0]
        self.Q = np.empty((n, size)) if size > 0 else np.empty((n, 0))
        self.KQ = np.empty_like(self.Q)   # K Q, so that adding a solution whose K x is known needs no product
        self.m = 0
        self.GK = np.zeros((size, size))
        self.GD = np.zeros((size, size))

    def guess(self, rho: float, b: np.ndarray) -> np.ndarray | None:
        """The projected initial guess, or None if the space is empty."""
        if self.m == 0:
            return None
        Q = self.Q[:, :self.m]
        G = self.GK[:self.m, :self.m] + rho * self.GD[:self.m, :self.m]
        c = Q.T @ b
        w, V = np.linalg.eigh(G)
        keep = w > 1e-12 * w.max()
        y = V[:, keep] @ ((V[:, keep].T @ c) / w[keep])
        return Q @ y

    def add(self, x: np.ndarray, Kx: np.ndarray | None = None) -> None:
        """Add a solution (orthonormalised against the basis; restart when full).

        ``Kx`` = K x, if known, saves the product with K.
        """
        if self.size == 0:
            return
        if self.m == self.size:
            self.m = 0
        q = np.array(x, dtype=float)
        norm0 = np.linalg.norm(q)
        if norm0 == 0:
            return
        coef = np.zeros(self.m)
        if self.m:
            Q = self.Q[:, :self.m]
            for _ in range(2):  # classical Gram-Schmidt twice ("twice is enough")
                c = Q.T @ q
                q -= Q @ c
                coef += c
        norm = np.linalg.norm(q)
        if norm <= 1e-10 * norm0:
            return
        q /= norm
        j = self.m
        self.Q[:, j] = q
        if Kx is None:
            Kq = self.K @ q
        else:          # K q = (K x - K Q coef) / norm
            Kq = (Kx - self.KQ[:, :j] @ coef) / norm if j else Kx / norm
        self.KQ[:, j] = Kq
        Dq = self.D @ q
        self.GK[j, :j + 1] = self.GK[:j + 1, j] = self.Q[:, :j + 1].T @ Kq
        self.GD[j, :j + 1] = self.GD[:j + 1, j] = self.Q[:, :j + 1].T @ Dq
        self.m += 1


# ---------------------------------------------------------------- K + rho D on one pattern
class PencilMatrix:
    """K + rho D for any rho without sparse additions: both on the union of their patterns.

    The union pattern is stored once in CSR (blocksize 1) or BSR (d x d blocks,
    what the smoothed aggregation of a vector problem wants); ``at(rho)``
    returns the matrix with data K_data + rho D_data, one axpy of the values.
    """

    def __init__(self, K: sp.csr_matrix, D: sp.csr_matrix, blocksize: int = 1):
        self.shape = K.shape
        self.blocksize = blocksize
        if blocksize == 1:     # fast path: D's entries all inside K's pattern (the usual case: D couples
            K = sp.csr_matrix(K, copy=True)   # dofs of one contact node or edge, which K couples too)
            K.sum_duplicates()
            K.sort_indices()
            self.pattern = K
            if self._contains(sp.csr_matrix(D)):
                self.K_data = K.data.copy()
                self.D_data = self._aligned(D)
                return
        ones = lambda M: sp.csr_matrix((np.ones_like(M.data), M.indices, M.indptr), shape=M.shape)  # noqa: E731
        pattern = (ones(K) + ones(D)).tocsr()     # positive values: no entry of the union cancels
        if blocksize > 1:
            pattern = pattern.tobsr(blocksize=(blocksize, blocksize))
        pattern.sort_indices()
        self.pattern = pattern
        self.K_data = self._aligned(K)
        self.D_data = self._aligned(D)

    def _contains(self, M: sp.csr_matrix) -> bool:
        """Whether every stored entry of M lies in the pattern."""
        M = M.tocsr()
        M.sum_duplicates()
        if M.nnz == 0:
            return True
        keys_union, keys = self._keys(self.pattern), self._keys(M)
        pos = np.minimum(np.searchsorted(keys_union, keys), keys_union.size - 1)
        return bool(np.array_equal(keys_union[pos], keys))

    def _keys(self, M) -> np.ndarray:
        rows = np.repeat(np.arange(M.indptr.size - 1), np.diff(M.indptr))
        return rows.astype(np.int64) * (self.shape_blocks + 1) + M.indices

    @property
    def shape_blocks(self) -> int:
        """Number of block columns."""
        return self.pattern.shape[1] // self.blocksize

    def _aligned(self, M: sp.csr_matrix) -> np.ndarray:
        """M's values placed on the union pattern (zeros elsewhere)."""
        bs = self.blocksize
        M = M.tobsr(blocksize=(bs, bs)) if bs > 1 else sp.csr_matrix(M)
        M.sort_indices()
        M.sum_duplicates()
        keys_union, keys = self._keys(self.pattern), self._keys(M)
        pos = np.searchsorted(keys_union, keys)
        if keys.size and not np.array_equal(keys_union[np.minimum(pos, keys_union.size - 1)], keys):
            raise AssertionError("pattern of a term is not inside the union pattern")  # by construction
        data = np.zeros_like(self.pattern.data)
        data[pos] = M.data
        return data

    def at(self, rho: float):
        """The sparse matrix K + rho D (CSR or BSR)."""
        data = self.K_data + rho * self.D_data
        if self.blocksize > 1:
            return sp.bsr_matrix((data, self.pattern.indices, self.pattern.indptr), shape=self.shape)
        return sp.csr_matrix((data, self.pattern.indices, self.pattern.indptr), shape=self.shape)


# ---------------------------------------------------------------- the x-step solver
class IterativeXSolver:
    """Solve (K + rho D) x = b for successive b and rho by AMG-preconditioned CG.

    Parameters
    ----------
    K, D : sparse symmetric matrices, K + rho D SPD for rho > 0.
    near_null : (n, m) near-null space of K (e.g. the rigid body modes of :mod:`problems.contact.iterative`) or
        None (pyamg's default: the constant per block).
    blocks : (n_nodes, d) dof indices of each node (:func:`node_blocks`) or
        None.  With blocks the AMG aggregates nodes (BSR d x d blocks).
    reuse : "auto", "keep", "galerkin" or "rebuild" (module docstring).
    tol : the inner tolerance: "adaptive" for rule (*) of the module docstring
        or a fixed relative energy-norm tolerance in (0, 1).
    kappa, tol0, tol_min : the constants of rule (*).
    projection : number of recent solutions kept for the projected warm start
        (0: warm start from the last solution only).
    maxiter : CG iteration cap per solve.  Reaching it with the error estimate
        above 0.5 raises LinAlgError; below, the solve counts as ``cg_unconverged``.

    Counters: ``setups`` (hierarchy builds), ``refreshes`` (Galerkin
    refreshes), ``solves``, ``cg_iterations``, ``unconverged``; times ``setup_time``,
    ``refresh_time``, ``solve_time``; ``last`` describes the last solve.
    """

    def __init__(self, K, D, *, near_null=None, blocks=None, reuse: str = "auto", tol="adaptive",
                 kappa: float = 0.1, tol0: float = 0.1, tol_min: float = 1e-10, projection: int = 8,
                 maxiter: int = 1000, max_coarse: int = 500):
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
            K, D = K[self.perm][:, self.perm].tocsr(), D[self.perm][:, self.perm].tocsr()
            if near_null is not None:
                near_null = np.asarray(near_null)[self.perm]
        self.K, self.D = K, D
        self.pencil = PencilMatrix(K, D)      # CSR: its products were faster than BSR's here
        self.near_null = None if near_null is None else np.ascontiguousarray(near_null, dtype=float)
        self.reuse, self.tol = reuse, tol
        self.kappa, self.tol0, self.tol_min = float(kappa), float(tol0), float(tol_min)
        self.maxiter, self.max_coarse = maxiter, max_coarse
        self.space = SolutionSpace(K, D, projection)
        self._rho_A = None        # rho of the current matrix A
        self._A = None
        self._amg = None
        self._rho_amg = None      # rho the preconditioner was built or refreshed for
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
        if self._rho_A != rho:
            self._A, self._rho_A = self.matrix(rho), rho
        if self._amg is None:
            action = "setup"
        elif self._rho_amg != rho:
            if self.reuse == "rebuild":
                action = "setup"
            elif self.reuse == "galerkin":
                action = "refresh"
            elif self.reuse == "keep":
                action = "keep"
            else:  # auto: rent (keep) until the measured loss reaches the price of a refresh
                action = "refresh" if self._stale_loss >= self._refresh_price() else "keep"
        if action == "setup":
            start = time.perf_counter()
            self._amg = AMGPreconditioner(self._A, self.near_null, blocksize=self.blocksize,
                                          max_coarse=self.max_coarse, D=self.D, rho=rho)
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

    def _refresh_price(self) -> float:
        """Seconds a Galerkin refresh costs: measured once one was done; before, 0 for the axpy
        refresh (one axpy per coarse level) and a third of the setup for R A P products."""
        if math.isfinite(self._amg.refresh_time):
            return self._amg.refresh_time
        return 0.0 if self._amg._pencils is not None else self._amg.setup_time / 3

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
            b = b[self.perm]
        action = self._prepare(rho)
        tol = self.inner_tolerance()
        start = time.perf_counter()
        guess = self.space.guess(rho, b)
        if guess is None:
            guess = np.zeros(self.n) if x0 is None else np.asarray(x0, dtype=float)[self.perm if self.perm is not None else slice(None)]
        A = self._A
        x, its, ratio, start_ratio, r = pcg(A.__matmul__, b, guess, self._amg, tol=tol, maxiter=self.maxiter)
        elapsed = time.perf_counter() - start
        if ratio > tol:
            if ratio > 0.5:
                raise np.linalg.LinAlgError(f"CG did not converge in {self.maxiter} iterations "
                                            f"(error ratio {ratio:.2e}, tolerance {tol:.2e})")
            self.unconverged += 1
        self._account(its, ratio, start_ratio, elapsed)
        Kx = (b - r) - rho * (self.D @ x)          # K x = A x - rho D x with A x = b - r: no product with K
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
        out = np.empty_like(v)
        out[self.perm] = v
        return out

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

    def _account(self, its: int, ratio: float, start_ratio: float, elapsed: float) -> None:
        """Track the convergence factor; with a stale hierarchy, add up the time it lost."""
        if its == 0 or not (ratio > 0 and start_ratio > ratio):
            return
        factor = (ratio / start_ratio) ** (1.0 / its)
        if self._rho_amg == self._rho_A:
            self._fresh_factor = factor if self._fresh_factor is None else min(self._fresh_factor, factor)
        elif self._fresh_factor is not None and self._fresh_factor < 1:
            needed = math.log(ratio / start_ratio) / math.log(self._fresh_factor)  # iterations a fresh one needs
            self._stale_loss += max(its - needed, 0.0) * elapsed / its

    def counters(self) -> dict[str, int]:
        """AMG setups, Galerkin refreshes, solves, CG iterations and solves that hit maxiter so far."""
        return {"amg_setups": self.setups, "amg_refreshes": self.refreshes, "solves": self.solves,
                "cg_iterations": self.cg_iterations, "cg_unconverged": self.unconverged}
