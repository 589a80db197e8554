"""The 3D pieces of the adaptive contact loop (:func:`admmkit.problems.contact.solvers.adaptive.solve_adaptive`).

A frictionless :class:`~admmkit.problems.contact.model.scene3d.Scene3D` is
assembled on any tetrahedral mesh of its block (:func:`assemble3d_on`, the
same operators as :func:`~admmkit.problems.contact.model.scene3d.assemble3d`
on the structured mesh): NGSolve's bisection keeps the boundary names of the
refined faces, and the block's faces are flat, so no curving is needed.  The
contact pressure of a level is carried to the contact nodes of the next one
by :func:`surface_interpolate`: linear on a Delaunay triangulation of the old
nodes in the plane of the contact face (z = 0), nearest old node outside
their hull (new nodes near a clamped edge).
"""
from __future__ import annotations

import ngsolve as ng
import numpy as np
import scipy.sparse as sp

from admmkit.problems.contact.model.assembly import ContactOperators, _csr, lame
from admmkit.problems.contact.model.scene3d import Scene3D, block_mesh


def mesh3d(scene: Scene3D) -> ng.Mesh:
    """The structured tetrahedral mesh of the scene's block (the adaptive loop's first level)."""
    return block_mesh(scene.Lx, scene.Ly, scene.Lz, scene.h)


def unknowns3d(mesh: ng.Mesh, order: int) -> int:
    """Dofs of a VectorH1 space of ``order`` on ``mesh`` before the Dirichlet ones go."""
    return 3 * (mesh.nv + (mesh.nedge if order == 2 else 0))


def assemble3d_on(scene: Scene3D, mesh: ng.Mesh) -> ContactOperators:
    """K, f, B, mc, g of a frictionless 3D scene on ``mesh`` (a refined mesh of its block), as ``assemble3d``."""
    if scene.order != 1 or scene.tangential != "frictionless":
        raise ValueError(f"the 3D adaptive assembly takes frictionless P1 scenes, got P{scene.order}, "
                         f"tangential {scene.tangential!r}")
    known = set(mesh.GetBoundaries())
    for label in (*scene.dirichlet, *scene.tractions, scene.contact):
        if label not in known:
            raise ValueError(f"unknown boundary label {label!r}; known labels: {', '.join(sorted(known))}")
    fes = ng.VectorH1(mesh, order=1, dirichlet="|".join(scene.dirichlet))
    u, v = fes.TnT()
    mu, lam = lame(scene.E, scene.nu)
    eps = lambda w: ng.Sym(ng.Grad(w))  # noqa: E731
    a = ng.BilinearForm(fes)
    a += (2 * mu * ng.InnerProduct(eps(u), eps(v)) + lam * ng.Trace(ng.Grad(u)) * ng.Trace(ng.Grad(v))) * ng.dx
    a.Assemble()
    lf = ng.LinearForm(fes)
    for label, t in scene.tractions.items():
        lf += ng.CF(t) * v * ng.ds(definedon=mesh.Boundaries(label))
    lf.Assemble()
    free = np.flatnonzero(np.array(fes.FreeDofs(), dtype=bool))
    K = _csr(a.mat)[free][:, free].tocsr()
    f = lf.vec.FV().NumPy()[free].copy()

    # contact nodes: vertices of the contact face not on a clamped face; lumped mass = area/3 per triangle
    points = np.array(mesh.ngmesh.Coordinates())
    nv = mesh.nv
    clamped = {vx.nr for el in mesh.Elements(ng.BND) if el.mat in scene.dirichlet for vx in el.vertices}
    tris = np.array([[vx.nr for vx in el.vertices] for el in mesh.Elements(ng.BND) if el.mat == scene.contact])
    P = points[tris]
    area = 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)
    weight = np.bincount(tris.ravel(), weights=np.repeat(area / 3, 3), minlength=nv)
    nodes = np.array(sorted(set(tris.ravel().tolist()) - clamped))
    xc = points[nodes]
    order = np.lexsort((xc[:, 1], xc[:, 0]))
    nodes, xc = nodes[order], xc[order]
    g = np.array([scene.gap_at(x, y) for x, y, _ in xc])
    if not np.all(np.isfinite(g)):
        raise ValueError(f"gap: not finite at the contact nodes {xc[~np.isfinite(g)].tolist()}")
    # u.n at node i = -u_z(node i); VectorH1 (P1) numbers the z-component dofs 2 nv + vertex
    Bfull = sp.csr_matrix((-np.ones(len(nodes)), (np.arange(len(nodes)), 2 * nv + nodes)), shape=(len(nodes), fes.ndof))
    return ContactOperators(K=K, f=f, B=Bfull[:, free].tocsr(), mc=weight[nodes], g=g, xc=xc,
                            normals=np.tile([0.0, 0.0, -1.0], (len(nodes), 1)), free=free,
                            mesh=mesh, fes=fes, scene=scene)


def surface_interpolate(xc_old: np.ndarray, values: np.ndarray, xc_new: np.ndarray) -> np.ndarray:
    """``values`` at the old contact nodes, interpolated to the new ones on the flat contact face (module docstring)."""
    from scipy.interpolate import LinearNDInterpolator, NearestNDInterpolator
    old, new = np.asarray(xc_old)[:, :2], np.asarray(xc_new)[:, :2]
    nearest = NearestNDInterpolator(old, values)(new)
    if len(old) < 3:
        return nearest
    linear = LinearNDInterpolator(old, values)(new)
    return np.where(np.isnan(linear), nearest, linear)


__all__ = ["mesh3d", "unknowns3d", "assemble3d_on", "surface_interpolate"]
