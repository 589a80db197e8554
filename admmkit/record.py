"""The read-only record of one ADMM iteration, as policies and stopping rules see it."""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Callable

import numpy as np


@dataclass(frozen=True, slots=True)
class IterationRecord:
    """What happened in iteration k (which produced x^{k+1}, z^{k+1}, lam^{k+1}).

    All norms are those of the problem: ||.||_M on the constraint space,
    ||.||_X on x.  With r = A x^{k+1} - z^{k+1} - c:

    - ``primal_residual``  ||r||_M
    - ``dual_residual``    Boyd's dual residual: rho ||A^T M (z^{k+1} - z^k)||
      for order "xz"; rho ||A (x^{k+1} - x^k)||_M for order "zx" (where x is
      the second block; this is the denominator of the paper's w_k)
    - ``rho_Ax_change``    rho ||A x^{k+1} - A x^k||_M (the paper's w_k denominator)
    - ``lam_change``       ||lam^{k+1} - lam^k||_M = rho ||r||_M (w_k numerator)
    - ``x_change``, ``x_norm``  ||x^{k+1} - x^k||_X and ||x^{k+1}||_X
    - ``primal_scale``     max(||A x||_M, ||z||_M, ||c||_M)  (Boyd 3.3.1)
    - ``dual_scale``       ||A^T M lam|| ("xz") or ||lam||_M ("zx")
    - ``primal_unit``, ``dual_unit``  the norms of the all-ones vector of the
      spaces the residuals live in (Boyd's sqrt(p), sqrt(n))

    The vectors are read-only views of the new iterates; ``z_prev`` and
    ``Ax_prev`` are those of the previous iterate (z^k, A x^k) and ``inner``
    is the problem's (., .)_M (None: Euclidean, for hand-made records).
    From them the record gives the multiplier of each block's optimality
    condition (``lam_x``, ``lam_z``), which spectral rules need.
    """

    k: int
    rho: float
    order: str
    primal_residual: float
    dual_residual: float
    rho_Ax_change: float
    lam_change: float
    x_change: float
    x_norm: float
    z_change: float
    primal_scale: float
    dual_scale: float
    primal_unit: float
    dual_unit: float
    time: float
    x: np.ndarray
    z: np.ndarray
    lam: np.ndarray
    Ax: np.ndarray
    z_prev: np.ndarray | None = None
    Ax_prev: np.ndarray | None = None
    inner: Callable[[np.ndarray, np.ndarray], float] | None = None

    def dot(self, a: np.ndarray, b: np.ndarray) -> float:
        """(a, b)_M, the problem's inner product of the constraint space (Euclidean if not given)."""
        return float(np.dot(a, b)) if self.inner is None else float(self.inner(a, b))

    @property
    def lam_x(self) -> np.ndarray:
        """The multiplier of the x-step's optimality condition: -A^T M lam_x in the subdifferential of f at x^{k+1}.

        Order "zx" (x-step last): lam^{k+1}.  Order "xz": the x-step used z^k, so
        lam_x = lam^k + rho (A x^{k+1} - z^k - c) = lam^{k+1} + rho (z^{k+1} - z^k)
        (Xu, Figueiredo & Goldstein 2017's "hat" multiplier).  Needs ``z_prev``.
        """
        if self.order == "zx":
            return self.lam
        if self.z_prev is None:
            raise ValueError("lam_x of an order 'xz' record needs z_prev (the previous z)")
        return self.lam + self.rho * (self.z - self.z_prev)

    @property
    def lam_z(self) -> np.ndarray:
        """The multiplier of the z-step's optimality condition: M lam_z in the subdifferential of g at z^{k+1}.

        Order "xz" (z-step last): lam^{k+1}.  Order "zx": the z-step used A x^k, so
        lam_z = lam^k + rho (A x^k - z^{k+1} - c) = lam^{k+1} - rho (A x^{k+1} - A x^k).
        Needs ``Ax_prev``.
        """
        if self.order == "xz":
            return self.lam
        if self.Ax_prev is None:
            raise ValueError("lam_z of an order 'zx' record needs Ax_prev (the previous A x)")
        return self.lam - self.rho * (self.Ax - self.Ax_prev)

    @property
    def rel_change(self) -> float:
        """||x^{k+1} - x^k||_X / ||x^{k+1}||_X (inf when x^{k+1} = 0 and x moved)."""
        if self.x_norm > 0:
            return self.x_change / self.x_norm
        return 0.0 if self.x_change == 0 else float("inf")

    @property
    def primal_residual_rel(self) -> float:
        """Primal residual normalised by ``primal_scale``."""
        return _ratio(self.primal_residual, self.primal_scale)

    @property
    def dual_residual_rel(self) -> float:
        """Dual residual normalised by ``dual_scale``."""
        return _ratio(self.dual_residual, self.dual_scale)


def _ratio(a: float, b: float) -> float:
    if b > 0:
        return a / b
    return 0.0 if a == 0 else float("inf")


#: the scalar fields of a record that the history keeps
SCALAR_FIELDS = tuple(f.name for f in fields(IterationRecord) if f.type in ("int", "float"))
