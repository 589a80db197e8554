"""The discrete contact problem's operators: what :func:`admmkit.problems.contact.model.assembly.assemble` returns.

This module imports no NGSolve (the type names below are strings): a solve
from operators read back from the operator cache
(:mod:`admmkit.problems.contact.model.operator_cache`) runs without it, and
only what needs the mesh (a plot, a VTU, the P2 dof coordinates) imports
NGSolve, when it is asked for.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.sparse as sp

from admmkit.problems.contact.model.scene import Scene
from admmkit.problems.contact.solvers.friction import Friction

if TYPE_CHECKING:                     # NGSolve's names for the annotations only
    import ngsolve as ng


@dataclass
class ContactOperators:
    """K, f, B, mc, g on the free dofs, with the NGSolve handles to map back."""

    K: sp.csr_matrix          # (n_free, n_free) stiffness, SPD
    f: np.ndarray             # (n_free,) load
    B: sp.csr_matrix          # (n_c, n_free): u_free -> u.n at the contact nodes
    mc: np.ndarray            # (n_c,) lumped boundary mass (quadrature weights) on Gamma_C
    g: np.ndarray             # (n_c,) gap at the contact nodes
    xc: np.ndarray            # (n_c, 2) contact node coordinates
    normals: np.ndarray       # (n_c, 2) unit directions of u.n (the body's outward normals or scene.contact_normal)
    free: np.ndarray          # (n_free,) indices of the free dofs in the full dof vector
    mesh: Any                 # the ngsolve.Mesh (Any: this module imports no NGSolve)
    fes: Any                  # the ngsolve VectorH1 space of the displacement
    scene: Scene
    T: sp.csr_matrix | None = None     # ((d-1) n_c, n_free): u_free -> u.t at the contact nodes, by component
    tangents: np.ndarray | None = None  # (n_c, d-1, d) unit tangents t = (-n_y, n_x) in 2D (friction.tangent_frames)
    friction: Friction | None = None    # the friction law at the contact nodes (None: frictionless or stick)

    @property
    def n_free(self) -> int:
        """Number of free dofs."""
        return self.K.shape[0]

    @property
    def n_c(self) -> int:
        """Number of contact nodes."""
        return self.B.shape[0]

    @property
    def h(self) -> float:
        """Mesh size of the scene."""
        return self.scene.h

    @property
    def dim(self) -> int:
        """Dimension of the body (2 or 3)."""
        return int(self.mesh.dim)

    @property
    def n_cells(self) -> int:
        """Number of cells (triangles or tetrahedra) of the mesh."""
        return int(self.mesh.ne)

    def full_vector(self, u_free: np.ndarray) -> np.ndarray:
        """All dofs (zero on the clamped boundary) from the free ones."""
        u = np.zeros(self.fes.ndof)
        u[self.free] = u_free
        return u

    def to_gridfunction(self, u_free: np.ndarray) -> ng.GridFunction:
        """NGSolve GridFunction of the displacement given by the free dofs."""
        import ngsolve as ng
        gf = ng.GridFunction(self.fes)
        gf.vec.FV().NumPy()[:] = self.full_vector(u_free)
        return gf

    def dof_coordinates(self) -> np.ndarray | None:
        """(n_free, d): a point for each free dof, for the nested dissection of the condensed set-up.

        P1: the vertex the dof sits at (the dofs are the vertices, component by component). P2: the
        vertex for a vertex dof (H1 numbers them first), and for an edge dof the centroid of its basis
        function, int(phi x) / int(phi): the bubble is a multiple of lambda_a lambda_b, so this is the
        edge's midpoint moved a fifth of the way to the mean of the opposite vertices (a dissection needs
        locality, not exact points). Three linear forms assembled by NGSolve, where a loop over the mesh's
        nodes cost about 3 us per dof. VectorH1 numbers its components one after the other, each as H1 of
        the same order. None for any other space.
        """
        import ngsolve as ng
        points = np.asarray(self.mesh.ngmesh.Coordinates())
        dim = points.shape[1]
        if self.fes.ndof == dim * points.shape[0]:
            return np.tile(points, (dim, 1))[self.free]
        order = getattr(self.scene, "order", None)
        if order != 2:
            return None
        scalar = ng.H1(self.mesh, order=2)
        if dim * scalar.ndof != self.fes.ndof:
            return None
        v = scalar.TestFunction()
        moments = []
        for weight in (ng.CF(1.0), ng.x, ng.y, ng.z)[:dim + 1]:
            form = ng.LinearForm(weight * v * ng.dx(bonus_intorder=2)).Assemble()
            moments.append(form.vec.FV().NumPy().copy())
        mass = moments[0]                    # NGSolve's edge bubbles are scaled negative; the ratio does not care
        if not np.all(np.abs(mass) > 0):
            return None
        centroids = np.column_stack([m / mass for m in moments[1:]])
        centroids[:points.shape[0]] = points          # H1 numbers the vertices first, in order: their own points
        return np.tile(centroids, (dim, 1))[self.free]
