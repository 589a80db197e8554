"""The contact plug-in: the paper's splitting of min 1/2 u'Ku - f'u s.t. B u <= g.

x = u (displacement), z = p (the auxiliary normal displacement on Gamma_C),
A x = B u, c = 0, and the constraint space carries the lumped boundary mass
M_c, so that (the paper's eqs. (11)-(13))

    z-step:  p = min(g, u_n + lam/rho)                               (11)
    x-step:  (K + rho B'M_c B) u = f + B'M_c (rho p - lam)             (12)
    dual:    lam <- lam + rho (B u - p)      (in admmkit's loop)        (13)

With friction (Tresca, or each step of Coulomb's fixed point) B is replaced by
A = [B; T], T the tangential components at the contact nodes, z = (p, p_t),
M_c acts on every block, and the z-step adds the shrink of the tangential part
(:mod:`admmkit.problems.contact.solvers.friction`, eq. (11t)); every mode below works
unchanged with A in place of B (the condensed one on d n_c contact unknowns).

The x norm is the energy norm ||u||_K = sqrt(u'Ku), the norm of V in which
the paper's convergence theorem is stated; the paper's stopping rule
||u^{k+1} - u^k|| <= 1e-5 ||u^{k+1}|| is measured in it.

Two modes give the same iterates (to round-off):

- ``"full"``: the x-step solves with K + rho B'M_c B, one sparse
  factorisation per rho value (cached).
- ``"condensed"``: the nonlinearity lives on Gamma_C only.  With u0 = K^{-1} f,
  d0 = B u0 and the compliance C = B K^{-1} B' (from one factorisation, see
  :mod:`admmkit.problems.contact.solvers.schur`), every iterate is u = s u0 + K^{-1} B' w with
  (s, w) in R^{1+n_c}, and the x-step is the dense SPD solve

      (M_c^{-1} + rho C) w = rho p - lam - rho d0,   s = 1,

  so an iteration costs O(n_c^2); u itself is recovered once, at the end.
- ``"iterative"``: the x-step of the full mode solved inexactly by CG with a
  smoothed-aggregation AMG preconditioner (:mod:`admmkit.blocks.iterative`; memory
  linear in the unknowns, for meshes too large to factorise).  Its iterates
  match the other modes to the inner tolerance, not to round-off.
"""
from __future__ import annotations

from collections import deque

import numpy as np
import scipy.sparse as sp

from admmkit.kernels import compiled_now
from admmkit.linalg.linsolve import CachedFactorization
from admmkit.problems.contact.model.operators import ContactOperators
from admmkit.problems.contact.solvers import lapack
from admmkit.problems.contact.solvers.base import _ContactBase
from admmkit.problems.contact.solvers.schur import SCHUR_BACKENDS, BoundarySchur

MODES = ("auto", "full", "condensed", "iterative")
#: below this many contact nodes the condensed mode is chosen by "auto"
CONDENSED_MAX_NC = 3000
#: from this many unknowns "auto" prefers the iterative mode to the full one in 2D, and to both
#: direct modes in 3D (measured crossovers: docs/results/scale/amg_crossover.md, contact3d.md)
ITERATIVE_MIN_N_2D = 100_000
ITERATIVE_MIN_N_3D = 30_000
#: the iterative mode's AMG (admmkit.linalg.amg.AMGPreconditioner): rho(D^-1 A) from 10 Arnoldi steps and the
#: V-cycle on single-precision values.  Example 1 at 1e6 unknowns (one thread): AMG set-up 5.3 -> 2.8 s,
#: V-cycle 0.111 -> 0.078 s (with the compiled cycle), 83 -> 82 CG iterations in SADMM's 35 (issue #25)
FAST_AMG = {"spectral_steps": 10, "cycle_values": "float32"}


class DenseCholesky:
    """The Cholesky factor of a dense SPD matrix (LAPACK's potrf), solved by LAPACK's potrs directly.

    cho_solve's checks cost 0.25 ms at n_c = 600 and its wrapper ~40 us at n_c = 80 (a third of an
    iteration); the loop checks the iterates for non-finite values anyway.  Both routines are scipy's,
    called without importing scipy.linalg (:mod:`admmkit.problems.contact.solvers.lapack`).
    """

    __slots__ = ("factor", "lower")
    ldl = refactor = None        # what admmkit.linalg.linsolve.CachedFactorization asks of a solve

    def __init__(self, matrix: np.ndarray):
        self.factor, self.lower = lapack.cho_factor(matrix)

    def __call__(self, rhs: np.ndarray) -> np.ndarray:
        """The solution of matrix @ x = rhs."""
        return lapack.cho_solve(self.factor, self.lower, rhs)


#: the memory the condensed mode's dense factors of M_c^{-1} + rho C may hold together (bytes)
DENSE_FACTORS_BYTES = 2 ** 29


def dense_factors_held(m: int) -> int:
    """How many dense m x m factors (one per rho) the condensed mode keeps: those that fit DENSE_FACTORS_BYTES,
    at least 2 (the rho of the run and the one before), at most 32 (the cache's default).

    A factor dropped is refactorised when its rho comes back, the same factor: the iterates do not change.  A
    2D boundary (m up to 1,448) keeps 32; the 3D block's Coulomb levels (m = 3 n_c, thousands) kept 32 factors
    of 8 m^2 bytes each before (docs/contact.md)."""
    return int(max(2, min(32, DENSE_FACTORS_BYTES // max(8 * m * m, 1))))


class FullContact(_ContactBase):
    """Full-space mode: x = u, one cached sparse factorisation per rho."""

    mode = "full"

    def __init__(self, ops: ContactOperators, backend: str = "auto"):
        from admmkit.blocks.operators import LinearMap        # with scipy.sparse.linalg: imported for this mode only
        from admmkit.blocks.xstep import QuadraticXStep
        super().__init__(ops)
        self.n = ops.n_free
        # f(u) = 1/2 u'Ku - f'u, A = B (or [B; T]) in the boundary mass: one factorisation of K + rho A'MA per rho
        self._xstep = QuadraticXStep(ops.K, -ops.f, LinearMap(self.A, M=self.w), solver="direct", backend=backend)

    def x_step(self, z, lam, rho, u):
        """Solve (K + rho B'M_c B) u = f + B'M_c (rho p - lam), eq. (12) (A = [B; T] with friction)."""
        return self._xstep(z, lam, rho, u)

    def update_rho(self, rho):
        """A change of rho: K + rho B'M_c B factorised now (held per rho, admmkit.QuadraticXStep)."""
        self._xstep.update_rho(rho)

    def apply_A(self, u):
        """u_n = B u at the contact nodes (and T u with friction)."""
        return self.A @ u

    def x_norm(self, u):
        """Energy norm sqrt(u'Ku)."""
        return float(np.sqrt(max(u @ (self.ops.K @ u), 0.0)))

    def begin_run(self):
        """Count the x-step's work from the start of a run (called by admmkit.solve)."""
        self._xstep.begin_run()

    def counters(self):
        """Sparse factorisations (rho values this run used; ``factorizations_computed``: not cached) and solves."""
        return self._xstep.counters()


class CondensedContact(_ContactBase):
    """Boundary-condensed mode: x = (s, w), u = s u0 + K^{-1} B'w (see the module docstring).

    A run's steps are numpy's and LAPACK's, or, when compiled code runs (numba imported, see
    :func:`admmkit.kernels.compiled_now`) and the contact is frictionless, the kernels of
    ``admmkit.problems.contact.solvers.condensed_segment``, which also run SADMM's iterations in one compiled
    call (:meth:`segment`): the same iterates bit for bit as these steps.  The two choices agree to round-off.
    """

    mode = "condensed"
    #: the steps are the package's own (tests/problems/test_contact_segment.py): a segment may run the first iteration
    trusted_steps = True

    def __init__(self, ops: ContactOperators, backend: str = "auto", compiled="auto"):
        super().__init__(ops)
        self.n = self.A.shape[0] + 1
        # "auto", "cholmod", "ldl" or "superlu"; the last two order by nested dissection where the dofs have
        # coordinates; compiled: numba's kernels where they pay ("auto"), always (True: "auto" may take "ldl"), never
        self.schur = BoundarySchur(ops.K, self.A, backend=backend, coordinates=_coordinates(ops), compiled=compiled,
                                   order=getattr(ops, "condensed_order", None))   # stored by the operator cache
        self.e0, u0_c = self.schur.load(ops.f)     # ||u0||_K^2 = f'K^{-1}f and u0 = K^{-1} f on the contact dofs
        self._A_c = self.schur.contact_columns(self.A)
        self.d0 = self._A_c @ u0_c                 # A K^{-1} f (A touches the contact dofs only)
        self.C = self.schur.compliance(self.A, self._A_c)     # A K^{-1} A'
        # the dense m x m factors of M_c^{-1} + rho C, one per rho, as many as fit DENSE_FACTORS_BYTES (at least 2,
        # at most 32; least recently used out): a grown 3D contact boundary does not hold 32 of them
        self.factors = CachedFactorization(lambda rho: np.diag(1.0 / self.w) + rho * self.C, factor=DenseCholesky,
                                           max_cached=dense_factors_held(self.C.shape[0]))
        self._recent_Cw: deque = deque(maxlen=2)  # (x, C w) of the last x-steps: one C-matvec per iteration
        self.compiled_steps = False               # this run's steps are the compiled kernels (begin_run)

    def begin_run(self):
        """Start a run: its steps are the compiled kernels where compiled code runs now and the contact is
        frictionless, else numpy's and LAPACK's (the run keeps the choice)."""
        self.compiled_steps = self.friction is None and compiled_now()

    def update_rho(self, rho):
        """A change of rho: M_c^{-1} + rho C factorised now (dense Cholesky, held per rho)."""
        self.factors.prepare(rho)

    def _cholesky(self, rho) -> np.ndarray:
        """R with R'R = M_c^{-1} + rho C (its upper triangle), the held factor (factorised now if not held)."""
        held = self.factors.held(rho)              # the cache's own entry, as its solve takes it
        return held.factor.T if held.lower else held.factor

    def z_step(self, Ax, lam, rho, z):
        """p = min(g, u_n + lam/rho), eq. (11) (with friction also the shrink (11t))."""
        if not self.compiled_steps:
            return super().z_step(Ax, lam, rho, z)
        out = np.empty(Ax.shape[0])
        _kernels().z_step(self.g, Ax, lam, rho, out)
        return out

    def x_step(self, z, lam, rho, x):
        """(M_c^{-1} + rho C) w = rho p - lam - rho d0, s = 1: eq. (12) on Gamma_C."""
        if self.compiled_steps:
            m = z.shape[0]
            x_new, Cw = np.empty(m + 1), np.empty(m)
            _kernels().x_step(rho, z, lam, self.d0, self._cholesky(rho), self.C, x_new, Cw, np.empty(m))
            self.factors.solves += 1
        else:
            w = self.factors.solve(rho, rho * z - lam - rho * self.d0)
            x_new = np.concatenate(([1.0], w))
            Cw = self.C @ w
        self._recent_Cw.append((x_new, Cw))
        return x_new

    def segment(self, x, z, lam, Ax, rho, alpha, order, count, read=False, check=None):
        """``count`` iterations of order zx (alpha = 1) in one compiled call, SADMM's rule and the paper's stop
        decided in it where they go on (:mod:`admmkit.loop.segments`,
        ``admmkit.problems.contact.solvers.condensed_segment``); None where it does not apply (another order,
        alpha != 1, friction, a run on numpy's steps)."""
        if not self.compiled_steps or order != "zx" or alpha != 1.0:
            return None
        from admmkit.problems.contact.solvers.condensed_segment import run_segment
        out, before, after = run_segment(self, self._cholesky(rho), x, z, lam, Ax, self._Cw(x), rho, count, read,
                                         check)
        done = out[4]
        self.factors.solves += done
        if done:
            self._recent_Cw.append(before)
            self._recent_Cw.append(after)
        return out if read else out[:5]

    def _Cw(self, x):
        """C w for x = (s, w), reused when x is one of the last x-step results."""
        for x_seen, Cw in self._recent_Cw:
            if x_seen is x:
                return Cw
        if self.compiled_steps:
            Cw = np.empty(self.C.shape[0])
            _kernels().symmetric_times(self.C, np.ascontiguousarray(x[1:], dtype=np.float64), Cw)
            return Cw
        return self.C @ x[1:]

    def apply_A(self, x):
        """u_n = s d0 + C w."""
        if not self.compiled_steps:
            return x[0] * self.d0 + self._Cw(x)
        out = np.empty(self.d0.shape[0])
        _kernels().apply_A(float(x[0]), self.d0, self._Cw(x), out)
        return out

    def x_norm(self, x):
        """||u||_K with u'Ku = s^2 e0 + 2 s d0'w + w'Cw."""
        s, w = x[0], x[1:]
        return float(np.sqrt(max(s * s * self.e0 + 2 * s * (self.d0 @ w) + w @ self._Cw(x), 0.0)))

    def x_distance(self, x, y):
        """||u_x - u_y||_K, from the cached C w of both (no n_c x n_c product)."""
        ds, dw = x[0] - y[0], x[1:] - y[1:]
        dCw = self._Cw(x) - self._Cw(y)
        return float(np.sqrt(max(ds * ds * self.e0 + 2 * ds * (self.d0 @ dw) + dw @ dCw, 0.0)))

    def finalize(self, x):
        """The full displacement u = K^{-1}(s f + B'w): one solve, once (with ``ldl`` its forward half was done
        for f at the set-up, BoundarySchur.load)."""
        return self.schur.solve_load(x[0], self._A_c.T @ x[1:])

    def initial_point(self):
        """u^0 = 0 (s = 0, w = 0), p^0 = 0, lam^0 = 0."""
        x0 = np.zeros(self.n)
        m = self.A.shape[0]
        return x0, np.zeros(m), np.zeros(m)

    def counters(self):
        """Dense factorisations (one per rho held) and solves on Gamma_C."""
        return {"factorizations": self.factors.factorizations, "solves": self.factors.solves}


class IterativeContact(_ContactBase):
    """Iterative mode: x = u, the x-step (12) by AMG-preconditioned CG (admmkit.blocks.iterative)."""

    mode = "iterative"

    def __init__(self, ops: ContactOperators, **options):
        from admmkit.blocks.iterative import IterativeXSolver          # AMG and its kernels: loaded for this mode only
        from admmkit.problems.contact.solvers.iterative import near_null_space
        super().__init__(ops)
        self.n = ops.n_free
        AtMA = (self.A.T @ sp.diags(self.w) @ self.A).tocsr()
        modes, blocks = near_null_space(ops)
        options.setdefault("amg_options", FAST_AMG)
        self.solver = IterativeXSolver(ops.K, AtMA, near_null=modes, blocks=blocks, **options)

    def update_rho(self, rho):
        """A change of rho: K + rho B'M_c B, and the AMG hierarchy's set-up, Galerkin refresh or keep, now."""
        self.solver.update_rho(rho)

    def x_step(self, z, lam, rho, u):
        """Solve (K + rho B'M_c B) u = f + B'M_c (rho p - lam), eq. (12), by AMG-CG warm-started."""
        rhs = self.ops.f + self.A.T @ (self.w * (rho * z - lam))
        return self.solver.solve(rho, rhs, x0=u)

    def apply_A(self, u):
        """u_n = B u at the contact nodes (and T u with friction)."""
        return self.A @ u

    def x_norm(self, u):
        """Energy norm sqrt(u'Ku) (K u from the x-step's CG residual when u is a recent iterate)."""
        Ku = self.solver.known_Kx(u)
        return float(np.sqrt(max(u @ (self.ops.K @ u if Ku is None else Ku), 0.0)))

    def x_distance(self, u, v):
        """||u - v||_K, from the known K u and K v of the last two iterates when possible."""
        Ku, Kv = self.solver.known_Kx(u), self.solver.known_Kx(v)
        d = u - v
        Kd = self.ops.K @ d if Ku is None or Kv is None else Ku - Kv
        return float(np.sqrt(max(d @ Kd, 0.0)))

    def counters(self):
        """AMG setups and Galerkin refreshes, solves and CG iterations."""
        return self.solver.counters()


def _kernels():
    """``admmkit.problems.contact.solvers.condensed_segment`` (imported at a compiled run's first step)."""
    from admmkit.problems.contact.solvers import condensed_segment
    return condensed_segment


def _coordinates(ops) -> np.ndarray | None:
    """The free dofs' coordinates when the operators know them (None otherwise: minimum degree instead)."""
    points = getattr(ops, "dof_coordinates", None)
    return points() if callable(points) else None


def contact_problem(ops: ContactOperators, mode: str = "auto", backend: str = "auto",
                    compiled="auto") -> _ContactBase:
    """The contact plug-in for assembled operators, in the requested mode.

    ``backend`` names the sparse solver: any of :mod:`admmkit.linalg.linsolve`'s in
    the full mode, "cholmod", "ldl" or "superlu" (or "auto") in the condensed mode.
    ``compiled`` (condensed mode): "auto" runs numba's kernels only where
    they pay, so a small body's set-up imports no numba; True also lets
    "auto" take the compiled ``ldl`` for a small body (the choice before
    issue #49; the same iterates to round-off, a few ms faster once numba is
    loaded); False never (:class:`admmkit.problems.contact.solvers.schur.BoundarySchur`).
    ``mode="auto"`` picks the condensed mode when the contact boundary has at
    most CONDENSED_MAX_NC nodes (the dense n_c x n_c compliance then fits and
    its factorisations are cheaper than sparse ones of the whole body), unless
    ``auto_mode`` finds the body too large for a factorisation.
    """
    if mode not in MODES:
        raise ValueError(f"mode must be one of {', '.join(MODES)}, got {mode!r}")
    if compiled not in ("auto", True, False):
        raise ValueError(f"compiled must be 'auto', True or False, got {compiled!r}")
    if mode == "auto":
        mode = auto_mode(ops, backend)
    if mode == "iterative":
        return IterativeContact(ops)
    if mode == "condensed":
        if backend not in ("auto",) + SCHUR_BACKENDS:
            raise ValueError(f"backend for mode 'condensed' must be 'auto' or one of {', '.join(SCHUR_BACKENDS)} "
                             f"(the solvers that give the Schur complement), got {backend!r}")
        return CondensedContact(ops, backend=backend, compiled=compiled)
    return FullContact(ops, backend=backend)


def auto_mode(ops: ContactOperators, backend: str = "auto") -> str:
    """The mode ``"auto"`` picks (measured crossovers in docs/results/scale/).

    The direct choice is the condensed mode when n_c <= CONDENSED_MAX_NC (and
    the backend can build the Schur complement), else the full mode.  The
    iterative mode replaces it in 3D from ITERATIVE_MIN_N_3D unknowns, in 2D
    when the direct choice is the full mode and there are at least
    ITERATIVE_MIN_N_2D unknowns, and whenever the direct choice's memory
    estimate exceeds the available memory.  On Example 1 (2D, n_c <= 1000)
    the condensed mode was the fastest at every size measured up to 4.1e5
    unknowns and tied with the iterative one at 1e6, so "auto" keeps it
    there; the iterative mode beat the full one from 1e5 unknowns on.  On the
    3D scene the iterative mode beat both direct modes from between 1.8e4 and
    4.2e4 unknowns on (docs/results/scale/contact3d.md).
    """
    m = ops.n_c * (ops.dim if ops.friction is not None else 1)   # rows of A: normal (and tangential) parts
    direct = "condensed" if m <= CONDENSED_MAX_NC and backend in ("auto",) + SCHUR_BACKENDS else "full"
    dim = ops.dim
    if dim == 3 and ops.n_free >= ITERATIVE_MIN_N_3D:
        return "iterative"
    if dim == 2 and direct == "full" and ops.n_free >= ITERATIVE_MIN_N_2D:
        return "iterative"
    return "iterative" if _direct_would_not_fit(ops, direct) else direct


def _direct_would_not_fit(ops: ContactOperators, mode: str) -> bool:
    """Whether the memory estimate of a direct mode exceeds the available memory."""
    from admmkit.problems.contact.model.memory import available_memory, memory_need, memory_need3d
    from admmkit.problems.contact.model.scene import Scene, is_scene3d
    if isinstance(ops.scene, Scene):
        need = memory_need(ops.scene, mode)
    elif is_scene3d(ops.scene):
        need = memory_need3d(ops.scene, mode)
    else:
        return False
    return need > available_memory()
