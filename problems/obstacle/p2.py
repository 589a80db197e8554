"""P2 elements for the obstacle plug-in, in nodal values, so that the constraint stays a box.

NGSolve's order-2 H1 basis is hierarchical: a vertex coefficient is the
function's value there, an edge coefficient scales a bubble that vanishes at
the vertices.  The obstacle is imposed at the P2 Lagrange nodes (the vertices
and the edge midpoints), where a function with coefficients c has the values

    v_vertex = c_vertex,      v_e = (c_a + c_b) / 2 + beta c_e,      v = T c,

beta the bubble's value at the midpoint of its edge e = (a, b).  In the nodal
values v the discrete problem has the P1 plug-in's form,

    min 1/2 v'K_v v - F_v'v   subject to   v >= psi at the nodes,
    K_v = T^-T K T^-1,   F_v = T^-T F,

so :class:`ObstacleProblemP2` inherits the splitting of
:class:`admmkit.problems.obstacle.problem.ObstacleProblem` (the x-step with K_v,
the z-step a projection, the duality-gap bound of the balanced stop) with M the
HRZ-lumped P2 mass: the diagonal of the consistent mass scaled to the same
total (row sums vanish at P2 vertices, so row-sum lumping is no inner
product).  The consistent mass is at least :data:`MASS_RATIO` times it, which
the guaranteed algebraic bound (``EnergyGap``) needs.
"""
from __future__ import annotations

import math

import ngsolve as ng
import numpy as np
import scipy.sparse as sp

from .problem import ObstacleProblem, csr_of


def _mass_ratio() -> float:
    """The largest kappa with M >= kappa diag(M)/s on every triangle (s = sum diag / sum M: HRZ lumping).

    The P2 element mass on a triangle of area ``A`` is ``A/180`` times the matrix below (vertices, then the
    edges opposite them); the ratio is affine-invariant, so one eigenvalue problem gives it.
    """
    M = np.array([[6, -1, -1, -4, 0, 0], [-1, 6, -1, 0, -4, 0], [-1, -1, 6, 0, 0, -4],
                  [-4, 0, 0, 32, 16, 16], [0, -4, 0, 16, 32, 16], [0, 0, -4, 16, 16, 32]], dtype=float)
    lumped = np.diag(M) * M.sum() / np.diag(M).sum()
    scale = 1.0 / np.sqrt(lumped)
    return float(np.linalg.eigvalsh(scale[:, None] * M * scale[None, :]).min())


#: consistent P2 mass >= MASS_RATIO x the HRZ-lumped one (element by element)
MASS_RATIO = _mass_ratio()


def edge_vertices(mesh: ng.Mesh, fes: ng.comp.FESpace) -> np.ndarray:
    """(edge dofs, 2): the two vertices of the edge of every P2 edge dof (dofs nv, nv+1, ...).

    From one mixed mass matrix against the P1 hats, vectorised: a bubble c l_a l_b integrates against
    the hats of its own vertices at least twice as strongly as against the two opposite ones
    (``int_T l_a^2 l_b = area(T)/30``, ``int_T l_a l_b l_c = area(T)/60``), so the two largest entries of
    its row name its edge.
    """
    p1 = ng.H1(mesh, order=1)
    form = ng.BilinearForm(trialspace=p1, testspace=fes)
    form += p1.TrialFunction() * fes.TestFunction() * ng.dx
    B = csr_of(form.Assemble().mat)[mesh.nv:].tocoo()
    order = np.lexsort((-np.abs(B.data), B.row))                   # by row, the largest entries first
    rows, cols = B.row[order], B.col[order]
    first = np.searchsorted(rows, np.arange(B.shape[0]))
    return np.sort(np.stack([cols[first], cols[first + 1]], axis=1), axis=1)


class ObstacleProblemP2(ObstacleProblem):
    """The obstacle problem of a :class:`admmkit.problems.obstacle.Scene` in P2 elements, unknowns the nodal values
    (module docstring).

    The attributes of :class:`ObstacleProblem`, with ``nodes`` the points of all P2 nodes (vertices first,
    then the edge midpoints in NGSolve's dof order), ``m`` the HRZ-lumped mass and ``mass_ratio`` its
    bound; ``T`` maps hierarchical coefficients to nodal values (all dofs).
    """

    order = 2
    mass_ratio = MASS_RATIO

    def _node_points(self) -> np.ndarray:
        """The vertices, then the midpoints of the edges in dof order; ``T`` and its inverse built on the way."""
        mesh, nv = self.mesh, self.mesh.nv
        vertices = np.array(mesh.ngmesh.Coordinates())[:, :2]
        edges = edge_vertices(mesh, self.fes)
        self.T, self._T_inverse = _transforms(nv, edges, _bubble_at_midpoint(self.fes, vertices, edges, nv))
        return np.concatenate([vertices, vertices[edges].mean(axis=1)])

    def _forms(self):
        """(K_v on all nodes, f -> M_v f with the consistent mass, the HRZ-lumped mass on all nodes)."""
        u, v = self.fes.TnT()
        Ti = self._T_inverse
        K = (Ti.T @ csr_of(ng.BilinearForm(ng.grad(u) * ng.grad(v) * ng.dx).Assemble().mat) @ Ti).tocsr()
        M = (Ti.T @ csr_of(ng.BilinearForm(u * v * ng.dx).Assemble().mat) @ Ti).tocsr()
        lumped = M.diagonal() * (self.area.sum() / M.diagonal().sum())
        return K, M.__matmul__, lumped

    def gridfunction(self, u: np.ndarray) -> ng.GridFunction:
        """The P2 function with nodal values u on the free nodes and u_D on the boundary nodes."""
        gf = ng.GridFunction(self.fes)
        gf.vec.FV().NumPy()[:] = self._T_inverse @ self.full_vector(u)
        return gf

    def zz_estimator(self):
        """The ZZ estimator of P2 functions (:class:`admmkit.problems.obstacle.p2.ZZ2`)."""
        return ZZ2(self)


class ZZ2:
    """ZZ for P2: grad u_h recovered in continuous vector P2 (NGSolve's ``Set``: element-wise L2 projection,
    averaged at shared dofs), eta_T = ||grad u_h - G u_h||_{L2(T)} integrated by NGSolve element by element."""

    def __init__(self, problem: ObstacleProblemP2):
        self.problem, self.tri = problem, problem.tri                     # tri: the triangles' vertices, for plots
        self._G = ng.GridFunction(ng.VectorH1(problem.mesh, order=2))
        self._last: tuple[np.ndarray, np.ndarray] | None = None

    def energy(self, u: np.ndarray) -> float:
        """``|u_h|_{H1}`` of the full field (boundary data included)."""
        g = ng.grad(self.problem.gridfunction(u))
        return math.sqrt(max(ng.Integrate(ng.InnerProduct(g, g) * ng.dx, self.problem.mesh), 0.0))

    def indicators(self, u: np.ndarray) -> np.ndarray:
        """eta_T for every triangle (u: nodal values on the free nodes); the last u's kept."""
        if self._last is not None and np.array_equal(self._last[0], u):
            return self._last[1].copy()
        g = ng.grad(self.problem.gridfunction(u))
        self._G.Set(g)
        d = g - self._G
        eta2 = ng.Integrate(ng.InnerProduct(d, d) * ng.dx, self.problem.mesh, element_wise=True)
        self._last = (np.array(u, dtype=float), np.sqrt(np.maximum(eta2.NumPy(), 0.0)))
        return self._last[1].copy()


def _bubble_at_midpoint(fes, vertices: np.ndarray, edges: np.ndarray, nv: int) -> float:
    """beta, the edge bubble's value at its edge's midpoint, read off the interpolant of x^2 (exact in P2):
    x_m^2 - (x_a^2 + x_b^2)/2 = -(x_a - x_b)^2 / 4 = beta c_e on an edge with x_a != x_b."""
    gf = ng.GridFunction(fes)
    gf.Set(ng.x * ng.x)
    c = gf.vec.FV().NumPy()[nv:]
    dx = vertices[edges[:, 0], 0] - vertices[edges[:, 1], 0]
    k = int(np.argmax(np.abs(dx)))
    return float(-dx[k] ** 2 / 4 / c[k])


def _transforms(nv: int, edges: np.ndarray, beta: float) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """T (coefficients -> nodal values) and its inverse, both sparse (module docstring)."""
    ne = edges.shape[0]
    e = nv + np.arange(ne)
    rows = np.concatenate([np.arange(nv), e, e, e])
    half = np.full(ne, 0.5)
    T = sp.csr_matrix((np.concatenate([np.ones(nv), half, half, np.full(ne, beta)]),
                       (rows, np.concatenate([np.arange(nv), edges[:, 0], edges[:, 1], e]))), shape=(nv + ne,) * 2)
    inverse = sp.csr_matrix((np.concatenate([np.ones(nv), -half / beta, -half / beta, np.full(ne, 1 / beta)]),
                             (rows, np.concatenate([np.arange(nv), edges[:, 0], edges[:, 1], e]))),
                            shape=(nv + ne,) * 2)
    return T, inverse


def prolongation(problem: ObstacleProblemP2, u: np.ndarray, lam: np.ndarray):
    """A function that gives u and lam (full nodal vectors) at the nodes of a problem built on a refinement of
    this problem's mesh, by evaluating this level's P2 fields there (exact for u: the meshes are nested).

    The fields are evaluated on ``problem.mesh`` itself, so the caller refines a copy of it
    (``admmkit.problems.fe.refined_copy``), never the mesh in place.  Evaluating on a copy of the mesh
    scrambled the edge values: NGSolve numbers a copy's edges anew (a refined mesh keeps its bisected
    parents' edges, a copy does not), so this level's coefficients were put on other edges.
    """
    fields = [ng.GridFunction(problem.fes) for _ in range(2)]
    for gf, values in zip(fields, (problem.full_vector(u), problem.full_multiplier(lam))):
        gf.vec.FV().NumPy()[:] = problem._T_inverse @ values
    mesh = problem.mesh

    def at(new_problem: ObstacleProblemP2) -> dict:
        points = mesh(new_problem.nodes[:, 0], new_problem.nodes[:, 1])
        return {key: np.asarray(gf(points)).ravel() for key, gf in zip(("x0", "lam0"), fields)}
    return at


__all__ = ["ObstacleProblemP2", "ZZ2", "MASS_RATIO", "edge_vertices", "prolongation"]
