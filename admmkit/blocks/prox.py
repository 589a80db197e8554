"""Proximal operators for z-steps, in the weighted metric of the constraint space.

The z-step of ADMM is a proximal operator: with v = A x - c + lam/rho,

    z^{k+1} = argmin_z g(z) + rho/2 ||z - v||_M^2 = prox_{g, t}^M(v),   t = 1/rho.

Each operator here implements ``prox(v, t, m)`` = argmin_z g(z) + 1/(2t) ||z - v||_M^2
with M = diag(m) (m None: the identity), and ``value(z)`` = g(z) (inf outside
a constraint set).  The M-weighted form is exact where g is separable
(Box, NonNegative, UpperBound, L1, Zero), where the metric is uniform on
each group (GroupL1, L2Ball with a uniform m) or where g is defined in the M
norm itself (L2Ball(in_M_norm=True)); anything else is refused with a
ValueError rather than solved approximately.  :class:`PyProximal` adapts any
operator of the pyproximal library (Euclidean; uniform m only).
"""
from __future__ import annotations

import numpy as np


def _uniform(m, what: str):
    """The single value of a uniform weight vector (1 for None); ValueError otherwise."""
    if m is None:
        return 1.0
    m = np.asarray(m, dtype=float)
    if m.size and np.all(m == m.flat[0]):
        return float(m.flat[0])
    raise ValueError(f"{what} has no closed-form prox in a non-uniform metric M; use a uniform M, "
                     "an operator defined in the M norm, or your own z_step")


class Prox:
    """Base class: a convex g with its proximal operator in the metric M."""

    def prox(self, v: np.ndarray, t: float, m: np.ndarray | None = None) -> np.ndarray:
        """argmin_z g(z) + 1/(2t) ||z - v||_M^2 (a new array)."""
        raise NotImplementedError

    def value(self, z: np.ndarray) -> float:
        """g(z) (inf outside the set of an indicator, up to a 1e-9 relative tolerance)."""
        raise NotImplementedError

    def check(self, m: np.ndarray | None) -> None:
        """Raise ValueError now if the prox is not exact in the metric diag(m) (called by SplitProblem)."""

    def __repr__(self) -> str:
        return type(self).__name__


class Zero(Prox):
    """g = 0: prox is the identity."""

    def prox(self, v, t, m=None):
        """v (copied)."""
        return np.array(v, dtype=float)

    def value(self, z):
        """0."""
        return 0.0


def _indicator(ok: bool) -> float:
    return 0.0 if ok else float("inf")


class Box(Prox):
    """Indicator of {lower <= z <= upper} (bounds may be +-inf): prox = clip, in any diagonal M."""

    def __init__(self, lower=-np.inf, upper=np.inf):
        self.lower, self.upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
        if np.any(self.lower > self.upper):
            raise ValueError("Box needs lower <= upper everywhere")

    def prox(self, v, t, m=None):
        """clip(v, lower, upper)."""
        return np.minimum(np.maximum(v, self.lower), self.upper)

    def value(self, z):
        """0 inside the box, inf outside."""
        tol = 1e-9 * (1 + np.abs(z))
        return _indicator(bool(np.all(z >= self.lower - tol) and np.all(z <= self.upper + tol)))


class NonNegative(Box):
    """Indicator of the nonnegative orthant {z >= 0}."""

    def __init__(self):
        super().__init__(0.0, np.inf)

    def prox(self, v, t, m=None):
        """max(v, 0)."""
        return np.maximum(v, 0.0)


class UpperBound(Box):
    """Indicator of {z <= g} (the paper's contact set): prox = min(v, g)."""

    def __init__(self, g):
        super().__init__(-np.inf, g)

    def prox(self, v, t, m=None):
        """min(v, g)."""
        return np.minimum(v, self.upper)


class L1(Prox):
    """g = sum_i w_i abs(z_i) (w a number or an array >= 0): soft-thresholding at t w_i / m_i."""

    def __init__(self, weight=1.0):
        self.weight = np.asarray(weight, dtype=float)
        if np.any(self.weight < 0) or not np.all(np.isfinite(self.weight)):
            raise ValueError("L1 weight must be finite and >= 0")

    def prox(self, v, t, m=None):
        """sign(v) max(abs(v) - t w / m, 0)."""
        thresh = t * self.weight if m is None else t * self.weight / m
        return np.sign(v) * np.maximum(np.abs(v) - thresh, 0.0)

    def value(self, z):
        """sum w abs(z)."""
        return float(np.sum(self.weight * np.abs(z)))


class GroupL1(Prox):
    """g = w sum_G ||z_G||_2 over the groups G (a list of index arrays partitioning some of the entries).

    Block soft-thresholding; exact when m is uniform on each group.
    """

    def __init__(self, groups, weight: float = 1.0):
        self.groups = [np.asarray(g, dtype=int) for g in groups]
        self.weight = float(weight)
        if self.weight < 0:
            raise ValueError("GroupL1 weight must be >= 0")

    def check(self, m):
        """Refuse a metric that is not uniform on every group."""
        if m is not None:
            for g in self.groups:
                _uniform(m[g], "GroupL1 with M not uniform on a group")

    def prox(self, v, t, m=None):
        """z_G = max(1 - t w / (m_G ||v_G||), 0) v_G on each group; other entries unchanged."""
        z = np.array(v, dtype=float)
        for g in self.groups:
            mg = 1.0 if m is None else _uniform(m[g], "GroupL1 with M not uniform on a group")
            norm = np.linalg.norm(v[g])
            z[g] = 0.0 if norm == 0 else max(1.0 - t * self.weight / (mg * norm), 0.0) * v[g]
        return z

    def value(self, z):
        """w sum ||z_G||."""
        return self.weight * float(sum(np.linalg.norm(z[g]) for g in self.groups))


class L2Ball(Prox):
    """Indicator of {||z - center|| <= radius}, the norm Euclidean or (``in_M_norm``) the M norm: radial projection."""

    def __init__(self, radius: float, center=0.0, *, in_M_norm: bool = False):
        self.radius, self.center, self.in_M_norm = float(radius), np.asarray(center, dtype=float), bool(in_M_norm)
        if not self.radius >= 0:
            raise ValueError("L2Ball radius must be >= 0")
        self._m = None

    def check(self, m):
        """A Euclidean ball needs a uniform M (else the M-projection has no closed form)."""
        self._m = m
        if not self.in_M_norm:
            _uniform(m, "L2Ball (a Euclidean ball)")

    def _norm(self, d, m):
        if self.in_M_norm and m is not None:
            return float(np.sqrt(np.dot(d, m * d)))
        return float(np.linalg.norm(d))

    def prox(self, v, t, m=None):
        """center + d min(1, radius / ||d||) with d = v - center."""
        if not self.in_M_norm:
            _uniform(m, "L2Ball (a Euclidean ball)")
        d = v - self.center
        norm = self._norm(d, m)
        return self.center + (d if norm <= self.radius else d * (self.radius / norm))

    def value(self, z):
        """0 inside the ball, inf outside (M norm: the metric of the last prox)."""
        return _indicator(self._norm(z - self.center, None if not self.in_M_norm else self._m)
                          <= self.radius * (1 + 1e-9))


class Consensus(Prox):
    """Indicator of {z_1 = ... = z_B} for z = (z_1, ..., z_B) stacked in B equal blocks: the M-weighted block average."""

    def __init__(self, blocks: int):
        if isinstance(blocks, bool) or not isinstance(blocks, int) or blocks < 1:
            raise ValueError(f"blocks must be an integer >= 1, got {blocks!r}")
        self.blocks = blocks

    def prox(self, v, t, m=None):
        """Every block replaced by the average of the blocks (weighted by m entrywise)."""
        V = np.reshape(v, (self.blocks, -1))
        if m is None:
            avg = V.mean(axis=0)
        else:
            W = np.reshape(m, (self.blocks, -1))
            avg = (W * V).sum(axis=0) / W.sum(axis=0)
        return np.tile(avg, self.blocks)

    def value(self, z):
        """0 if the blocks agree (to 1e-9 relative), inf otherwise."""
        Z = np.reshape(z, (self.blocks, -1))
        return _indicator(bool(np.all(np.abs(Z - Z[0]) <= 1e-9 * (1 + np.abs(Z[0])))))


class PyProximal(Prox):
    """Any pyproximal operator (``pip install pyproximal``): prox(v, t, m) = op.prox(v, t / m) for a uniform m.

    pyproximal's ``op.prox(x, tau)`` is argmin_z f(z) + 1/(2 tau) ||z - x||^2; in
    the metric M = m I that is tau = t / m.  A non-uniform M is refused.
    """

    def __init__(self, op):
        if not (hasattr(op, "prox") and callable(op.prox)):
            raise TypeError(f"op must be a pyproximal operator (with a prox(x, tau) method), got {type(op).__name__}")
        self.op = op

    def check(self, m):
        """pyproximal's operators are Euclidean: only a uniform M is exact."""
        _uniform(m, f"pyproximal operator {type(self.op).__name__}")

    def prox(self, v, t, m=None):
        """op.prox(v, t / m)."""
        scale = _uniform(m, f"pyproximal operator {type(self.op).__name__}")
        return np.asarray(self.op.prox(np.asarray(v, dtype=float), t / scale), dtype=float)

    def value(self, z):
        """op(z)."""
        return float(self.op(z))

    def __repr__(self) -> str:
        return f"PyProximal({type(self.op).__name__})"
