"""Random feasible convex QPs of several shapes, for tests and demos."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .problem import QP

KINDS = ("inequality", "equality", "mixed")


def random_qp(n: int = 30, m: int = 40, *, kind: str = "mixed", density: float = 0.3, seed: int = 0, **qp_options) -> QP:
    """A random strictly convex QP that is feasible by construction.

    ``kind``: "inequality" (two-sided rows), "equality" (some rows l = u),
    "mixed" (two-sided, one-sided, free and equality rows).
    P = G'G + 0.1 I is positive definite, so the solution is unique.
    """
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")
    if n < 1 or m < 1:
        raise ValueError(f"n and m must be >= 1, got n={n}, m={m}")
    if not 0 < density <= 1:
        raise ValueError(f"density must be in (0, 1], got {density!r}")
    rng = np.random.default_rng(seed)
    G = sp.random(n, n, density=density, random_state=rng, data_rvs=rng.standard_normal)
    P = (G.T @ G + 0.1 * sp.identity(n)).tocsc()
    q = rng.standard_normal(n)
    A = sp.random(m, n, density=density, random_state=rng, data_rvs=rng.standard_normal).tocsc()
    x_feasible = rng.standard_normal(n)
    Ax = A @ x_feasible
    l = Ax - rng.uniform(0.1, 1.0, m)
    u = Ax + rng.uniform(0.1, 1.0, m)
    if kind in ("equality", "mixed"):
        eq = rng.random(m) < 0.2
        eq[: max(1, m // 10)] = True
        l[eq] = u[eq] = Ax[eq]
    if kind == "mixed":
        roll = rng.random(m)
        l[(roll < 0.2) & ~eq] = -np.inf          # one-sided: upper only
        u[(roll > 0.8) & ~eq] = np.inf           # one-sided: lower only
        free = (roll > 0.45) & (roll < 0.55) & ~eq
        l[free], u[free] = -np.inf, np.inf      # free rows
    return QP(P, q, A, l, u, name=f"random-{kind}-{n}x{m}-s{seed}", **qp_options)
