"""The read-only record of one ADMM iteration, as policies and stopping rules see it."""
from __future__ import annotations

from dataclasses import dataclass, fields

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

    The vectors are read-only views of the new iterates.
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
