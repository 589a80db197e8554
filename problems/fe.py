"""Finite-element pieces the NGSolve plug-ins (contact, obstacle) share."""
from __future__ import annotations

from contextlib import contextmanager

import ngsolve as ng
import numpy as np

#: meshes with fewer elements assemble without NGSolve's task manager (the contact assembly's threshold)
TASKS_MIN_ELEMENTS = 200_000


@contextmanager
def ngsolve_tasks(elements: int, min_elements: int = TASKS_MIN_ELEMENTS):
    """NGSolve's ``TaskManager`` (its default thread count, one per core) for the block, on a mesh of at least
    ``min_elements`` elements.

    Each of its parallel loops waits for every thread: with the other core busy that cost 0.15 s for a
    form of 3,200 elements (0.02 s without it), so small meshes go without.  The assembled values do not
    depend on it (compared entry by entry), nor does a refined mesh (its vertices and elements, compared).
    """
    if elements < min_elements:
        yield
        return
    with ng.TaskManager():
        yield


#: adaptive refinement and the obstacle's assembly use the task manager from this many elements (NGSolve's
#: bisection from 2e5 to 6e5 triangles: 2.3 -> 1.1 s; a P1 Laplacian of 2.6e5 triangles: 0.24 -> 0.14 s, 9e4:
#: 0.085 -> 0.048 s; this machine, the other core idle)
ADAPTIVE_TASKS_MIN_ELEMENTS = 20_000


def refine_marked(mesh: ng.Mesh, marked: np.ndarray) -> None:
    """NGSolve's bisection of the marked elements (and the closure conformity needs), in place.

    The flags are set in one call (a loop over the elements: 0.3 s at 2e5); the refinement runs under the
    task manager on meshes of at least ADAPTIVE_TASKS_MIN_ELEMENTS elements (the same mesh, 1.5-2x sooner).
    ``marked``: one boolean (or 0/1) per element; anything else is refused (netgen would take a short list).
    """
    flags = np.asarray(marked)
    if flags.shape != (mesh.ne,) or not (flags.dtype == bool or np.isin(flags, (0, 1)).all()):
        raise ValueError(f"marked must hold one boolean per element, shape ({mesh.ne},); got shape {flags.shape}, "
                         f"dtype {flags.dtype}")
    mesh.SetRefinementFlags(flags.astype(bool).tolist())
    with ngsolve_tasks(mesh.ne, ADAPTIVE_TASKS_MIN_ELEMENTS):
        mesh.Refine()


def mesh_copy(mesh: ng.Mesh) -> ng.Mesh:
    """A new NGSolve mesh with the points and elements of ``mesh`` in the same order, without its refinement
    history: a finished level's model keeps it while ``mesh`` is refined in place (netgen's bisection of
    tetrahedra reads that history, so refining a copy instead would give other meshes in 3D)."""
    return ng.Mesh(mesh.ngmesh.Copy())


def refined_copy(mesh: ng.Mesh, marked: np.ndarray) -> ng.Mesh:
    """A new mesh: a copy of ``mesh`` with the marked elements bisected (:func:`refine_marked`); ``mesh`` stays as
    it is, so fields on it can be evaluated at the new mesh's points.

    The copy has the same points and elements in the same order (so ``marked`` applies to it), but not the
    refinement hierarchy: NGSolve's prolongation (``GridFunction.Update``) does not reach the new mesh; P1
    values are carried over by :func:`p1_prolongation`.
    """
    copy = mesh_copy(mesh)
    refine_marked(copy, marked)
    return copy


def vertex_parents(mesh: ng.Mesh, coarse_vertices: int) -> np.ndarray:
    """(new vertices, 2): the two ends of the edge each vertex of a refined mesh numbered from
    ``coarse_vertices`` on was made at (NGSolve's bisection numbers new vertices after the old ones; in one
    refinement a parent may itself be new, then it has the lower number)."""
    parents = [mesh.GetParentVertices(v) for v in range(coarse_vertices, mesh.nv)]
    return np.array(parents, dtype=np.int64).reshape(-1, 2)


def p1_prolongation(parents: np.ndarray, coarse: np.ndarray) -> np.ndarray:
    """P1 nodal values on a refined mesh from those on its parent: each new vertex the mean of its parent
    edge's two ends (:func:`vertex_parents`), as NGSolve's ``GridFunction.Update`` prolongates in place.

    With :func:`refined_copy` this takes the place of in-place refinement, whose hierarchy made NGSolve's
    bisection twice as dear after a dozen levels (1.6e5 -> 2.9e5 triangles: 0.88 s in place, 0.40 s on a copy).
    """
    n0 = coarse.shape[0]
    fine = np.empty(n0 + parents.shape[0])
    fine[:n0] = coarse
    if parents.size == 0 or parents.max() < n0:             # every parent old: one gather
        fine[n0:] = 0.5 * (coarse[parents[:, 0]] + coarse[parents[:, 1]])
        return fine
    for i, (a, b) in enumerate(parents):                      # in order: a new parent is set before its children
        fine[n0 + i] = 0.5 * (fine[a] + fine[b])
    return fine


def facet_sizes(mesh: ng.Mesh) -> ng.GridFunction:
    """h_E on every facet: its length (2D) or the square root of its area (3D), as a FacetFESpace function."""
    facets = ng.FacetFESpace(mesh, order=0)
    v = facets.TestFunction()
    lf = ng.LinearForm(facets)
    lf += v * ng.dx(skeleton=True)
    lf += v * ng.ds(skeleton=True)
    lf.Assemble()
    gf = ng.GridFunction(facets)
    gf.vec.FV().NumPy()[:] = np.abs(lf.vec.FV().NumPy()) ** (1.0 / (mesh.dim - 1))
    return gf


def triangles(mesh: ng.Mesh) -> np.ndarray:
    """The vertex numbers of every triangle of a 2D mesh, (elements, 3), in NGSolve's element order.

    Read as one array from netgen (1-based there); a Python loop over ``mesh.Elements`` took 0.4 s at 4.5e5
    triangles.
    """
    return mesh.ngmesh.Elements2D().NumPy()["nodes"][:, :3].astype(np.int64) - 1


def areas(nodes: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """The area of every triangle ((elements,); ``nodes`` (vertices, 2), ``tri`` (elements, 3))."""
    p = nodes[tri]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    return 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


def p1_mass(nodes: np.ndarray, tri: np.ndarray, area: np.ndarray | None = None):
    """The P1 mass of a triangle mesh without assembling it: ``(lumped, apply)``.

    ``lumped``: the row sums of the consistent mass, sum over the triangles at a vertex of |T|/3;
    ``apply(f)``: the consistent mass times nodal values f, with the element mass |T|/12 (1 + delta_ij),
    i.e. |T|/12 (f_i + f_0 + f_1 + f_2) on every vertex i of T.
    """
    area = areas(nodes, tri) if area is None else area
    n = nodes.shape[0]
    lumped = np.bincount(tri.ravel(), weights=np.repeat(area / 3.0, 3), minlength=n)

    def apply(f: np.ndarray) -> np.ndarray:
        """M f for nodal values f on every vertex."""
        local = area[:, None] / 12.0 * (f[tri] + f[tri].sum(axis=1, keepdims=True))
        return np.bincount(tri.ravel(), weights=local.ravel(), minlength=n)
    return lumped, apply
