"""The read-only record of one ADMM iteration, as policies and stopping rules see it.

The loop builds a *lazy* record: it holds references to the iterates and
computes each norm the first time something reads it (then keeps it), so an
iteration costs only the norms that the stopping rule, the policy, the
callback or the history actually read.  A record made by hand
(``IterationRecord(k=..., rho=..., primal_residual=..., ...)``, as in the
tests of the policies) holds the given numbers and computes nothing.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from .norms import COMPUTE, LAZY_FIELDS, RunContext

__all__ = ["IterationRecord", "LAZY_FIELDS", "SCALAR_FIELDS", "RunContext", "loop_record", "ratio", "relative_change"]

#: the scalar fields of a record that the history keeps, in its column order
SCALAR_FIELDS = ("k", "rho", "primal_residual", "dual_residual", "rho_Ax_change", "lam_change", "x_change",
                 "x_norm", "z_change", "primal_scale", "dual_scale", "primal_unit", "dual_unit", "time")
_INDEX = {name: i for i, name in enumerate(LAZY_FIELDS)}
#: each lazy field's computation, in the order of LAZY_FIELDS
_COMPUTE_IN_ORDER = tuple(COMPUTE[name] for name in LAZY_FIELDS)


def _lazy(name: str, doc: str) -> property:
    i, compute = _INDEX[name], COMPUTE[name]

    def get(self):
        v = self._vals[i]
        if v is None:
            v = self._vals[i] = compute(self)
        return v
    return property(get, doc=doc)


def _cached(rec) -> list:
    """The record's cached vectors (6 read-only views, then r), made on first use."""
    try:
        return rec._cache
    except AttributeError:
        cache = [None] * 7
        _SET_CACHE(rec, cache)
        return cache


def _view(i: int, slot: int, doc: str) -> property:
    def get(self):
        cache = _cached(self)
        view = cache[slot]
        if view is None:
            v = self._d[i]
            if v is None:
                return None
            view = v.view()
            view.flags.writeable = False
            cache[slot] = view
        return view
    return property(get, doc=doc)


class _Given:
    """The context of a hand-made record: its order, units, inner product and row weights."""

    __slots__ = ("order", "primal_unit", "dual_unit", "inner", "alpha", "row_weights")

    def __init__(self, order, primal_unit, dual_unit, inner, row_weights=None):
        self.order, self.primal_unit, self.dual_unit, self.inner, self.alpha = order, primal_unit, dual_unit, inner, 1.0
        self.row_weights = row_weights


def _item(i: int, doc: str) -> property:
    return property(lambda self: self._d[i], doc=doc)


def _ctx_attr(name: str, doc: str) -> property:
    return property(lambda self: getattr(self._ctx, name), doc=doc)


class IterationRecord:
    """What happened in iteration k (which produced x^{k+1}, z^{k+1}, lam^{k+1}).

    All norms are those of the problem: ||.||_M on the constraint space,
    ||.||_X on x.  With r = A x^{k+1} - z^{k+1} - c:

    - ``primal_residual``  ||r||_M
    - ``dual_residual``    Boyd's dual residual: rho ||A^T M (z^{k+1} - z^k)||
      for order "xz"; rho ||A (x^{k+1} - x^k)||_M for order "zx" (where x is
      the second block; this is the denominator of the paper's w_k).  With
      over-relaxation (alpha != 1) the norm of the first block's optimality
      defect ||lam_x - lam^{k+1}|| (xz) or ||lam_z - lam^{k+1}|| (zx), see docs/math.md
    - ``rho_Ax_change``    rho ||A x^{k+1} - A x^k||_M (the paper's w_k denominator)
    - ``lam_change``       ||lam^{k+1} - lam^k||_M (= rho ||r||_M when alpha = 1; w_k numerator)
    - ``x_change``, ``x_norm``  ||x^{k+1} - x^k||_X and ||x^{k+1}||_X
    - ``primal_scale``     max(||A x||_M, ||z||_M, ||c||_M)  (Boyd 3.3.1)
    - ``dual_scale``       ||A^T M lam|| ("xz") or ||lam||_M ("zx")
    - ``primal_unit``, ``dual_unit``  the norms of the all-ones vector of the
      spaces the residuals live in (Boyd's sqrt(p), sqrt(n))

    In a record of the loop each of these norms is computed the first time it
    is read and then kept, so an iteration pays only for the norms something
    reads.  The vectors are read-only views of the new iterates; ``z_prev``
    and ``Ax_prev`` are those of the previous iterate (z^k, A x^k) and
    ``inner`` is the problem's (., .)_M (None: Euclidean, for hand-made
    records).  From them the record gives the multiplier of each block's
    optimality condition (``lam_x``, ``lam_z``), which spectral rules need.
    Records are read-only.
    """

    # _d = (k, rho, time, x, z, lam, Ax, x_prev, z_prev, lam_prev, Ax_prev, hat, ||r||_M if the loop took it);
    # _vals = the 9 lazy norms; _cache (set on first use) = 6 read-only views, then r
    __slots__ = ("_d", "_vals", "_ctx", "_cache")

    def __init__(self, k: int, rho: float, order: str, primal_residual: float, dual_residual: float,
                 rho_Ax_change: float, lam_change: float, x_change: float, x_norm: float, z_change: float,
                 primal_scale: float, dual_scale: float, primal_unit: float, dual_unit: float, time: float,
                 x: np.ndarray, z: np.ndarray, lam: np.ndarray, Ax: np.ndarray,
                 z_prev: np.ndarray | None = None, Ax_prev: np.ndarray | None = None,
                 inner: Callable[[np.ndarray, np.ndarray], float] | None = None,
                 row_weights: np.ndarray | None = None):
        _SET_D(self, (k, rho, time, x, z, lam, Ax, None, z_prev, None, Ax_prev, None, None))
        _SET_VALS(self, [primal_residual, dual_residual, rho_Ax_change, lam_change, x_change, x_norm,
                         z_change, primal_scale, dual_scale])
        _SET_CTX(self, _Given(order, primal_unit, dual_unit, inner, row_weights))

    def __setattr__(self, name, value):
        raise AttributeError(f"IterationRecord is read-only (tried to set {name!r})")

    k = _item(0, "The iteration number k (0-based).")
    rho = _item(1, "rho_k, the penalty of this iteration.")
    time = _item(2, "Seconds since the start of the run, after the two steps.")
    _x, _z, _lam, _Ax = _item(3, ""), _item(4, ""), _item(5, ""), _item(6, "")
    _x_prev, _z_prev, _lam_prev, _Ax_prev, _hat = _item(7, ""), _item(8, ""), _item(9, ""), _item(10, ""), _item(11, "")
    order = _ctx_attr("order", "'xz' or 'zx'.")
    alpha = _ctx_attr("alpha", "The over-relaxation parameter of the run.")
    primal_unit = _ctx_attr("primal_unit", "||1||_M (Boyd's sqrt(p)).")
    dual_unit = _ctx_attr("dual_unit", "sqrt(n) (order xz) or ||1||_M (order zx).")
    inner = _ctx_attr("inner", "The problem's inner product (., .)_M (None: Euclidean).")
    primal_residual = _lazy("primal_residual", "||A x^{k+1} - z^{k+1} - c||_M.")
    dual_residual = _lazy("dual_residual", "Boyd's dual residual (see the class docstring).")
    rho_Ax_change = _lazy("rho_Ax_change", "rho_k ||A x^{k+1} - A x^k||_M.")
    lam_change = _lazy("lam_change", "||lam^{k+1} - lam^k||_M.")
    x_change = _lazy("x_change", "||x^{k+1} - x^k||_X.")
    x_norm = _lazy("x_norm", "||x^{k+1}||_X.")
    z_change = _lazy("z_change", "||z^{k+1} - z^k||_M.")
    primal_scale = _lazy("primal_scale", "max(||A x^{k+1}||_M, ||z^{k+1}||_M, ||c||_M).")
    dual_scale = _lazy("dual_scale", "||A^T M lam^{k+1}|| (order xz) or ||lam^{k+1}||_M (order zx).")
    x = _view(3, 0, "x^{k+1} (read-only).")
    z = _view(4, 1, "z^{k+1} (read-only).")
    lam = _view(5, 2, "lam^{k+1} (read-only).")
    Ax = _view(6, 3, "A x^{k+1} (read-only).")
    z_prev = _view(8, 4, "z^k (read-only; None in a hand-made record that did not give it).")
    Ax_prev = _view(10, 5, "A x^k (read-only; None in a hand-made record that did not give it).")

    @property
    def row_weights(self) -> np.ndarray | None:
        """The diagonal w of M in this iteration (row i's penalty is rho w_i), a copy: the problem's
        ``inner_weights()`` (None when it has none; a hand-made record's given ``row_weights``).  What a rule
        with ``per_row = True`` moves (:class:`admmkit.RowPenalties`)."""
        ctx = self._ctx
        if isinstance(ctx, _Given):
            w = ctx.row_weights
        else:
            weights = getattr(ctx.problem, "inner_weights", None)
            w = weights() if callable(weights) else None
        return None if w is None else np.array(w, dtype=float)

    def _residual(self) -> np.ndarray:
        """r = A x^{k+1} - z^{k+1} - c (the dual update's vector when alpha = 1)."""
        cache = _cached(self)
        r = cache[6]
        if r is None:
            ctx = self._ctx
            r = cache[6] = self._Ax - self._z if ctx.c_is_zero else self._Ax - self._z - ctx.c
        return r

    def complete(self) -> "IterationRecord":
        """Compute every norm not yet computed (what the eager loop computed), in the order of ``LAZY_FIELDS``, as
        reading each would; return self."""
        vals = self._vals
        for i, compute in enumerate(_COMPUTE_IN_ORDER):
            if vals[i] is None:
                vals[i] = compute(self)
        return self

    def computed(self) -> tuple:
        """The lazy fields as they stand: a number where computed, None where not (no computation)."""
        return tuple(self._vals)

    def dot(self, a: np.ndarray, b: np.ndarray) -> float:
        """(a, b)_M, the problem's inner product of the constraint space (Euclidean if not given)."""
        inner = self._ctx.inner
        return float(np.dot(a, b)) if inner is None else float(inner(a, b))

    @property
    def lam_x(self) -> np.ndarray:
        """The multiplier of the x-step's optimality condition: -A^T M lam_x in the subdifferential of f at x^{k+1}.

        Order "zx" (x-step last): lam^{k+1}.  Order "xz": the x-step used z^k, so
        lam_x = lam^k + rho (A x^{k+1} - z^k - c), which is
        lam^{k+1} + rho (z^{k+1} - z^k) when alpha = 1
        (Xu, Figueiredo & Goldstein 2017's "hat" multiplier).  Needs ``z_prev``.
        """
        if self.order == "zx":
            return self.lam
        if self._z_prev is None:
            raise ValueError("lam_x of an order 'xz' record needs z_prev (the previous z)")
        if self.alpha == 1.0:
            return self.lam + self.rho * (self.z - self.z_prev)
        return self.lam + self.rho * ((self._Ax - self._hat) + (self._z - self._z_prev))

    @property
    def lam_z(self) -> np.ndarray:
        """The multiplier of the z-step's optimality condition: M lam_z in the subdifferential of g at z^{k+1}.

        Order "xz" (z-step last): lam^{k+1}.  Order "zx": the z-step used A x^k, so
        lam_z = lam^k + rho (A x^k - z^{k+1} - c), which is
        lam^{k+1} - rho (A x^{k+1} - A x^k) when alpha = 1.  Needs ``Ax_prev``.
        """
        if self.order == "xz":
            return self.lam
        if self._Ax_prev is None:
            raise ValueError("lam_z of an order 'zx' record needs Ax_prev (the previous A x)")
        if self.alpha == 1.0:
            return self.lam - self.rho * (self.Ax - self.Ax_prev)
        return self.lam - self.rho * ((self._Ax - self._Ax_prev) + (self._z - self._hat))

    @property
    def rel_change(self) -> float:
        """||x^{k+1} - x^k||_X / ||x^{k+1}||_X (inf when x^{k+1} = 0 and x moved)."""
        return relative_change(self.x_change, self.x_norm)

    @property
    def primal_residual_rel(self) -> float:
        """Primal residual normalised by ``primal_scale``."""
        return ratio(self.primal_residual, self.primal_scale)

    @property
    def dual_residual_rel(self) -> float:
        """Dual residual normalised by ``dual_scale``."""
        return ratio(self.dual_residual, self.dual_scale)

    def __repr__(self) -> str:
        shown = ", ".join(f"{n}={v:.3g}" for n, v in zip(LAZY_FIELDS, self._vals) if v is not None)
        return f"IterationRecord(k={self.k}, rho={self.rho:.4g}, order={self.order!r}{', ' if shown else ''}{shown})"


def relative_change(change: float, norm: float) -> float:
    """change / norm (0 when both are 0, inf when only norm is 0)."""
    if norm > 0:
        return change / norm
    return 0.0 if change == 0 else float("inf")


def ratio(a: float, b: float) -> float:
    """a / b, with 0/0 = 0 and a/0 = inf."""
    if b > 0:
        return a / b
    return 0.0 if a == 0 else float("inf")



_SET_D = IterationRecord.__dict__["_d"].__set__
_SET_VALS = IterationRecord.__dict__["_vals"].__set__
_SET_CTX = IterationRecord.__dict__["_ctx"].__set__
_SET_CACHE = IterationRecord.__dict__["_cache"].__set__
_NEW = object.__new__


def loop_record(ctx: RunContext, k: int, rho: float, t: float, x1, z1, lam1, Ax1, x, z, lam, Ax, hat,
                r_norm) -> IterationRecord:
    """The loop's lazy record of iteration k: x^{k+1}, z^{k+1}, lam^{k+1}, A x^{k+1}, then x^k, z^k, lam^k, A x^k.

    ``t`` is the perf_counter() after the two steps, ``hat`` the relaxed vector (None when
    alpha = 1, and then lam^k is not kept: ||lam^{k+1} - lam^k|| = rho ||r||), ``r_norm`` is
    ||A x^{k+1} - z^{k+1} - c||_M if the dual update took it (else None; ``primal_residual``
    returns it when read, and it counts as computed only then), as an iteration of
    :mod:`admmkit.loop.steps` returns them.
    """
    rec = _NEW(IterationRecord)
    _SET_D(rec, (k, rho, t - ctx.start, x1, z1, lam1, Ax1, x, z, None if hat is None else lam, Ax, hat, r_norm))
    _SET_VALS(rec, [None] * 9)
    _SET_CTX(rec, ctx)
    return rec
