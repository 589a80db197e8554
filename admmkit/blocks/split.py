"""A problem assembled from building blocks: a quadratic f, a prox-friendly g and the map A.

    minimise 1/2 x'Px + q'x + g(z)   subject to   A x - z = c,   (., .)_M on the constraint space

    x_step = admmkit.QuadraticXStep(P, q, A, M=m)      # the solve of (P + rho A'MA) x = ..., cached per rho
    problem = admmkit.SplitProblem(x_step, admmkit.blocks.prox.L1(0.1))
    result = admmkit.solve(problem, policy="summable", order="zx")

:class:`SplitProblem` derives everything else from the blocks: the z-step
z = prox_{g, 1/rho}^M(A x - c + lam/rho), apply_A, the inner product,
adjoint_norm (so Boyd's dual residual works in order "xz"), the objective,
the counters and relative KKT measures (``kkt_relative``), which
:func:`admmkit.solve` compares with the stopping rule's tolerance.
"""
from __future__ import annotations

import math

import numpy as np

from ..problem import Problem
from .prox import Prox
from .xstep import QuadraticXStep


class SplitProblem(Problem):
    """f (a :class:`admmkit.QuadraticXStep`, which carries A and M) + g (an ``admmkit.blocks.prox`` operator), A x - z = c."""

    def __init__(self, x_step: QuadraticXStep, g: Prox, *, c=0.0):
        if not isinstance(x_step, QuadraticXStep):
            raise TypeError(f"x_step must be an admmkit.QuadraticXStep, got {type(x_step).__name__}")
        if not isinstance(g, Prox):
            raise TypeError(f"g must be an admmkit.blocks.prox.Prox (or prox.PyProximal(op)), got {type(g).__name__}")
        self.f, self.g, self.map = x_step, g, x_step.A
        self.n, self.m = x_step.n, x_step.A.m
        c = np.asarray(c, dtype=float)
        if c.ndim and c.shape != (self.map.p,):
            raise ValueError(f"c must be a number or an array of shape ({self.map.p},), got {c.shape}")
        self.c = float(c) if c.ndim == 0 else c
        g.check(self.m)

    # -- the splitting
    def x_step(self, z, lam, rho, x):
        """The quadratic x-step (eq. (12))."""
        return self.f(z, lam, rho, x, self.c)

    def update_rho(self, rho):
        """The event of a change of rho: the x-step's refresh (:meth:`admmkit.QuadraticXStep.update_rho`)."""
        self.f.update_rho(rho)

    def z_step(self, Ax, lam, rho, z):
        """prox_{g, 1/rho}^M (A x - c + lam / rho) (eq. (11))."""
        v = (Ax if np.isscalar(self.c) and self.c == 0 else Ax - self.c) + lam / rho
        return self.g.prox(v, 1.0 / rho, self.m)

    def segment(self, x, z, lam, Ax, rho, alpha, order, count):
        """``count`` iterations in one compiled call (:mod:`admmkit.loop.segments`), or None where a block has no kernel
        (:mod:`admmkit.blocks.split_segment` lists the covered ones)."""
        from .split_segment import run_segment
        return run_segment(self, x, z, lam, Ax, rho, alpha, order, count)

    def apply_A(self, x):
        """A x."""
        return self.map.apply(x)

    def inner(self, a, b):
        """(a, b)_M."""
        return self.map.inner(a, b)

    def norm(self, y):
        """||y||_M."""
        return self.map.norm(y)

    def adjoint_norm(self, y):
        """||A'M y|| in the dual of the x norm (derived from A)."""
        return self.map.adjoint_norm(y)

    def x_norm(self, x):
        """||x||_W, the x norm whose dual ``adjoint_norm`` uses (Euclidean unless the LinearMap has x_weights)."""
        return self.map.x_norm(x)

    # -- diagnostics
    def objective(self, x, z):
        """f(x) + g(z) at the ADMM iterate."""
        return self.f.f(x) + self.g.value(z)

    def kkt_relative(self, x, z, lam) -> dict[str, float]:
        """Relative residuals of the three optimality conditions (OSQP-style normalisation).

        primal: ||Ax - z - c||_M / max(||Ax||_M, ||z||_M, ||c||_M);
        dual:   ||Px + q + A'M lam|| / max(||Px||, ||q||, ||A'M lam||);
        z:      ||z - prox_g^M(z + lam)||_M / max(||z||_M, ||lam||_M)  (M lam in the subdifferential of g at z).
        Each denominator is floored at 1e-30 (0/0 counts as 0).
        """
        A, c = self.map, self.c
        Ax = A.apply(x)
        r = Ax - z - c
        Px = np.zeros(self.n) if self.f.P is None else self.f.P @ x
        AtMlam = A.adjoint_M(lam)
        zfix = z - self.g.prox(z + lam, 1.0, self.m)
        c_norm = A.norm(np.broadcast_to(np.asarray(c, dtype=float), z.shape))
        return {
            "primal": _rel(A.norm(r), A.norm(Ax), A.norm(z), c_norm),
            "dual": _rel(float(np.linalg.norm(Px + self.f.q + AtMlam)), float(np.linalg.norm(Px)),
                         float(np.linalg.norm(self.f.q)), float(np.linalg.norm(AtMlam))),
            "z_optimality": _rel(A.norm(zfix), A.norm(z), A.norm(lam)),
        }

    def kkt(self, x, z, lam):
        """The relative KKT residuals (:meth:`kkt_relative`)."""
        return self.kkt_relative(x, z, lam)

    def begin_run(self):
        """Reset the x-step's per-run counters (called by admmkit.solve)."""
        self.f.begin_run()

    def counters(self):
        """The x-step's work in this run: solves, factorisations, CG iterations."""
        return self.f.counters()

    def __repr__(self) -> str:
        return f"SplitProblem(f={self.f!r}, g={self.g!r})"


def _rel(value: float, *scales: float) -> float:
    scale = max(scales)
    if scale > 1e-30:
        return value / scale
    return 0.0 if value == 0 else math.inf
