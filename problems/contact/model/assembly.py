"""Discrete contact operators: min 1/2 u'Ku - f'u [+ j(T u)]  subject to  B u <= g.

With friction T maps u to its tangential components at the contact nodes and
j is the Tresca functional (:mod:`admmkit.problems.contact.solvers.friction`).

The pairing (v_n, q)_Gc is approximated by nodal quadrature, sum_i mc_i v_n(x_i) q_i,
over the contact nodes x_i (vertices, and for P2 also edge midpoints, of Gamma_C
that are not clamped). All matrices act on the free (non-Dirichlet) dofs.
"""
from __future__ import annotations

import ngsolve as ng
import numpy as np
import scipy.sparse as sp

from admmkit.linalg.submatrix import principal_submatrix

from admmkit.problems.contact.model.fastpaths import component_map, free_dofs
from admmkit.problems.contact.model.operators import ContactOperators  # noqa: F401  (its home before; re-exported)
from admmkit.problems.fe import ngsolve_tasks
from admmkit.problems.contact.solvers.friction import friction_of, tangent_frames
from admmkit.problems.contact.model.mesh import geometry_mesh, structured_rectangle, unstructured_rectangle
from admmkit.problems.contact.model.scene import Scene


def lame(E: float, nu: float) -> tuple[float, float]:
    """Lame parameters (mu, lambda) for plane strain."""
    return E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))


def build_mesh(scene: Scene) -> ng.Mesh:
    """The NGSolve mesh described by the scene."""
    if scene.geometry is not None:
        return geometry_mesh(scene.geometry, scene.h)
    if scene.mesh_kind == "structured":
        return structured_rectangle(scene.L, scene.H, scene.h)
    return unstructured_rectangle(scene.L, scene.H, scene.h)


def _csr(mat, copy: bool = True) -> sp.csr_matrix:
    """An NGSolve sparse matrix in scipy's CSR: a copy, or (``copy=False``) views of NGSolve's arrays that live
    only as long as ``mat``."""
    vals, cols, rows = mat.CSR()
    take = np.array if copy else np.asarray
    return sp.csr_matrix((take(vals), take(cols), np.asarray(rows, dtype=np.int64)), shape=(mat.height, mat.width))


def free_matrix(mat, free: np.ndarray) -> sp.csr_matrix:
    """The rows and columns ``free`` of an assembled NGSolve matrix, in CSR with sorted rows: the values of
    ``_csr(mat)[free][:, free]`` read straight from NGSolve's arrays in one pass (0.9 -> 0.1 s at 1e6 unknowns)."""
    return principal_submatrix(_csr(mat, copy=False), free)


def _vector_cf(t):
    """Constant pair or callable (x, y) -> pair  ->  NGSolve vector CoefficientFunction."""
    if callable(t):
        try:
            t = t(ng.x, ng.y)
        except Exception as err:
            raise ValueError("a traction/body-force callable must accept NGSolve coefficient functions "
                             f"(write it with arithmetic and ngsolve.sin/exp/...): {err}") from None
    return ng.CF(tuple(t))


def contact_nodes(mesh: ng.Mesh, scene: Scene):
    """Contact nodes of Gamma_C without the clamped ones (those on a ``scene.dirichlet`` label).

    Returns (nodes, xc, mc, normals) as :func:`boundary_nodes`.
    """
    clamped = {v.nr for el in mesh.Elements(ng.BND) if el.mat in scene.dirichlet for v in el.vertices}
    return boundary_nodes(mesh, scene.contact, scene.order, lambda key: key[0] == "V" and key[1] in clamped)


def boundary_nodes(mesh: ng.Mesh, contact: str, order: int, clamped):
    """The nodes of the 2D boundary ``contact`` for which ``clamped(key)`` is false.

    Returns (nodes, xc, mc, normals): nodes[i] = ("V", vertex) or ("E", edge) for a
    P2 midpoint; mc = trapezoid (P1) or Simpson (P2) weights; normals = length-weighted
    average of the outward normals of the adjacent contact edges, normalised.
    """
    point = lambda v: np.array(mesh[v].point[:2])  # noqa: E731
    weight, nsum, coords = {}, {}, {}
    for el in mesh.Elements(ng.BND):
        if el.mat != contact:
            continue
        va, vb = el.vertices
        pa, pb = point(va), point(vb)
        ell = np.linalg.norm(pb - pa)
        (edge,) = el.edges
        (vol,) = mesh[edge].elements               # the triangle beside this boundary edge
        centre = np.mean([point(v) for v in mesh[vol].vertices], axis=0)
        n = np.array([pb[1] - pa[1], pa[0] - pb[0]]) / ell
        if n @ ((pa + pb) / 2 - centre) < 0:       # make it point out of the body
            n = -n
        ends = ell / 2 if order == 1 else ell / 6
        parts = [(("V", va.nr), pa, ends), (("V", vb.nr), pb, ends)]
        if order == 2:
            parts.append((("E", edge.nr), (pa + pb) / 2, 2 * ell / 3))
        for key, p, w in parts:
            weight[key] = weight.get(key, 0.0) + w
            nsum[key] = nsum.get(key, 0.0) + ell * n
            coords[key] = p
    keys = [k for k in weight if not clamped(k)]
    if not keys:
        raise ValueError(f"contact: boundary {contact!r} has no unclamped node on this mesh")
    xc = np.array([coords[k] for k in keys])
    order = np.lexsort((xc[:, 1], xc[:, 0]))
    keys = [keys[i] for i in order]
    normals = np.array([nsum[k] / np.linalg.norm(nsum[k]) for k in keys])
    return keys, xc[order], np.array([weight[k] for k in keys]), normals


def _point_evaluation(mesh: ng.Mesh, scalar: ng.comp.FESpace, points: np.ndarray,
                      vertex: np.ndarray | None = None) -> sp.csr_matrix:
    """E[i, j] = phi_j(points[i]) for the scalar space's basis.

    ``vertex[i]`` >= 0 says that point i is that vertex: its row is then the unit row of the
    vertex's dof (H1 gives vertex v the dof v, and every other basis function vanishes there),
    without locating the point (0.5 ms a point at 1e6 unknowns).

    NGSolve 6.2.2608 has no nodal P2 basis (the H1 flag ``nodalp2`` is not
    recognised), its P2 basis is hierarchical: vertex hat functions plus edge
    bubbles.  So a midpoint value is (U_a + U_b)/2 + phi_e(mid) U_e; we get these
    coefficients by evaluating the element's shape functions at the point (for P1 and
    at vertices this just selects the vertex dof).
    """
    rows, cols, vals = [], [], []
    for i, (x, y) in enumerate(points):
        if vertex is not None and vertex[i] >= 0:
            rows.append(i); cols.append(int(vertex[i])); vals.append(1.0)
            continue
        mp = mesh(x, y)
        el = ng.ElementId(ng.VOL, mp.nr)
        shape = np.array(scalar.GetFE(el).CalcShape(*mp.pnt[:2]))
        for j, s in zip(scalar.GetDofNrs(el), shape):
            if abs(s) > 1e-12:
                rows.append(i); cols.append(j); vals.append(s)
    return sp.csr_matrix((vals, (rows, cols)), shape=(len(points), scalar.ndof))


def _stick_components(scene: Scene, normals: np.ndarray) -> dict:
    """Component-wise Dirichlet flags for u.t = 0 on an axis-aligned straight Gamma_C."""
    if np.allclose(np.abs(normals[:, 1]), 1, atol=1e-10):
        return {"dirichletx": scene.contact}
    if np.allclose(np.abs(normals[:, 0]), 1, atol=1e-10):
        return {"dirichlety": scene.contact}
    raise ValueError(f"tangential = 'stick' is supported only for a straight contact boundary parallel "
                     f"to the x or y axis; {scene.contact!r} is not (use tangential = 'frictionless')")


def assemble(scene: Scene, mesh: ng.Mesh | None = None) -> ContactOperators:
    """Assemble K, f, B, mc, g of the scene on the free dofs (see ContactOperators).

    ``mesh``: a mesh of the scene's body to use instead of the scene's own (an adapted one).
    """
    mesh = build_mesh(scene) if mesh is None else mesh
    known = set(mesh.GetBoundaries())
    for label in (*scene.dirichlet, *scene.tractions, scene.contact):
        if label not in known:
            raise ValueError(f"unknown boundary label {label!r}; known labels: {', '.join(sorted(known))}")
    nodes, xc, mc, normals = contact_nodes(mesh, scene)
    if scene.contact_normal is not None:   # a flat obstacle's fixed direction instead of the body's normals
        normals = np.tile(np.asarray(scene.contact_normal, dtype=float), (len(xc), 1))
    g = np.array([scene.gap_at(x, y) for x, y in xc])
    if not np.all(np.isfinite(g)):
        raise ValueError(f"gap: not finite at the contact nodes {xc[~np.isfinite(g)].tolist()}")

    fes = displacement_space(scene, mesh, normals)
    u, v = fes.TnT()
    mu, lam = lame(scene.E, scene.nu)
    eps = lambda w: ng.Sym(ng.Grad(w))  # noqa: E731
    div = lambda w: ng.Trace(ng.Grad(w))  # noqa: E731
    a = ng.BilinearForm(fes)
    a += (2 * mu * ng.InnerProduct(eps(u), eps(v)) + lam * div(u) * div(v)) * ng.dx
    with ngsolve_tasks(mesh.ne):
        a.Assemble()
    l = ng.LinearForm(fes)
    for label, t in scene.tractions.items():
        l += _vector_cf(t) * v * ng.ds(definedon=mesh.Boundaries(label), bonus_intorder=2 * callable(t))
    if scene.body_force is not None:
        l += _vector_cf(scene.body_force) * v * ng.dx(bonus_intorder=2 * callable(scene.body_force))
    l.Assemble()

    free, K, f = free_system(fes, a, l.vec.FV().NumPy())
    vertex = np.array([key[1] if key[0] == "V" else -1 for key in nodes])
    B, T, tangents = normal_tangential_maps(mesh, scene.order, xc, normals, free, vertex=vertex)
    return ContactOperators(K=K, f=f, B=B, mc=mc, g=g, xc=xc, normals=normals, free=free,
                            mesh=mesh, fes=fes, scene=scene, T=T, tangents=tangents,
                            friction=friction_of(scene, xc))


def displacement_space(scene: Scene, mesh: ng.Mesh, normals: np.ndarray) -> ng.comp.FESpace:
    """The scene's VectorH1 space on ``mesh``: its order, clamped on the Dirichlet labels (and, with
    ``tangential = "stick"``, the tangential component clamped on Gamma_C; ``normals`` at the contact nodes)."""
    flags = _stick_components(scene, normals) if scene.tangential == "stick" else {}
    return ng.VectorH1(mesh, order=scene.order, dirichlet="|".join(scene.dirichlet), **flags)


def free_system(fes: ng.comp.FESpace, a: ng.BilinearForm, load: np.ndarray):
    """(free, K, f): the free dofs of ``fes``, the assembled form ``a`` and the load (one value per dof) on them."""
    free = free_dofs(fes)
    K = free_matrix(a.mat, free)
    f = np.asarray(load)[free].copy()
    return free, K, f


def normal_tangential_maps(mesh: ng.Mesh, order: int, xc: np.ndarray, normals: np.ndarray, free: np.ndarray,
                           vertex: np.ndarray | None = None):
    """(B, T, tangents) of a 2D VectorH1 space of ``order``: u.n and u.t at the contact nodes xc, on the free dofs.

    ``vertex``: the vertex each node is (-1 for an edge midpoint), as :func:`_point_evaluation` takes it.
    """
    # u.n at x_i = n_x u_x(x_i) + n_y u_y(x_i); VectorH1 numbers the y-component dofs after all x ones
    scalar = ng.H1(mesh, order=order)
    E = _point_evaluation(mesh, scalar, xc, vertex)
    tangents = tangent_frames(normals)
    B = component_map(E, normals[:, :2], free, 2 * scalar.ndof)
    T = component_map(E, tangents[:, 0, :2], free, 2 * scalar.ndof)
    return B, T, tangents
