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

import functools
import math

import numpy as np

from admmkit import Problem

from . import products, rows
from .scaling import ruiz
from .segment import run_segment
from .kkt import kkt_relative, kkt_residuals
from .rows import FREE_ROW_PENALTY
from .validate import _real, _validate, check_options
from .xstep_forms import (REDUCED_MAX_NNZ, reduced_nnz_bound, weighted_gram, x_step_backend, x_step_solution,
                          x_step_solver)

class QP(Problem):
    """A convex QP, validated on construction.

    Parameters: P (n x n, symmetric PSD), q (n,), A (m x n), l, u (m,) with
    l <= u (infinite bounds allowed, equal bounds are equality rows), r a
    constant, sigma >= 0 the proximal weight, backend the sparse solver,
    xstep the form of the x-step system ("auto", "reduced" or "kkt"; see the
    module docstring), scaling the number of Ruiz iterations (0: none;
    OSQP uses 10), row_weights "uniform" (M = I) or "osqp" (OSQP's penalty
    per row, see ``admmkit.problems.qp.rows.row_weights``), allow_nonconvex
    (default False: a P that is not PSD is refused; True: a warning, and the
    QP is solved anyway, as OSQP does).  ``P, q, A, l, u`` stay the user's
    data; the loop works on ``Ps, qs, As, ls, us`` (the same objects when
    scaling = 0).
    """

    #: its steps are this package's own (tests/problems check them): the loop's segments may start at the first
    #: iteration (:mod:`admmkit.loop.segments`)
    trusted_steps = True
    #: :meth:`adjoint_norm` is always implemented (``admmkit.loop.checks.has_adjoint`` need not try it)
    adjoint_norm_implemented = True

    def __init__(self, P, q, A, l, u, r: float = 0.0, *, sigma: float = 1e-6, backend: str = "auto",
                 name: str = "qp", xstep: str = "auto", scaling: int = 0, row_weights: str = "uniform",
                 x_relaxation: float = 1.0, allow_nonconvex: bool = False):
        self.P, self.q, self.A, self.l, self.u = _validate(P, q, A, l, u, allow_nonconvex)
        r_value = _real("r", r)
        if r_value.shape not in ((), (1,)) or not math.isfinite(r_value.item()):
            raise ValueError(f"r (the constant of the objective) must be one finite number, got {r!r:.60}")
        self.r, self.name = float(r_value.item()), name
        self._take_options(dict(sigma=sigma, backend=backend, xstep=xstep, scaling=scaling, row_weights=row_weights,
                                x_relaxation=x_relaxation, allow_nonconvex=allow_nonconvex))

    def _take_options(self, options: dict, checked: bool = False) -> None:
        """The options, checked now (the constructor's messages) unless ``checked`` says they were; what they build
        waits for its first use."""
        self.options = options if checked else check_options(**options)
        self.n, self.m, self.c = self.P.shape[0], self.A.shape[0], 0.0
        self.sigma, self.x_relaxation = self.options["sigma"], self.options["x_relaxation"]
        self._xstep = self.options["xstep"]                 # "auto" is resolved at first use (xstep)
        backend = self.options["backend"]
        # a named backend is checked against the form now; "auto" fits either form (decided at first use)
        self._backend = backend if backend == "auto" else x_step_backend(backend, self.xstep)
        self._x_solver = None
        self._built = False

    def __getattr__(self, name: str):
        """The scaled data and the x-step's pieces, built at the first use of one of them (:meth:`_build`): the
        QP a user hands to ``solve_qp`` is copied with OSQP's options and never needs its own."""
        if name.startswith("__") or self.__dict__.get("_built", True):
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        self._build()
        return getattr(self, name)

    def _build(self) -> None:
        """The scaled copy (S1), the row weights and the free rows (Q5) of the options taken."""
        self._built = True
        scaling = self.options["scaling"]
        self.scaling, Ps, qs, As = ruiz(self.P, self.q, self.A, scaling)                          # (S1)
        self.scaled = scaling > 0
        if self.scaled:
            self.Ps, self.qs, self.As = Ps, qs, As
            self.ls, self.us = self.scaling.E * self.l, self.scaling.E * self.u
        else:
            self.Ps, self.qs, self.As, self.ls, self.us = self.P, self.q, self.A, self.l, self.u
        # free rows (both bounds infinite) under "osqp": the x-step's penalty is RHO_MIN whatever rho is, as OSQP's
        # rho_vec; their lam and residual are 0 from the first iteration on, so only the x-step sees it (Q5)
        self.w, self._free = rows.weights_and_free_rows(self.ls, self.us, self.options["row_weights"])
        self._ones = (np.ones(self.m), np.ones(self.n))         # unit weights and scalings for compiled kernels
        self.begin_run()
        w = self._ones[0] if self.w is None else self.w
        self._w_free_over_penalty = w[self._free] / FREE_ROW_PENALTY

    @functools.cached_property
    def At(self):
        """A' (CSR), built once at first use: scipy builds a new matrix on every ``A.T``."""
        return self.A.T.tocsr()

    @functools.cached_property
    def Ats(self):
        """The scaled A' (CSR; ``At`` when the QP is not scaled), built once at first use."""
        return self.As.T.tocsr() if self.scaled else self.At

    @property
    def xstep(self) -> str:
        """The x-step's form, "reduced" or "kkt" ("auto" decided here, the first time it is asked)."""
        if self._xstep == "auto":
            self._xstep = "kkt" if reduced_nnz_bound(self.P, self.A) > REDUCED_MAX_NNZ else "reduced"
        return self._xstep

    @property
    def _solver(self):
        """The x-step's factorisations (built on first use: a QP that ``solve_qp`` copies never needs its own)."""
        if self._x_solver is None:
            self._x_solver = x_step_solver(self, self._backend)
        return self._x_solver

    def setup(self, rho: float) -> int:
        """Factorise the x-step matrix for ``rho`` now (OSQP's setup), unless cached; return the factorisations made.

        The factorisation is not counted as a solve.
        """
        if float(rho) in self._solver:
            return 0
        self._solver.prepare(rho)
        return 1

    def update_rho(self, rho: float) -> None:
        """A change of rho (OSQP's ``update_rho``): the x-step's KKT or reduced matrix factorised now, held per
        rho (a numeric refactorisation of the same pattern with qdldl)."""
        self._solver.prepare(rho)

    def update_row_weights(self, rho: float, w) -> None:
        """A penalty per row (a rule's ``admmkit.RowPenalties``): M = diag(w), so that rho w_i is OSQP's rho_vec,
        in one refresh of the x-step (a numeric refactorisation of the KKT matrix with its new -R^-1 diagonal,
        or A'MA anew in the reduced form).  Free rows keep their weight (their penalty is RHO_MIN whatever rho
        is, Q5).  The loop keeps M lam; the weights hold until the next run starts (:meth:`begin_run` puts the
        QP's own back)."""
        if "_w_own" not in self.__dict__:
            self._w_own = (self.w, None if self.w is None else self.w.copy())
        new = np.array(w, dtype=float)
        if self.w is None:
            self.w = new
        else:
            new[self._free] = self.w[self._free]
            self.w[:] = new             # in place: whoever holds w (an accelerator's inner product) sees it
        self._reweighted()
        self._solver.refresh(rho)

    def _reweighted(self) -> None:
        """Drop what was made from the old row weights: the held R^-1, the reduced form's A'MA, the arrays the
        segment's in-kernel test reads (``segment_checks._data`` holds w itself, which a rule may have replaced)."""
        self.__dict__.pop("_inverse_penalty", None)
        self.__dict__.pop("_segment_checks", None)
        if self._x_solver is not None and self.xstep == "reduced":
            self._reduced_gram = weighted_gram(self)

    def inverse_penalty(self, rho: float) -> np.ndarray:
        """R^-1 = 1 / :meth:`penalty` (rho): the KKT matrix's last diagonal block is -R^-1 (the same numbers), held for
        the last rho asked."""
        held = self.__dict__.get("_inverse_penalty")
        if held is None or held[0] != rho:
            held = self._inverse_penalty = (rho, 1.0 / self.penalty(rho))
        return held[1]

    def penalty(self, rho: float) -> np.ndarray:
        """OSQP's rho_vec: rho w_i, and RHO_MIN on free rows under row_weights "osqp" (Q5)."""
        R = rho * (np.ones(self.m) if self.w is None else self.w)
        R[self._free] = FREE_ROW_PENALTY
        return R

    def with_options(self, **options) -> "QP":
        """The same data with some constructor options changed (a new QP, its own factorisations).

        The data was validated when this QP was built, so it is not checked
        again; only the options are (the constructor's messages).
        """
        merged = {**self.options, **options}
        if merged["allow_nonconvex"] != self.options["allow_nonconvex"]:     # the convexity verdict may change
            return QP(self.P, self.q, self.A, self.l, self.u, self.r, name=self.name, **merged)
        return self._copy(merged, checked=False)

    def with_checked_options(self, options: dict) -> "QP":
        """:meth:`with_options` for options already checked (``validate.check_options``'s plain values, without
        ``allow_nonconvex``): ``solve_qp``'s copy of a QP with the settings' options, which it checks once per
        settings (``solve.qp_options``), not at every copy."""
        return self._copy({**self.options, **options}, checked=True)

    def _copy(self, options: dict, checked: bool) -> "QP":
        """A QP of the same data (validated when this QP was built: not checked again) with ``options``."""
        qp = QP.__new__(QP)
        qp.P, qp.q, qp.A, qp.l, qp.u, qp.r, qp.name = self.P, self.q, self.A, self.l, self.u, self.r, self.name
        qp._take_options(options, checked)
        return qp

    # -- the splitting --------------------------------------------------------
    def begin_run(self):
        """Forget the iterates of a previous run (called by :func:`admmkit.solve` at the start)."""
        own = self.__dict__.pop("_w_own", None)
        if own is not None:             # a per-row rule moved the weights in the last run: the QP's own back
            self.w = own[0]
            if own[1] is not None:
                self.w[:] = own[1]
            self._reweighted()
            if self._x_solver is not None:
                self._x_solver.clear()
        self._x_in = self._x_last = self._x_rel = self._x_rel_prev = None
        self._residuals_of = None                 # (record, OSQP's residuals at it): see termination._iterate
        self._kernel_residuals = None             # (x_rel, z, lam, 11 numbers) of a segment's read iteration: ditto
        self._z_tilde = None                      # (x~, z~) of the last KKT x-step (Q6): see apply_A

    def initial_point(self):
        """(x0, z0, lam0) = (0, A 0 - c, 0) = (0, 0, 0), without the product: A 0 sums +0.0 terms from y = 0 and
        c = 0 (``admmkit.Problem.initial_point``'s numbers, every zero +0.0)."""
        return np.zeros(self.n), np.zeros(self.m), np.zeros(self.m)

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
        x_new, z_tilde = x_step_solution(self, xp, z, lam, rho)                            # (Q1), (Q5), (Q6)
        self._z_tilde = None if z_tilde is None else (x_new, z_tilde)      # A x_new, for apply_A (KKT form)
        if relax:
            a = self.x_relaxation
            self._x_rel_prev, self._x_rel, self._x_last = xp, a * x_new + (1.0 - a) * xp, x_new      # (Q4)
        return x_new

    def segment(self, x, z, lam, Ax, rho, alpha, order, count, read=False, accel=None, check=None):
        """``count`` iterations in one compiled call (:mod:`admmkit.loop.segments`; ``read``: the last is a read one;
        ``accel``: the accelerator's steps between them; ``check``: OSQP's test and rule made in the kernel where
        they go on, :mod:`admmkit.problems.qp.segment_checks`), or None where it does not apply."""
        if check is not None:
            from .segment_checks import checked_segment
            return checked_segment(self, x, z, lam, Ax, rho, alpha, order, count, read, accel, check)
        return run_segment(self, x, z, lam, Ax, rho, alpha, order, count, read, accel)

    def after_segment(self, x, x_prev, x_rel, x_rel_prev, done: int) -> None:
        """The x-step's bookkeeping after a segment of ``done`` iterations ended at x (its x-step's output)."""
        self._x_in = x_prev
        if self.x_relaxation != 1.0:
            self._x_last, self._x_rel, self._x_rel_prev = x, x_rel, x_rel_prev
        self._solver.solves += done

    def relaxed_x(self, x):
        """OSQP's x for the loop's iterate ``x`` (the relaxed one of (Q4) when ``x`` is the last x-step's, else x)."""
        if self._is_last(x):
            return self._x_rel
        return x

    def _is_last(self, x) -> bool:
        """``x`` is the last x-step's output (or a view of it, as a record's ``x``)."""
        last = self._x_last
        if last is None:
            return False
        if x is last or x.base is last:          # itself, or a record's view of it (``ctypes.data`` costs ~2 us)
            return True
        return x.shape == last.shape and x.ctypes.data == last.ctypes.data

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
        """A x (the scaled A when scaling); for the last KKT x-step's own output, z~ read off its solve (Q6), as OSQP
        (the loop asks for A x^{k+1} right after the x-step)."""
        held = self._z_tilde
        if held is not None and held[0] is x:
            self._z_tilde = None                 # read once: a later A x (a warm start's x0) is a product
            return held[1]
        return products.apply_A(self.As, x)

    def inner(self, a, b):
        """(a, b)_M = sum_i w_i a_i b_i."""
        return float(np.dot(a, b)) if self.w is None else float(np.dot(self.w * a, b))

    def inner_weights(self):
        """w of the inner product (a, b)_M = sum_i w_i a_i b_i (ones under uniform weights): an accelerator's steps
        use it (``admmkit.loop.anderson_kernel``), the same in the loop and in a segment."""
        return self._ones[0] if self.w is None else self.w

    def norm(self, y):
        """||y||_M."""
        return math.sqrt(max(self.inner(y, y), 0.0))

    def adjoint_norm(self, y):
        """||A' M y||_2 (Boyd's dual residual for order xz)."""
        return products.adjoint_norm(self.As, y if self.w is None else self.w * y)

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
        """1/2 x'Px + q'x + r at the user's x (P x compiled where chosen: scipy's sum, the same bits)."""
        return float(0.5 * x @ products.apply_A(self.P, x) + self.q @ x + self.r)

    def kkt(self, x, z, lam):
        """KKT residuals (inf-norms) of the user's QP at the user's x and the loop's (z, lam), OSQP's definitions and
        more (``admmkit.problems.qp.kkt``)."""
        return kkt_residuals(self, x, z, lam)

    def kkt_relative(self, x, z, lam):
        """OSQP's (R1)-(R3) relative to their scales at the user's x and the loop's (z, lam)
        (``admmkit.problems.qp.kkt.kkt_relative``): what :func:`admmkit.solve` checks a stop against."""
        return kkt_relative(self, x, z, lam)

    def counters(self):
        """Factorisations and solves of the x-step matrix so far."""
        if self._x_solver is None:
            return {"factorizations": 0, "solves": 0}
        return {"factorizations": self._solver.factorizations, "solves": self._solver.solves}
