"""The gradient-recovery (ZZ) estimate of the obstacle's discretisation error.

Zienkiewicz & Zhu: G u_h, the recovered gradient (grad u_h averaged to a
continuous P1 vector field, at each vertex the area-weighted mean of the
gradients of the triangles around it), and eta_T = ||grad u_h - G u_h||_{L2(T)};
eta = (sum eta_T^2)^{1/2} estimates ``|u_h - u|_{H1}``.  It is the simple
baseline; it is not a guaranteed bound (the residual estimators of the
literature are: :mod:`admmkit.problems.obstacle.estimate_residual`), and
``tests/problems/test_obstacle_estimate.py`` measures its effectivity
``eta / |u_h - u|_{H1}`` on the radial obstacle, whose exact solution is known.
P2 problems bring their own (:class:`admmkit.problems.obstacle.p2.ZZ2`).
"""
from __future__ import annotations

import numpy as np


class ZZ:
    """The ZZ estimator of one mesh: the P1 gradient per triangle, recovered by area-weighted vertex averages.

    Built once per problem (the triangles, their areas and the gradient of each
    hat function); :meth:`indicators` is then a few array operations.
    ``eta_T^2 = int_T |g_T - G|^2`` with G linear on T is integrated exactly:
    ``|T|/12 (sum_i |w_i|^2 + |sum_i w_i|^2)``, ``w_i = g_T - G(vertex i)``.
    """

    def __init__(self, problem):
        self.problem = problem
        tri, area = problem.tri, problem.area                            # (elements, 3 vertices), areas
        p = problem.nodes[tri]
        e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]                     # the two edges
        det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
        # g_T = inv @ (u1 - u0, u2 - u0), inv = (e1; e2)^{-1} in closed form
        self._inv = np.stack([np.stack([e2[:, 1], -e1[:, 1]], axis=1),
                              np.stack([-e2[:, 0], e1[:, 0]], axis=1)], axis=1) / det[:, None, None]
        self.tri, self.area = tri, area
        self._last: tuple[np.ndarray, np.ndarray] | None = None
        self._weights = np.bincount(tri.ravel(), weights=np.repeat(area, 3), minlength=problem.nodes.shape[0])

    def gradients(self, u: np.ndarray) -> np.ndarray:
        """The P1 gradient on every triangle, (elements, 2) (u: values on the free nodes)."""
        full = self.problem.full_vector(u)[self.tri]                      # (elements, 3)
        return np.einsum("eij,ej->ei", self._inv, full[:, 1:] - full[:, :1])

    def energy(self, u: np.ndarray) -> float:
        """``|u_h|_{H1}``, the energy norm of the full field (boundary data included)."""
        return float(np.sqrt(np.sum(self.area * np.sum(self.gradients(u) ** 2, axis=1))))

    def indicators(self, u: np.ndarray) -> np.ndarray:
        """eta_T for every triangle (u: values on the free nodes); the last u's kept (the balanced stop's final
        estimate is the adaptive loop's marking)."""
        if self._last is not None and np.array_equal(self._last[0], u):
            return self._last[1].copy()
        g = self.gradients(u)
        G = np.stack([np.bincount(self.tri.ravel(), weights=np.repeat(self.area * g[:, k], 3),
                                  minlength=self._weights.size) for k in range(2)], axis=1)
        G /= self._weights[:, None]                                       # area-weighted vertex averages
        w = g[:, None, :] - G[self.tri]                                   # (elements, 3, 2)
        eta2 = self.area / 12 * (np.sum(w ** 2, axis=(1, 2)) + np.sum(w.sum(axis=1) ** 2, axis=1))
        self._last = (np.array(u, dtype=float), np.sqrt(eta2))
        return self._last[1].copy()


def zz(problem) -> ZZ:
    """The problem's ZZ estimator (built on first use, then kept on the problem)."""
    return _zz(problem)


def _zz(problem) -> ZZ:
    if getattr(problem, "_zz", None) is None:       # P2 problems bring their own (admmkit.problems.obstacle.p2)
        own = getattr(problem, "zz_estimator", None)
        problem._zz = own() if callable(own) else ZZ(problem)
    return problem._zz


def zz_indicators(problem, u: np.ndarray) -> np.ndarray:
    """eta_T = ||grad u_h - G u_h||_{L2(T)} for every element T (u: values on the free nodes)."""
    return _zz(problem).indicators(u)


def zz_estimate(problem, u: np.ndarray) -> float:
    """eta = (sum_T eta_T^2)^{1/2}: the ZZ estimate of the discretisation error ``|u_h - u|_{H1}``."""
    return float(np.sqrt(np.sum(zz_indicators(problem, u) ** 2)))


__all__ = ["ZZ", "zz", "zz_indicators", "zz_estimate"]
