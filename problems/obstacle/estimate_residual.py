"""A residual-type a posteriori error estimator for the obstacle problem (beside the ZZ estimate).

The discrete solution u_h (P1, nodal constraint s (u_h - psi) >= 0 at the
free nodes, s = +1 for a lower obstacle) has a **discrete contact force**,
the nodal residual of the equation where u_h touches the obstacle,

    r_i = a(u_h, phi_i) - (f, phi_i) = (K u_h - F)_i    (s r_i >= 0 on contact nodes, 0 elsewhere),

(the obstacle pushes: -Delta u = f + sigma with s sigma >= 0), and its density
sigma_h = sum_i (r_i / m_i) phi_i (m_i the lumped mass).  u_h is the Galerkin
approximation of the *linear* problem -Delta w = f + sigma_h (Braess 2005, "A posteriori error estimators for obstacle problems -
another look", Numer. Math. 101): the residual estimator of that equation,
plus the terms by which u_h fails the variational inequality, estimate the
error.  For every triangle T

    eta_T^2 =  h_T^2 ||f_h + sigma_h||_T^2                                  (element residual; Delta u_h = 0)
             + 1/2 sum_{E in T, E interior} h_E ||[d_n u_h]||_E^2            (normal-derivative jumps)
             + int_T (s sigma_h) (s (u_h - psi_h))^+                          (complementarity: force off the obstacle)
             + ||grad (s (psi_h - u_h))^+||_T^2                               (the obstacle above u_h between nodes)

and eta = (sum_T eta_T^2)^{1/2} estimates ``|u - u_h|_{H1}``.  h_T is the
diameter of T, h_E the length of E; f_h is f interpolated in P1 (as in the
load F), psi_h the obstacle interpolated in P2 (vertices and edge
midpoints), so that the last term sees the obstacle between the nodes,
where the P1 solution cuts below a curved obstacle.

Where the contact force balances f (the full-contact part) the element
residual is f_h + sigma_h instead of f: the restriction to the non-contact
part of Veeser (2001, SIAM J. Numer. Anal. 39) in the form of Braess's
auxiliary equation; there the last term measures the data oscillation of
the obstacle, which is the error of u_h = I_h psi.  The last two terms are
the contact terms of Braess and of Gudi & Porwal's reliable estimator; on
the radial obstacle (concave psi on the contact set) the complementarity term
lives on the triangles across the free boundary.  Not included: the
oscillation of f and of the Dirichlet data (higher order for smooth data).

Unlike ZZ, the estimator is reliable and efficient up to constants (which
are not computed: it is an estimate, with an effectivity index ``eta / |u
- u_h|_{H1}`` measured in ``tests/problems/test_obstacle_estimate_residual.py``
and by ``admmkit bench estimators``).

All integrals are NGSolve's: a linear form on the element-wise constants
(``L2(order=0)``) whose test function is the indicator of each triangle, with
``dx(skeleton=True)`` and ``Other()`` for the jumps.
"""
from __future__ import annotations

import ngsolve as ng
import numpy as np

from admmkit.problems.fe import facet_sizes


class ResidualEstimator:
    """The residual estimator of one obstacle problem (module docstring); the mesh data built once."""

    def __init__(self, problem):
        self.problem = p = problem
        mesh = p.mesh
        self.cells = ng.L2(mesh, order=0)
        tri = np.array([[v.nr for v in el.vertices] for el in mesh.Elements(ng.VOL)], dtype=np.int64)
        pts = p.nodes[tri]
        diam = np.max([np.linalg.norm(pts[:, i] - pts[:, j], axis=1) for i, j in ((0, 1), (1, 2), (0, 2))], axis=0)
        self.h_T = _cell_function(self.cells, diam)
        self.h_E = facet_sizes(mesh)
        x, y = p.nodes.T
        self.f_h = ng.GridFunction(p.fes)
        self.f_h.vec.FV().NumPy()[:] = p.scene.evaluate("f", x, y)
        self.psi_h = _p2_interpolant(mesh, lambda xx, yy: p.scene.evaluate("psi", xx, yy), p.nodes)
        self.sigma = ng.GridFunction(p.fes)
        self.open, self.touching = ng.GridFunction(self.cells), ng.GridFunction(self.cells)
        self._tri = tri
        self._touch = 1e-8 * max(1.0, float(np.max(np.abs(p.psi), initial=0.0)))

    def contact_force(self, u: np.ndarray) -> np.ndarray:
        """The nodal contact force r = K u - F on the free nodes where u touches the obstacle (sign-clipped), 0 elsewhere."""
        p = self.problem
        r = p.K @ u - p.F
        touching = p.sign * (u - p.psi) <= self._touch
        return np.where(touching, p.sign * np.maximum(p.sign * r, 0.0), 0.0)

    def cells_of(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(open, touching) per triangle: 1 where a vertex is off the obstacle (boundary vertices count as off),
        1 where a vertex touches it; 0 elsewhere."""
        p = self.problem
        off = np.ones(p.fes.ndof, dtype=bool)
        off[p.free] = p.sign * (u - p.psi) > self._touch
        off = off[self._tri]
        return off.any(axis=1).astype(float), (~off).any(axis=1).astype(float)

    def terms(self, u: np.ndarray) -> dict[str, np.ndarray]:
        """The four squared contributions per triangle (u: values on the free nodes): ``residual``, ``jump``,
        ``complementarity``, ``obstacle`` (module docstring)."""
        p = self.problem
        uh = p.gridfunction(u)
        density = np.zeros(p.fes.ndof)
        density[p.free] = self.contact_force(u) / p.m
        self.sigma.vec.FV().NumPy()[:] = density
        opened, touching = self.cells_of(u)
        self.open.vec.FV().NumPy()[:] = opened
        self.touching.vec.FV().NumPy()[:] = touching
        w, w2 = self.open, ng.IfPos(self.open + self.open.Other() - 0.5, 1, 0)
        q = self.cells.TestFunction()
        n = ng.specialcf.normal(2)
        grad = ng.grad(uh)
        s = p.sign
        forms = {
            "residual": self.h_T ** 2 * (self.f_h + self.sigma) ** 2 * w * q * ng.dx(bonus_intorder=2),
            "jump": 0.5 * w2 * self.h_E * ((grad - grad.Other()) * n) ** 2 * (q + q.Other()) * ng.dx(skeleton=True),
            "complementarity": s * self.sigma * ng.IfPos(s * (uh - self.psi_h), s * (uh - self.psi_h), 0)
            * q * ng.dx(bonus_intorder=4),
            "obstacle": self.touching * ng.IfPos(s * (self.psi_h - uh), 1, 0) * ng.InnerProduct(ng.grad(self.psi_h) - grad,
                                                                                ng.grad(self.psi_h) - grad)
            * q * ng.dx(bonus_intorder=4),
        }
        out = {}
        for name, form in forms.items():
            lf = ng.LinearForm(self.cells)
            lf += form
            lf.Assemble()
            out[name] = np.maximum(lf.vec.FV().NumPy().copy(), 0.0)
        return out

    def indicators(self, u: np.ndarray) -> np.ndarray:
        """eta_T for every triangle (u: values on the free nodes)."""
        return np.sqrt(sum(self.terms(u).values()))


def _cell_function(space, values: np.ndarray) -> ng.GridFunction:
    """A piecewise constant function with one value per element (L2 order 0: dof i is element i)."""
    gf = ng.GridFunction(space)
    gf.vec.FV().NumPy()[:] = values
    return gf


def _p2_interpolant(mesh: ng.Mesh, g, nodes: np.ndarray) -> ng.GridFunction:
    """The P2 interpolant of a vectorised g(x, y) (values at the vertices and edge midpoints).

    NGSolve's P2 basis is hierarchical: a vertex hat per vertex and a bubble per
    edge, so the edge coefficient is (g(mid) - (g_a + g_b)/2) / b(mid) with b(mid)
    the bubble's value at the midpoint, measured on the first edge.
    """
    space = ng.H1(mesh, order=2)
    ends, edge_dofs = [], []
    for e in mesh.edges:          # after a refinement the parents of bisected edges remain, without a dof
        dofs = space.GetDofNrs(e)
        if dofs:
            ends.append([v.nr for v in e.vertices])
            edge_dofs.append(dofs[0])
    ends, edge_dofs = np.array(ends, dtype=np.int64), np.array(edge_dofs, dtype=np.int64)
    gf = ng.GridFunction(space)
    vec = gf.vec.FV().NumPy()
    vec[edge_dofs[0]] = 1.0
    bubble = gf(mesh(*((nodes[ends[0, 0]] + nodes[ends[0, 1]]) / 2)))
    vec[:] = 0.0
    at_vertices = g(nodes[:, 0], nodes[:, 1])
    mid = (nodes[ends[:, 0]] + nodes[ends[:, 1]]) / 2
    vec[:nodes.shape[0]] = at_vertices
    vec[edge_dofs] = (g(mid[:, 0], mid[:, 1]) - at_vertices[ends].mean(axis=1)) / bubble
    return gf


def residual_estimator(problem) -> ResidualEstimator:
    """The problem's residual estimator (built on first use, then kept on the problem)."""
    if getattr(problem, "_residual", None) is None:
        problem._residual = ResidualEstimator(problem)
    return problem._residual


def residual_indicators(problem, u: np.ndarray) -> np.ndarray:
    """eta_T of the residual estimator for every triangle (u: values on the free nodes)."""
    return residual_estimator(problem).indicators(u)


def residual_estimate(problem, u: np.ndarray) -> float:
    """eta = (sum_T eta_T^2)^{1/2}: the residual estimate of the discretisation error ``|u_h - u|_{H1}``."""
    return float(np.sqrt(np.sum(residual_indicators(problem, u) ** 2)))


#: the estimators by name (``--estimator``, ``estimator=``)
ESTIMATORS = ("zz", "residual")


def check_estimator(name) -> str:
    """The estimator's name, or ValueError naming the accepted ones."""
    if name not in ESTIMATORS:
        raise ValueError(f"estimator = {name!r} is unknown; accepted: {', '.join(ESTIMATORS)}")
    return name


__all__ = ["ESTIMATORS", "check_estimator", "ResidualEstimator", "residual_estimator", "residual_indicators", "residual_estimate"]
