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

from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from admmkit.problems.contact.model.operators import ContactOperators
from admmkit.problems.contact.model.scene3d import FACE_AXIS, block_arrays, block_mesh

if TYPE_CHECKING:      # NGSolve is imported by the routes that use it: the arrays route (P1 block) runs without it
    import ngsolve as ng
from admmkit.problems.contact.solvers.friction import friction_of, tangent_frames

#: the share of a P2 triangle's area at each of its vertices in the HRZ-lumped mass
P2_VERTEX_SHARE = 1 / 19
#: and at each of its edge midpoints (3/19 + 3 x 16/57 = 1)
P2_MIDPOINT_SHARE = 16 / 57


#: the ways to assemble K, "compiled" (P1 by ``p1_stiffness`` of problems/contact/model/stiffness3d.py, P2 by
#: NGSolve) or "ngsolve" (NGSolve's symbolic assembly for both)
STIFFNESS = ("compiled", "ngsolve")
#: the ways to build the structured P1 block, "arrays" (its mesh, free dofs, load and contact face from numpy
#: arrays into a BlockOperators3D, whose netgen mesh and NGSolve space are made only when something asks for
#: them) or "ngsolve" (netgen's mesh and NGSolve's space first, the library path)
ROUTES = ("arrays", "ngsolve")


def assemble3d(scene, mesh=None, stiffness: str = "compiled", route: str = "arrays") -> ContactOperators:
    """K, f, B, mc, g on the free dofs of the 3D scene (a ``Scene3D``; n = (0, 0, -1) on the contact face), in the
    scene's order.

    ``mesh``: a tetrahedral mesh of the scene's block with its face names (e.g. an adaptively refined
    one); default the structured mesh of ``scene.h``.  ``stiffness``: one of STIFFNESS (the same K to
    round-off; "compiled" took 1.7 s of CPU against NGSolve's 11 s at h = 1/32, 3.1e5 unknowns).
    ``route``: one of ROUTES; "arrays" applies to the structured mesh with P1 and the compiled K (otherwise
    NGSolve's route is taken) and returns the same arrays, in the same numbering, as "ngsolve"
    (:func:`assemble_block_arrays`).
    """
    if stiffness not in STIFFNESS:
        raise ValueError(f"stiffness = {stiffness!r}; accepted: {', '.join(STIFFNESS)}")
    if route not in ROUTES:
        raise ValueError(f"route = {route!r}; accepted: {', '.join(ROUTES)}")
    if route == "arrays" and mesh is None and scene.order == 1 and stiffness == "compiled":
        return assemble_block_arrays(scene)
    import ngsolve as ng
    from admmkit.problems.contact.model.fastpaths import component_map
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


def assemble_block_arrays(scene) -> "BlockOperators3D":
    """The operators of ``assemble3d(scene, route="ngsolve")`` for the structured P1 block, built from arrays.

    The mesh is scene3d's ``block_arrays`` (the vertices, tetrahedra and face
    triangles ``block_mesh`` gives netgen); the free dofs are those of NGSolve's VectorH1 with the scene's
    clamped faces (dof c n_v + v, component c of vertex v, not free on a clamped face or on a face that
    ``component_dirichlet`` fixes for c); K is the same compiled ``p1_stiffness``; f is the traction's exact
    integral t area(T) / 3 at each vertex of a loaded triangle T (NGSolve's quadrature of it, equal to round-off);
    the contact nodes and their weights are ``face_nodes``' from the same triangles.  At h = 1/48 (1.04e6
    unknowns) netgen's mesh and NGSolve's space took 4-5 s of CPU before K.
    """
    from admmkit.problems.contact.model.stiffness3d import p1_stiffness   # numba: loaded by a 3-D run only
    points, tets, faces = block_arrays(scene.Lx, scene.Ly, scene.Lz, scene.h)
    nv = points.shape[0]
    free = block_free_dofs(scene, nv, faces)
    K = p1_stiffness(points, tets, scene.E, scene.nu, free)
    load = np.zeros((3, nv))
    for label, t in scene.tractions.items():
        tris = faces[label]
        # NGSolve's element value |T| / 3 t as it computes it (2|T| (1/6) t); only the order in which its
        # assembly sums a vertex's triangles differs (round-off, at a few vertices)
        element = 2 * _areas(points, tris) * (1 / 6)
        for c in range(3):
            load[c] += np.bincount(tris.ravel(), weights=np.repeat(element * t[c], 3), minlength=nv)
    f = load.ravel()[free]
    clamped_tris = np.vstack([faces[label] for label in scene.dirichlet])
    tris = faces[scene.contact]
    vertex, xc, mc = _by_x(*_face_vertices(points, tris, clamped_tris, _areas(points, tris) / 3), scene.contact)
    normals = np.tile([0.0, 0.0, -1.0], (len(xc), 1))
    g = np.array([scene.gap_at(x, y) for x, y, _ in xc])
    if not np.all(np.isfinite(g)):
        raise ValueError(f"gap: not finite at the contact nodes {xc[~np.isfinite(g)].tolist()}")
    B, T = _vertex_maps(vertex, nv, 3 * nv, free)
    return BlockOperators3D(K=K, f=f, B=B, mc=mc, g=g, xc=xc, normals=normals, free=free, scene=scene, T=T,
                            tangents=tangent_frames(normals), friction=friction_of(scene, xc),
                            vertices=points, n_cells=tets.shape[0])


def block_free_dofs(scene, nv: int, faces: dict[str, np.ndarray]) -> np.ndarray:
    """The free dofs c n_v + v of VectorH1 on the block: not on a clamped face (``scene.dirichlet``) nor, for
    component c, on a face of ``component_dirichlet(scene)``'s c (ascending, as NGSolve's FreeDofs)."""
    clamped = np.zeros((3, nv), dtype=bool)
    for label in scene.dirichlet:
        clamped[:, faces[label].ravel()] = True
    for key, labels in component_dirichlet(scene).items():
        c = "xyz".index(key[-1])
        for label in labels.split("|"):
            clamped[c, faces[label].ravel()] = True
    return np.flatnonzero(~clamped.ravel())


class BlockOperators3D(ContactOperators):
    """The operators of the structured P1 block built from arrays (:func:`assemble_block_arrays`).

    The same fields as ``ContactOperators``; ``mesh`` and ``fes`` (netgen's ``block_mesh`` and NGSolve's
    VectorH1) are made when something first asks for them (a VTU file, an estimator), and checked against the
    arrays: a space whose dof count or free dofs differ raises RuntimeError, never a silent wrong map.
    ``vertices`` (n_v, 3) are the mesh's points, which the iterative mode's rigid-body modes read without NGSolve.
    """

    def __init__(self, *, vertices: np.ndarray, n_cells: int, **fields):
        for name, value in fields.items():
            setattr(self, name, value)
        self.vertices = vertices
        self._n_cells = int(n_cells)
        self._space = None

    def __repr__(self) -> str:
        return (f"BlockOperators3D({getattr(self.scene, 'name', '') or 'scene'}, n_free={self.n_free}, "
                f"n_c={self.n_c}, from arrays)")

    @property
    def dim(self) -> int:
        """3."""
        return 3

    @property
    def n_cells(self) -> int:
        """Number of tetrahedra."""
        return self._n_cells

    @property
    def ndof(self) -> int:
        """Number of dofs of VectorH1 (3 per vertex), free or not."""
        return 3 * self.vertices.shape[0]

    def full_vector(self, u_free: np.ndarray) -> np.ndarray:
        """All dofs (zero on the clamped boundary) from the free ones, without NGSolve."""
        u = np.zeros(self.ndof)
        u[self.free] = u_free
        return u

    def dof_coordinates(self) -> np.ndarray:
        """(n_free, 3): the vertex of each free dof."""
        return np.tile(self.vertices, (3, 1))[self.free]

    @property
    def mesh(self):
        """netgen's ``block_mesh`` as an NGSolve mesh, made on first use."""
        return self._netgen()[0]

    @property
    def fes(self):
        """NGSolve's VectorH1 with the scene's clamped faces, made on first use."""
        return self._netgen()[1]

    def _netgen(self):
        """(mesh, fes), made once and checked against the arrays."""
        if self._space is None:
            import ngsolve as ng
            scene = self.scene
            mesh = block_mesh(scene.Lx, scene.Ly, scene.Lz, scene.h)
            fes = ng.VectorH1(mesh, order=1, dirichlet="|".join(scene.dirichlet), **component_dirichlet(scene))
            free = np.flatnonzero(np.array(fes.FreeDofs(), dtype=bool))
            if fes.ndof != self.ndof or not np.array_equal(free, self.free) or mesh.ne != self._n_cells:
                raise RuntimeError(f"NGSolve's space of the block has {fes.ndof} dofs ({free.size} free) where the "
                                   f"arrays have {self.ndof} ({self.free.size} free)")
            self._space = (mesh, fes)
        return self._space


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
    import ngsolve as ng
    from admmkit.problems.contact.model.assembly import free_matrix, lame
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
    import ngsolve as ng
    points = np.array(mesh.ngmesh.Coordinates())
    # the boundary triangles from netgen's arrays (vertices numbered from 1, faces by their descriptor's
    # number from 1): NGSolve's BND elements in the same order, without a Python loop over them
    surface = mesh.ngmesh.Elements2D().NumPy()
    labels = np.array(mesh.GetBoundaries())[surface["index"] - 1]
    triangles = surface["nodes"][:, :3].astype(np.int64) - 1
    tris = triangles[labels == contact]
    area = _areas(points, tris)
    vertex, xc, mc = _face_vertices(points, tris, triangles[np.isin(labels, list(dirichlet))],
                                    area / 3 if order == 1 else area * P2_VERTEX_SHARE)
    if order == 2:
        bnd = list(mesh.Elements(ng.BND))
        face = [el for el in bnd if el.mat == contact]
        edges = np.array([[e.nr for e in el.edges] for el in face])
        clamped_edges = {e.nr for el in bnd if el.mat in dirichlet for e in el.edges}
        edge_weight = np.bincount(edges.ravel(), weights=np.repeat(area * P2_MIDPOINT_SHARE, 3), minlength=mesh.nedge)
        mids = np.array(sorted(set(edges.ravel().tolist()) - clamped_edges), dtype=np.int64)
        ends = np.array([[vx.nr for vx in mesh[ng.NodeId(ng.EDGE, int(e))].vertices] for e in mids],
                        dtype=np.int64).reshape(-1, 2)
        vertex = np.concatenate([vertex, np.full(len(mids), -1)])
        xc = np.vstack([xc, 0.5 * (points[ends[:, 0]] + points[ends[:, 1]])])
        mc = np.concatenate([mc, edge_weight[mids]])
    return _by_x(vertex, xc, mc, contact)


def _areas(points: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """The areas of the triangles ``tris`` (vertex numbers of ``points``)."""
    P = points[tris]
    return 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)


def _face_vertices(points: np.ndarray, tris: np.ndarray, clamped_tris: np.ndarray, share: np.ndarray):
    """(vertex, xc, mc) of the vertices of the triangles ``tris`` that lie on no triangle of ``clamped_tris``,
    ascending, mc the sum of ``share`` (one value per triangle) over each vertex's triangles."""
    nv = points.shape[0]
    is_clamped = np.zeros(nv, dtype=bool)
    is_clamped[clamped_tris.ravel()] = True
    weight = np.bincount(tris.ravel(), weights=np.repeat(share, 3), minlength=nv)
    nodes = np.unique(tris.ravel())
    nodes = nodes[~is_clamped[nodes]]
    return nodes, points[nodes], weight[nodes]


def _by_x(vertex: np.ndarray, xc: np.ndarray, mc: np.ndarray, contact: str):
    """The contact nodes ordered by x then y; ValueError if there are none."""
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
    import ngsolve as ng
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


__all__ = ["assemble3d", "assemble_block_arrays", "block_free_dofs", "BlockOperators3D", "ROUTES", "component_dirichlet", "STIFFNESS", "face_nodes", "point_evaluation", "P2_VERTEX_SHARE", "P2_MIDPOINT_SHARE"]
