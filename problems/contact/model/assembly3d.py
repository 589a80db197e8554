"""Assembly of the 3D contact scenes (``Scene3D`` of problems/contact/model/scene3d.py), P1 and P2 tetrahedra.

:func:`assemble3d` returns the same :class:`~admmkit.problems.contact.ContactOperators` as the 2D
assembly, so every contact mode and method works unchanged.  The contact
face is flat (z = 0, outward normal n = (0, 0, -1)), u.n = -u_z.

Contact nodes (:func:`face_nodes`): the vertices of the contact face's
triangles (P1), with P2 also the midpoints of their edges, less the nodes on a
clamped face (a vertex of a clamped boundary triangle; a midpoint of one of its
edges).  Their weights m_c (the nodal quadrature of (v_n, q) on the face):

* P1: the row sums of the P1 triangle mass, A/3 per vertex of a triangle of area A;
* P2: the row sums of the P2 triangle mass are 0 at the vertices (the quadratic
  basis integrates to 0 there), which would leave those nodes without weight, so
  HRZ lumping: the diagonal of the consistent P2 mass (A/30 at a vertex, 8A/45 at a
  midpoint) scaled to sum to A, i.e. A/19 per vertex and 16A/57 per midpoint
  (3/19 + 3 x 16/57 = 1).  Positive weights that integrate constants exactly.

B (u.n) and T (u_x, u_y) come from the point evaluation of the scalar H1 space
(:func:`point_evaluation`): a vertex's row is the unit row of its dof; NGSolve's
P2 basis is hierarchical (vertex hats and edge bubbles), so a midpoint's row is
the element's shape functions there (1/2 at both ends and the bubble's value);
VectorH1 numbers component c of scalar dof j as c n_scalar + j.
"""
from __future__ import annotations

import ngsolve as ng
import numpy as np
import scipy.sparse as sp

from admmkit.problems.contact.model.assembly import ContactOperators, free_matrix, lame
from admmkit.problems.contact.model.fastpaths import component_map
from admmkit.problems.contact.model.scene3d import FACE_AXIS, block_mesh
from admmkit.problems.contact.solvers.friction import friction_of, tangent_frames

#: the share of a P2 triangle's area at each of its vertices in the HRZ-lumped mass
P2_VERTEX_SHARE = 1 / 19
#: and at each of its edge midpoints (3/19 + 3 x 16/57 = 1)
P2_MIDPOINT_SHARE = 16 / 57


#: the ways to assemble K, "compiled" (P1 by ``p1_stiffness`` of problems/contact/model/stiffness3d.py, P2 by
#: NGSolve) or "ngsolve" (NGSolve's symbolic assembly for both)
STIFFNESS = ("compiled", "ngsolve")


def assemble3d(scene, mesh=None, stiffness: str = "compiled") -> ContactOperators:
    """K, f, B, mc, g on the free dofs of the 3D scene (a ``Scene3D``; n = (0, 0, -1) on the contact face), in the
    scene's order.

    ``mesh``: a tetrahedral mesh of the scene's block with its face names (e.g. an adaptively refined
    one); default the structured mesh of ``scene.h``.  ``stiffness``: one of STIFFNESS (the same K to
    round-off; "compiled" took 1.7 s of CPU against NGSolve's 11 s at h = 1/32, 3.1e5 unknowns).
    """
    if stiffness not in STIFFNESS:
        raise ValueError(f"stiffness = {stiffness!r}; accepted: {', '.join(STIFFNESS)}")
    if mesh is None:
        mesh = block_mesh(scene.Lx, scene.Ly, scene.Lz, scene.h)
    else:
        known = set(mesh.GetBoundaries())
        for label in (*scene.dirichlet, *scene.tractions, *scene.symmetry, scene.contact):
            if label not in known:
                raise ValueError(f"unknown boundary label {label!r}; known labels: {', '.join(sorted(known))}")
    fes = ng.VectorH1(mesh, order=scene.order, dirichlet="|".join(scene.dirichlet), **component_dirichlet(scene))
    v = fes.TestFunction()
    free = np.flatnonzero(np.array(fes.FreeDofs(), dtype=bool))
    if scene.order == 1 and stiffness == "compiled":
        points = np.array(mesh.ngmesh.Coordinates())
        tets = mesh.ngmesh.Elements3D().NumPy()["nodes"][:, :4] - 1        # netgen numbers points from 1
        from admmkit.problems.contact.model.stiffness3d import p1_stiffness   # numba: loaded by a 3-D run only
        K = p1_stiffness(points, tets, scene.E, scene.nu, free)
    else:
        K = _ngsolve_stiffness(fes, scene.E, scene.nu, free)
    lf = ng.LinearForm(fes)
    for label, t in scene.tractions.items():
        lf += ng.CF(t) * v * ng.ds(definedon=mesh.Boundaries(label))
    lf.Assemble()
    f = lf.vec.FV().NumPy()[free].copy()

    vertex, xc, mc = face_nodes(mesh, scene.contact, scene.dirichlet, scene.order)
    normals = np.tile([0.0, 0.0, -1.0], (len(xc), 1))
    g = np.array([scene.gap_at(x, y) for x, y, _ in xc])
    if not np.all(np.isfinite(g)):
        raise ValueError(f"gap: not finite at the contact nodes {xc[~np.isfinite(g)].tolist()}")
    tangents = tangent_frames(normals)           # t1 = (1, 0, 0), t2 = (0, 1, 0) for n = (0, 0, -1)
    if scene.order == 1:
        B, T = _vertex_maps(vertex, mesh.nv, fes.ndof, free)
    else:
        scalar = ng.H1(mesh, order=scene.order)
        E = point_evaluation(mesh, scalar, xc, vertex)
        B = component_map(E, normals, free, fes.ndof)                   # u.n = -u_z
        T = sp.vstack([component_map(E, tangents[:, k, :], free, fes.ndof) for k in range(2)]).tocsr()
    return ContactOperators(K=K, f=f, B=B, mc=mc, g=g, xc=xc, normals=normals, free=free,
                            mesh=mesh, fes=fes, scene=scene, T=T, tangents=tangents,
                            friction=friction_of(scene, xc))


def component_dirichlet(scene) -> dict:
    """VectorH1's per-component Dirichlet faces: u_x = u_y = 0 on the contact face for ``stick``, and u.n = 0 on
    every symmetry face (``FACE_AXIS``)."""
    faces = {axis: [] for axis in "xyz"}
    if scene.tangential == "stick":
        faces["x"].append(scene.contact)
        faces["y"].append(scene.contact)
    for label in getattr(scene, "symmetry", ()):
        faces[FACE_AXIS[label]].append(label)
    return {f"dirichlet{axis}": "|".join(labels) for axis, labels in faces.items() if labels}


def _ngsolve_stiffness(fes, E: float, nu: float, free: np.ndarray):
    """K on the free dofs by NGSolve's symbolic assembly of 2 mu eps(u):eps(v) + lam div u div v."""
    u, v = fes.TnT()
    mu, lam = lame(E, nu)
    eps = lambda w: ng.Sym(ng.Grad(w))  # noqa: E731
    a = ng.BilinearForm(fes)
    a += (2 * mu * ng.InnerProduct(eps(u), eps(v)) + lam * ng.Trace(ng.Grad(u)) * ng.Trace(ng.Grad(v))) * ng.dx
    a.Assemble()
    return free_matrix(a.mat, free)


def _vertex_maps(nodes: np.ndarray, nv: int, ndof: int, free: np.ndarray):
    """(B, T) of P1 (the dofs are the vertices): u.n = -u_z, u.t1 = u_x, u.t2 = u_y at the vertices ``nodes``."""
    # VectorH1 numbers the z-component dofs 2 nv + vertex
    Bfull = sp.csr_matrix((-np.ones(len(nodes)), (np.arange(len(nodes)), 2 * nv + nodes)), shape=(len(nodes), ndof))
    B = Bfull[:, free].tocsr()
    rows = np.arange(2 * len(nodes))
    Tfull = sp.csr_matrix((np.ones(2 * len(nodes)), (rows, np.concatenate([nodes, nv + nodes]))),
                          shape=(2 * len(nodes), ndof))
    T = Tfull[:, free].tocsr()
    T.eliminate_zeros()
    return B, T


def face_nodes(mesh: ng.Mesh, contact: str, dirichlet, order: int):
    """(vertex, xc, mc): the contact nodes of the face ``contact`` not on a ``dirichlet`` face (module docstring),
    ordered by x then y.

    ``vertex[i]``: the vertex node i is, -1 for an edge midpoint (P2); ``xc`` (n, 3) the points; ``mc`` the
    lumped weights (P1: A/3 per vertex of a triangle; P2: HRZ, A/19 per vertex and 16A/57 per midpoint).
    """
    if order not in (1, 2):
        raise ValueError(f"order = {order!r}; accepted: 1 (P1 tetrahedra) or 2 (P2)")
    points = np.array(mesh.ngmesh.Coordinates())
    # the boundary triangles from netgen's arrays (vertices numbered from 1, faces by their descriptor's
    # number from 1): NGSolve's BND elements in the same order, without a Python loop over them
    surface = mesh.ngmesh.Elements2D().NumPy()
    labels = np.array(mesh.GetBoundaries())[surface["index"] - 1]
    triangles = surface["nodes"][:, :3].astype(np.int64) - 1
    tris = triangles[labels == contact]
    is_clamped = np.zeros(mesh.nv, dtype=bool)
    is_clamped[triangles[np.isin(labels, list(dirichlet))].ravel()] = True
    P = points[tris]
    area = 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)
    share = area / 3 if order == 1 else area * P2_VERTEX_SHARE
    weight = np.bincount(tris.ravel(), weights=np.repeat(share, 3), minlength=mesh.nv)
    nodes = np.unique(tris.ravel())
    nodes = nodes[~is_clamped[nodes]]
    vertex, xc, mc = nodes, points[nodes], weight[nodes]
    if order == 2:
        bnd = list(mesh.Elements(ng.BND))
        face = [el for el in bnd if el.mat == contact]
        edges = np.array([[e.nr for e in el.edges] for el in face])
        clamped_edges = {e.nr for el in bnd if el.mat in dirichlet for e in el.edges}
        edge_weight = np.bincount(edges.ravel(), weights=np.repeat(area * P2_MIDPOINT_SHARE, 3), minlength=mesh.nedge)
        mids = np.array(sorted(set(edges.ravel().tolist()) - clamped_edges), dtype=np.int64)
        ends = np.array([[vx.nr for vx in mesh[ng.NodeId(ng.EDGE, int(e))].vertices] for e in mids],
                        dtype=np.int64).reshape(-1, 2)
        vertex = np.concatenate([nodes, np.full(len(mids), -1)])
        xc = np.vstack([xc, 0.5 * (points[ends[:, 0]] + points[ends[:, 1]])])
        mc = np.concatenate([mc, edge_weight[mids]])
    if len(xc) == 0:
        raise ValueError(f"contact: face {contact!r} has no unclamped node on this mesh")
    by_x = np.lexsort((xc[:, 1], xc[:, 0]))
    return vertex[by_x], xc[by_x], mc[by_x]


def point_evaluation(mesh: ng.Mesh, scalar: ng.comp.FESpace, points: np.ndarray,
                     vertex: np.ndarray | None = None) -> sp.csr_matrix:
    """E[i, j] = phi_j(points[i]) for the basis of a scalar H1 space on a 3D mesh.

    ``vertex[i]`` >= 0: point i is that vertex, its row the unit row of the vertex's dof (H1 gives vertex v the
    dof v and every other basis function vanishes there).  Otherwise the point is located (``mesh(x, y, z)``)
    and its row is the element's shape functions there (the 3D analogue of the 2D ``_point_evaluation``).
    """
    rows, cols, vals = [], [], []
    for i, (x, y, z) in enumerate(np.asarray(points, dtype=float)):
        if vertex is not None and vertex[i] >= 0:
            rows.append(i); cols.append(int(vertex[i])); vals.append(1.0)
            continue
        mp = mesh(x, y, z)
        if mp.nr < 0:
            raise ValueError(f"point ({x:g}, {y:g}, {z:g}) is not in the mesh")
        el = ng.ElementId(ng.VOL, mp.nr)
        shape = np.array(scalar.GetFE(el).CalcShape(*mp.pnt))
        for j, s in zip(scalar.GetDofNrs(el), shape):
            if abs(s) > 1e-12:
                rows.append(i); cols.append(j); vals.append(s)
    return sp.csr_matrix((vals, (rows, cols)), shape=(len(points), scalar.ndof))


__all__ = ["assemble3d", "component_dirichlet", "STIFFNESS", "face_nodes", "point_evaluation", "P2_VERTEX_SHARE", "P2_MIDPOINT_SHARE"]
