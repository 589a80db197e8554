"""The norms of an iteration record: what the records of one run share, and how each lazy norm is computed.

A record of the loop (:func:`admmkit.loop.record.loop_record`) computes each norm the
first time something reads it; the functions below are those norms, one each,
with its formula beside it (r = A x^{k+1} - z^{k+1} - c).  :class:`RunContext`
holds what they share: the problem's norms, the constants of the run and the
time origin of the records.
"""
from __future__ import annotations

import math

import numpy as np

#: the fields computed on first access in a loop record (indices into the record's ``_vals``)
LAZY_FIELDS = ("primal_residual", "dual_residual", "rho_Ax_change", "lam_change", "x_change", "x_norm",
               "z_change", "primal_scale", "dual_scale")


class RunContext:
    """What the lazy fields of every record of one run share: the problem's norms and the constants."""

    __slots__ = ("problem", "norm", "x_norm", "x_distance", "order", "alpha", "c", "c_is_zero", "c_norm",
                 "has_adjoint", "primal_unit", "dual_unit", "inner", "start")

    def __init__(self, problem, order: str, alpha: float, c, c_norm: float, has_adjoint: bool,
                 primal_unit: float, dual_unit: float):
        from ..problem import Problem
        self.problem, self.inner = problem, problem.inner
        kind = type(problem)
        # the default Euclidean norms, without three Python calls each (bitwise the same value:
        # Problem.norm is sqrt(max(dot(y, y), 0)) and numpy's norm of a vector is sqrt(dot(y, y)))
        euclid_M = getattr(kind, "norm", None) is Problem.norm and getattr(kind, "inner", None) is Problem.inner
        euclid_X = getattr(kind, "x_norm", None) is Problem.x_norm
        self.norm = _euclidean if euclid_M else problem.norm
        self.x_norm = _euclidean if euclid_X else problem.x_norm
        self.x_distance = (_euclidean_distance if euclid_X and getattr(kind, "x_distance", None) is Problem.x_distance
                           else problem.x_distance)
        self.order, self.alpha, self.c = order, alpha, c
        self.c_is_zero = np.isscalar(c) and c == 0
        self.c_norm, self.has_adjoint = c_norm, has_adjoint
        self.primal_unit, self.dual_unit = primal_unit, dual_unit
        self.start = 0.0          # perf_counter() at the start of the loop: a record's time is from here


_dot, _sqrt = np.dot, math.sqrt


def _euclidean(y) -> float:
    return _sqrt(_dot(y, y))


def _euclidean_distance(a, b) -> float:
    d = a - b
    return _sqrt(_dot(d, d))


# -- the lazy fields: each a function of the record (r = A x^{k+1} - z^{k+1} - c) --------------
def _primal_residual(rec) -> float:                  # ||r||_M (the loop may have taken it already)
    taken = rec._d[12]
    return rec._ctx.norm(rec._residual()) if taken is None else taken


def _lam_change(rec) -> float:                       # ||lam^{k+1} - lam^k||_M = rho ||r||_M if alpha = 1
    if rec._ctx.alpha == 1.0:
        return rec.rho * rec.primal_residual
    return rec._ctx.norm(rec._lam - rec._lam_prev)


def _rho_Ax_change(rec) -> float:                    # rho ||A x^{k+1} - A x^k||_M
    return rec.rho * rec._ctx.norm(rec._Ax - rec._Ax_prev)


def _dual_residual(rec) -> float:
    ctx = rec._ctx
    if ctx.order == "zx":                            # rho ||A x^{k+1} - A x^k + z_hat - z^{k+1}||_M
        if ctx.alpha == 1.0:
            return rec.rho_Ax_change
        return rec.rho * ctx.norm((rec._Ax - rec._Ax_prev) + (rec._z - rec._hat))
    if not ctx.has_adjoint:
        return math.nan
    if ctx.alpha == 1.0:                             # rho ||A^T M (z^{k+1} - z^k)||
        return rec.rho * ctx.problem.adjoint_norm(rec._z - rec._z_prev)
    return rec.rho * ctx.problem.adjoint_norm((rec._Ax - rec._hat) + (rec._z - rec._z_prev))


def _dual_scale(rec) -> float:                       # ||A^T M lam|| (xz) or ||lam||_M (zx)
    ctx = rec._ctx
    if ctx.order == "zx":
        return ctx.norm(rec._lam)
    return ctx.problem.adjoint_norm(rec._lam) if ctx.has_adjoint else math.nan


def _primal_scale(rec) -> float:                     # max(||A x||_M, ||z||_M, ||c||_M)
    ctx = rec._ctx
    return max(ctx.norm(rec._Ax), ctx.norm(rec._z), ctx.c_norm)


#: each lazy field's computation from a record
COMPUTE = {
    "primal_residual": _primal_residual,
    "dual_residual": _dual_residual,
    "rho_Ax_change": _rho_Ax_change,
    "lam_change": _lam_change,
    "x_change": lambda rec: rec._ctx.x_distance(rec._x, rec._x_prev),
    "x_norm": lambda rec: rec._ctx.x_norm(rec._x),
    "z_change": lambda rec: rec._ctx.norm(rec._z - rec._z_prev),
    "primal_scale": _primal_scale,
    "dual_scale": _dual_scale,
}
