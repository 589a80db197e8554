"""The problem protocol: what a plug-in tells the ADMM loop.

admmkit solves

    minimise  f(x) + g(z)   subject to   A x - z = c,

where the constraint space carries its own inner product (a, b)_M (a lumped
boundary mass for finite elements, the identity for a QP).  The augmented
Lagrangian, with the multiplier lam stored *unscaled*, is

    L_rho(x, z; lam) = f(x) + g(z) + (lam, A x - z - c)_M + rho/2 ||A x - z - c||_M^2.

A plug-in subclasses :class:`Problem` and implements the two partial
minimisations of L_rho and the constraint map; everything else has a default.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any

import numpy as np


class Problem(ABC):
    """Base class of every plug-in.

    Required: :meth:`x_step`, :meth:`z_step`, :meth:`apply_A` and the attribute
    ``n`` (the number of x unknowns, used for the default starting point and
    the absolute dual tolerance).  Optional: ``c`` (default 0), the inner
    products :meth:`inner`, :meth:`x_norm`, :meth:`x_distance`,
    :meth:`adjoint_norm` (needed only for Boyd's dual residual in order "xz"),
    :meth:`objective`, :meth:`kkt`, :meth:`counters` and :meth:`update_rho`
    (the event of a change of rho).  A plug-in whose inner product is
    M = diag(w) takes a penalty per row (rho w_i, from a rule with
    ``per_row = True``, :class:`admmkit.RowPenalties`) by implementing two more:
    ``inner_weights()`` (w, of z's shape) and ``update_row_weights(rho, w)``
    (make M = diag(w) and refresh what depends on it, once; the loop then
    rescales lam so that M lam is kept).  Without them such a rule is refused.
    """

    #: number of x unknowns
    n: int
    #: the constant of the constraint A x - z = c (a scalar or an array)
    c: Any = 0.0

    # -- the three pieces of the splitting ---------------------------------
    @abstractmethod
    def x_step(self, z: np.ndarray, lam: np.ndarray, rho: float, x: np.ndarray) -> np.ndarray:
        """Return argmin_x L_rho(x, z; lam).

        ``x`` is the current iterate, passed for warm starts or proximal terms;
        ``rho`` is passed on every call, the value of the last
        :meth:`update_rho` event during a run (or rho_0).  Return a new array;
        do not modify the arguments.
        """

    @abstractmethod
    def z_step(self, Ax: np.ndarray, lam: np.ndarray, rho: float, z: np.ndarray) -> np.ndarray:
        """Return argmin_z L_rho(x, z; lam), given ``Ax`` = A x (a new array)."""

    @abstractmethod
    def apply_A(self, x: np.ndarray) -> np.ndarray:
        """Return A x, the constraint map applied to x."""

    # -- the event of a change of rho --------------------------------------
    def update_rho(self, rho: float) -> None:
        """A change of rho: the loop calls this once, at the line where rho_{k+1} != rho_k takes effect.

        The place to redo what depends on rho, as OSQP's ``update_rho``: a new
        factorisation of the x-step's matrix, a numeric refactorisation of the
        same pattern, a Galerkin refresh of a multigrid hierarchy, or nothing
        (the default; a plug-in whose steps take rho as a scalar has nothing
        to redo).  Called only when another iteration follows.  The building
        blocks implement it (:class:`admmkit.QuadraticXStep`,
        :class:`admmkit.SplitProblem`); docs/framework.md lists what each x-step does.
        """

    # -- inner products (defaults: Euclidean) -------------------------------
    def inner(self, a: np.ndarray, b: np.ndarray) -> float:
        """The inner product (a, b)_M of the constraint space."""
        return float(np.dot(a, b))

    def norm(self, y: np.ndarray) -> float:
        """||y||_M, the norm of the constraint space."""
        return float(np.sqrt(max(self.inner(y, y), 0.0)))

    def x_norm(self, x: np.ndarray) -> float:
        """||x||_X, the norm the relative-change stopping rule uses."""
        return float(np.linalg.norm(x))

    def x_distance(self, x: np.ndarray, y: np.ndarray) -> float:
        """||x - y||_X (override when x is an affine representation)."""
        return self.x_norm(x - y)

    def adjoint_norm(self, y: np.ndarray) -> float:
        """||A^T M y|| in the dual norm of the x space.

        Boyd's dual residual for the order "xz" is rho ||A^T M (z^{k+1} - z^k)||.
        Plug-ins that cannot provide it leave this unimplemented; that residual
        is then NaN and policies that need it refuse to start.
        """
        raise NotImplementedError

    # -- starting point and diagnostics -------------------------------------
    def initial_point(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return (x0, z0, lam0); by default x0 = 0, z0 = A x0 - c, lam0 = 0."""
        x0 = np.zeros(self.n)
        Ax0 = self.apply_A(x0)
        z0 = Ax0 - self.c
        return x0, np.asarray(z0, dtype=float), np.zeros_like(Ax0, dtype=float)

    def objective(self, x: np.ndarray, z: np.ndarray) -> float | None:
        """f(x) + g(z) at a (feasible) point, or None if not provided."""
        return None

    def kkt(self, x: np.ndarray, z: np.ndarray, lam: np.ndarray) -> dict[str, float] | None:
        """KKT residuals of the original problem at (x, z, lam), or None."""
        return None

    def counters(self) -> dict[str, int]:
        """Work counters of the plug-in, e.g. {'factorizations': 3, 'solves': 120}."""
        return {}

    def finalize(self, x: np.ndarray) -> np.ndarray:
        """Map the iterate to the user's solution (identity by default).

        A condensed plug-in that iterates on a reduced representation recovers
        the full solution here, once, at the end of the run.
        """
        return x
