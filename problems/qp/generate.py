"""Random convex QPs of several shapes, for tests, demos and the agreement study: feasible ones, and primal
infeasible and unbounded (dual infeasible) ones with a known certificate."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .problem import QP

#: random_qp refuses sizes whose matrices would need more memory than this (bytes)
MEMORY_LIMIT = 8 * 2**30
KINDS = ("inequality", "equality", "mixed", "lp", "psd")


def random_qp(n: int = 30, m: int = 40, *, kind: str = "mixed", density: float = 0.3, seed: int = 0, **qp_options) -> QP:
    """A random convex QP that is feasible by construction and has a solution.

    ``kind``: "inequality" (two-sided rows), "equality" (some rows l = u),
    "mixed" (two-sided, one-sided, free and equality rows); for these
    P = G'G + 0.1 I is positive definite, so the solution is unique.
    "lp" (P = 0) and "psd" (P of rank about n/2) have the mixed rows and n
    more rows l_j <= x_j <= u_j, so that the problem is bounded (m + n rows).
    """
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")
    for name, v in (("n", n), ("m", m)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise ValueError(f"{name} must be an integer >= 1, got {v!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    need = 16.0 * (density * n * (n + m) + n * n)   # bytes of G, A and G'G (at most n^2 entries), 16 per entry
    if need > MEMORY_LIMIT:
        raise ValueError(f"random_qp({n}, {m}, density={density:g}) would need about {need / 2**30:.3g} GiB "
                         f"(more than {MEMORY_LIMIT / 2**30:.0f} GiB); give a smaller n, m or density")
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
    if kind != "inequality":
        eq = rng.random(m) < 0.2
        eq[: max(1, m // 10)] = True
        l[eq] = u[eq] = Ax[eq]
    if kind not in ("inequality", "equality"):
        roll = rng.random(m)
        l[(roll < 0.2) & ~eq] = -np.inf          # one-sided: upper only
        u[(roll > 0.8) & ~eq] = np.inf           # one-sided: lower only
        free = (roll > 0.45) & (roll < 0.55) & ~eq
        l[free], u[free] = -np.inf, np.inf      # free rows
    if kind in ("lp", "psd"):
        k = max(1, n // 2)
        H = sp.random(k, n, density=density, random_state=rng, data_rvs=rng.standard_normal)
        P = sp.csc_matrix((n, n)) if kind == "lp" else (H.T @ H).tocsc()
        A = sp.vstack([A, sp.identity(n)]).tocsc()
        l = np.r_[l, x_feasible - rng.uniform(0.5, 2.0, n)]
        u = np.r_[u, x_feasible + rng.uniform(0.5, 2.0, n)]
    return QP(P, q, A, l, u, name=f"random-{kind}-{n}x{m}-s{seed}", **qp_options)


def infeasible_qp(n: int = 20, m: int = 30, *, seed: int = 0, **qp_options) -> QP:
    """A primal infeasible QP: a random feasible one plus a row 2 a_i' x >= 2 u_i + 1 that contradicts a_i' x <= u_i.

    A certificate is y = e_i - e_new / 2 (A'y = 0, S(y) = u_i - (2 u_i + 1)/2 = -1/2 < 0).
    """
    base = random_qp(n, m, kind="inequality", seed=seed)
    rng = np.random.default_rng(seed + 7919)
    i = int(rng.integers(m))
    A = sp.vstack([base.A, 2.0 * base.A[i]]).tocsc()
    l = np.r_[base.l, 2.0 * base.u[i] + 1.0]
    u = np.r_[base.u, np.inf]
    return QP(base.P, base.q, A, l, u, name=f"infeasible-{n}x{m}-s{seed}", **qp_options)


def unbounded_qp(n: int = 20, m: int = 30, *, seed: int = 0, lp: bool = False, **qp_options) -> QP:
    """A dual infeasible (unbounded below) QP: x_n appears in no row, not in P, and q_n = 1.

    A certificate is dx = -e_n (P dx = 0, q'dx = -1 < 0, A dx = 0).
    """
    base = random_qp(n, m, kind="lp" if lp else "mixed", seed=seed)
    keep = np.ones(n)
    keep[-1] = 0.0
    K = sp.diags(keep)
    P = (K @ base.P @ K).tocsc()
    A = (base.A @ K).tocsc()
    if lp:                                            # drop the box row of x_n too (it is the identity row m + n - 1)
        rows = np.r_[np.arange(A.shape[0] - 1)]
        A, l, u = A[rows], base.l[rows], base.u[rows]
    else:
        l, u = base.l, base.u
    q = base.q.copy()
    q[-1] = 1.0
    return QP(P, q, A, l, u, name=f"unbounded-{'lp-' if lp else ''}{n}x{m}-s{seed}", **qp_options)
