"""The 3D pieces of the adaptive contact loop (:func:`admmkit.problems.contact.solvers.adaptive.solve_adaptive`).

A :class:`~admmkit.problems.contact.model.scene3d.Scene3D` (P1 or P2; frictionless, Tresca or Coulomb) is
assembled on any tetrahedral mesh of its block (:func:`assemble3d_on`:
``assemble3d`` given the mesh): NGSolve's bisection keeps the boundary names of the
refined faces, and the block's faces are flat, so no curving is needed.  The
contact pressure of a level is carried to the contact nodes of the next one
by :func:`surface_interpolate`: linear on a Delaunay triangulation of the old
nodes (with P2 the vertices and edge midpoints) in the plane of the contact
face (z = 0), nearest old node outside their hull (new nodes near a clamped
edge).
"""
from __future__ import annotations

import ngsolve as ng
import numpy as np

from admmkit.problems.contact.model.assembly import ContactOperators
from admmkit.problems.contact.model.assembly3d import assemble3d
from admmkit.problems.contact.model.scene3d import Scene3D, block_mesh


def mesh3d(scene: Scene3D) -> ng.Mesh:
    """The structured tetrahedral mesh of the scene's block (the adaptive loop's first level)."""
    return block_mesh(scene.Lx, scene.Ly, scene.Lz, scene.h)


def unknowns3d(mesh: ng.Mesh, order: int) -> int:
    """Dofs of a VectorH1 space of ``order`` on ``mesh`` before the Dirichlet ones go."""
    return 3 * (mesh.nv + (mesh.nedge if order == 2 else 0))


def assemble3d_on(scene: Scene3D, mesh: ng.Mesh) -> ContactOperators:
    """K, f, B, mc, g (with friction T and the slip bound) of a P1 or P2 3D scene on ``mesh`` (a refined mesh of
    its block): ``assemble3d``'s."""
    if scene.order not in (1, 2) or scene.tangential not in ("frictionless", "stick", "tresca", "coulomb"):
        raise ValueError(f"the 3D adaptive assembly takes P1 and P2 scenes, got "
                         f"P{scene.order}, tangential {scene.tangential!r}")
    return assemble3d(scene, mesh=mesh)


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
