"""Contact operators from your own NGSolve mesh, space and forms (issue #18).

A :class:`~admmkit.problems.contact.model.scene.Scene` describes a rectangle (or a netgen
geometry) of an isotropic plane-strain material.  Anything else, an
unstructured mesh of your own, an orthotropic or graded material, extra terms
in the energy, a point load, is written in NGSolve and handed in here:

    fes = ngsolve.VectorH1(mesh, order=1, dirichlet="left")
    u, v = fes.TnT()
    a = ngsolve.BilinearForm(fes); a += InnerProduct(C * strain(u), strain(v)) * dx
    f = ngsolve.LinearForm(fes);   f += CF((0, -10)) * v * ds("top")
    ops = contact_operators(fes, a, f, contact="bottom", gap=0.01)
    sol = solve_scene(ops, "sadmm", rho=1e3)

The discrete problem is the one of :func:`admmkit.problems.contact.model.assembly.assemble`,
min 1/2 u'Ku - f'u s.t. B u <= g (and Tresca's term with friction), with K
and f your forms on the free dofs of your space (its Dirichlet flags clamp),
and B, M_c, g built on the contact boundary exactly as there (in 2D the same
functions: ``boundary_nodes``, ``normal_tangential_maps`` of
problems/contact/model/assembly.py; on a 3D P1 tetrahedral mesh ``face_nodes``
and ``vertex_maps``, which give the operators of ``assemble3d`` on its block).  The result is a
:class:`~admmkit.problems.contact.model.assembly.ContactOperators` that
:func:`~admmkit.problems.contact.solvers.methods.solve_scene` and
:func:`~admmkit.problems.contact.solvers.problem.contact_problem` take in every mode (full,
condensed, iterative), and that the VTU and JSON exports write.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import ngsolve as ng
import numpy as np

from admmkit.problems.contact.model.assembly import ContactOperators, boundary_nodes, free_system, normal_tangential_maps
from admmkit.problems.expressions import as_function
from admmkit.problems.contact.solvers.friction import TANGENTIAL, check_friction_fields, friction_of
from admmkit.problems.contact.model.scene import _unit_pair, check_slide


@dataclass(frozen=True)
class CustomScene:
    """What :func:`contact_operators` was given, in the fields the plug-in reads from a scene.

    ``h`` is the longest edge of the mesh; ``gap`` as given (a number, a
    callable f(x, y), an expression or an NGSolve CoefficientFunction).
    """

    contact: str
    gap: Any
    h: float
    order: int
    tangential: str = "frictionless"
    slip_bound: Any = None
    mu: Any = None
    obstacle_slide: Any = 0.0
    contact_normal: Any = None
    name: str = "custom"
    mesh_kind: str = "user mesh"

    def gap_at(self, x: float, y: float) -> float:
        """g(x, y) for a number, callable or expression gap (a CoefficientFunction needs the mesh: ops.g)."""
        if isinstance(self.gap, ng.CoefficientFunction):
            raise ValueError("gap is a CoefficientFunction: read its values at the contact nodes from ops.g")
        return float(self.gap(x, y)) if callable(self.gap) else float(self.gap)


def contact_operators(fes, a, f, contact: str = "bottom", gap=0.0, *, normal=None, tangential: str = "frictionless",
                      slip_bound=None, mu=None, obstacle_slide=None, name: str = "custom") -> ContactOperators:
    """Contact operators of your own NGSolve space and forms (module docstring).

    ``fes``: an ``ngsolve.VectorH1`` of order 1 or 2 on a 2D mesh, or of
    order 1 on a 3D tetrahedral mesh (``face_nodes``); its
    Dirichlet flags are the clamped boundary (``dirichlet="left"``; for
    ``tangential="stick"`` also ``dirichletx``/``dirichlety`` on the contact
    boundary).  ``a``: an ``ngsolve.BilinearForm`` on ``fes``, the elastic
    energy (symmetric, positive definite on the free dofs; assembled here if it
    is not yet; not ``condense=True``).  ``f``: an ``ngsolve.LinearForm`` on
    ``fes`` (assembled here if its vector is still zero) or an array of one
    value per dof of ``fes``.  ``contact``: the boundary label of Gamma_C.
    ``gap``: g >= u.n there, a number, a callable f(x, y), an expression in
    x, y (in 3D of the node's x, y, as in a 3D scene) or a
    CoefficientFunction.  ``normal``: None measures u.n along the body's
    outward normal at each contact node, a fixed direction (nx, ny[, nz])
    along that (a flat obstacle).  ``tangential``, ``slip_bound``,
    ``mu``, ``obstacle_slide``: as in :class:`~admmkit.problems.contact.model.scene.Scene`.
    Bad input raises TypeError or ValueError naming the parameter.
    """
    mesh = _check_space(fes)
    order = int(fes.globalorder)
    K_form = _check_bilinear(a, fes)
    load = _load_vector(f, fes)
    known = set(mesh.GetBoundaries())
    if not isinstance(contact, str) or contact not in known:
        raise ValueError(f"contact = {contact!r}: not a boundary label of the mesh; known labels: "
                         f"{', '.join(sorted(known - {''}))}")
    if tangential not in TANGENTIAL:
        raise ValueError(f"tangential = {tangential!r}; accepted: {', '.join(TANGENTIAL)}")

    freedofs = np.array(fes.FreeDofs(), dtype=bool)
    kind = {"V": ng.VERTEX, "E": ng.EDGE}

    def clamped(key) -> bool:                 # every dof of the node (all components) is a Dirichlet dof
        return not freedofs[list(fes.GetDofNrs(ng.NodeId(kind[key[0]], key[1])))].any()

    if mesh.dim == 2:
        _, xc, mc, normals = boundary_nodes(mesh, contact, order, clamped)
    else:
        nodes, xc, mc, normals = face_nodes(mesh, contact, lambda v: clamped(("V", v)))
    if normal is not None:
        normals = np.tile(_unit_vector(normal, mesh.dim), (len(xc), 1))
    g = _gap_values(gap, mesh, xc)
    slip = None if slip_bound is None else as_function(slip_bound, "slip_bound")
    check_friction_fields(tangential, slip, mu, [tuple(x[:2]) for x in xc])
    if obstacle_slide is None:
        obstacle_slide = 0.0 if mesh.dim == 2 else (0.0, 0.0)
    check_slide(obstacle_slide, tangential, mesh.dim - 1)
    scene = CustomScene(contact=contact, gap=gap, h=_longest_edge(mesh), order=order, tangential=tangential,
                        slip_bound=slip, mu=mu, obstacle_slide=obstacle_slide,
                        contact_normal=None if normal is None else tuple(normals[0]), name=name)

    free, K, f_free = free_system(fes, K_form, load)
    if mesh.dim == 2:
        B, T, tangents = normal_tangential_maps(mesh, order, xc, normals, free)
    else:
        B, T, tangents = vertex_maps(fes, nodes, normals, free)
    if tangential == "stick" and T.nnz:
        raise ValueError("tangential = 'stick' needs the tangential displacement clamped on the contact boundary "
                         f"by the space: VectorH1(..., dirichletx={contact!r}) or dirichlety (u.t is free here)")
    return ContactOperators(K=K, f=f_free, B=B, mc=mc, g=g, xc=xc, normals=normals, free=free, mesh=mesh, fes=fes,
                            scene=scene, T=T, tangents=tangents, friction=friction_of(scene, xc))


# ---------------------------------------------------------------- 3D, P1
def face_nodes(mesh: ng.Mesh, contact: str, clamped):
    """The vertices of the triangles of the 3D boundary ``contact`` for which ``clamped(vertex)`` is false.

    Returns (nodes, xc, mc, normals) sorted by x, then y, then z: mc = a third of the area of every adjacent
    triangle (the lumped mass of P1), normals = the area-weighted average of their outward normals (each
    turned away from the tetrahedron beside it), normalised.
    """
    points = np.array(mesh.ngmesh.Coordinates(), dtype=float)
    tris = np.array([[v.nr for v in el.vertices] for el in mesh.Elements(ng.BND) if el.mat == contact])
    if tris.ndim != 2 or tris.shape[1] != 3:
        raise ValueError(f"contact: boundary {contact!r} must be made of triangles (P1 tetrahedral mesh)")
    P = points[tris]
    cross = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    beside = _opposite_vertices(mesh, tris)                       # the 4th vertex of the tetrahedron beside
    cross[np.sum(cross * (points[beside] - P[:, 0]), axis=1) > 0] *= -1      # point out of the body
    nv = mesh.nv
    weight = np.bincount(tris.ravel(), weights=np.repeat(area / 3, 3), minlength=nv)
    nsum = np.zeros((nv, 3))
    np.add.at(nsum, tris.ravel(), np.repeat(cross / 2, 3, axis=0))   # area times the unit normal
    nodes = np.array(sorted(v for v in set(tris.ravel().tolist()) if not clamped(v)), dtype=int)
    if not nodes.size:
        raise ValueError(f"contact: boundary {contact!r} has no unclamped node on this mesh")
    xc = points[nodes]
    order = np.lexsort((xc[:, 2], xc[:, 1], xc[:, 0]))
    nodes, xc = nodes[order], xc[order]
    normals = nsum[nodes] / np.linalg.norm(nsum[nodes], axis=1, keepdims=True)
    return nodes, xc, weight[nodes], normals


def _opposite_vertices(mesh: ng.Mesh, tris: np.ndarray) -> np.ndarray:
    """For each boundary triangle, the vertex of the tetrahedron it bounds that is not on it."""
    tets = np.array([[v.nr for v in el.vertices] for el in mesh.Elements(ng.VOL)])
    opposite = {}
    for k in range(4):
        face = np.sort(np.delete(tets, k, axis=1), axis=1)
        opposite.update(zip(map(tuple, face.tolist()), tets[:, k].tolist()))
    return np.array([opposite[tuple(t)] for t in np.sort(tris, axis=1).tolist()])


def vertex_maps(fes, nodes: np.ndarray, normals: np.ndarray, free: np.ndarray):
    """(B, T, tangents) of a P1 VectorH1 space: u.n and u.t at the vertices ``nodes``, on the free dofs."""
    import scipy.sparse as sp

    from admmkit.problems.contact.solvers.friction import tangent_frames
    dofs = np.array([fes.GetDofNrs(ng.NodeId(ng.VERTEX, int(v))) for v in nodes])        # (n_c, 3): x, y, z
    tangents = tangent_frames(normals)
    n_c, rows = len(nodes), np.repeat(np.arange(len(nodes)), 3)

    def along(directions):                    # row i: directions[i] . u(x_i)
        return sp.csr_matrix((directions.ravel(), (rows, dofs.ravel())), shape=(n_c, fes.ndof))[:, free]

    B = along(normals).tocsr()
    T = sp.vstack([along(tangents[:, j]) for j in range(tangents.shape[1])]).tocsr()
    B.eliminate_zeros()
    T.eliminate_zeros()
    return B, T, tangents


# ---------------------------------------------------------------- checks of the input
def _check_space(fes) -> ng.Mesh:
    """The mesh of a VectorH1 space of order 1 or 2 in 2D, 1 in 3D (TypeError or ValueError naming ``fes`` otherwise)."""
    if not isinstance(fes, ng.comp.FESpace) or fes.type != "VectorH1":
        raise TypeError(f"fes must be an ngsolve.VectorH1 space (its dofs numbered by component), "
                        f"got {getattr(fes, 'type', type(fes).__name__)!r}")
    mesh = fes.mesh
    if fes.globalorder not in ((1, 2) if mesh.dim == 2 else (1,)):
        accepted = "1 or 2 (the lumped mass is trapezoid or Simpson)" if mesh.dim == 2 else "1 in 3D"
        raise ValueError(f"fes: order {fes.globalorder}; accepted: {accepted}")
    return mesh


def _check_bilinear(a, fes):
    """``a`` on ``fes``, assembled (TypeError or ValueError naming ``a`` otherwise)."""
    if not isinstance(a, ng.BilinearForm):
        raise TypeError(f"a must be an ngsolve.BilinearForm on fes, got {type(a).__name__}")
    if a.space is not fes:
        raise ValueError("a: the bilinear form is defined on another space than fes")
    if a.condense:
        raise ValueError("a: condense=True gives the Schur complement, not K; build the form without it")
    try:
        a.mat
    except TypeError:                        # "matrix not ready - assemble bilinearform first"
        a.Assemble()
    return a


def _load_vector(f, fes) -> np.ndarray:
    """The load on every dof: a LinearForm's vector (assembled if still zero), or an array (TypeError or ValueError naming ``f``)."""
    if isinstance(f, ng.LinearForm):
        if f.space is not fes:
            raise ValueError("f: the linear form is defined on another space than fes")
        if not np.any(f.vec.FV().NumPy()):
            f.Assemble()
        return f.vec.FV().NumPy().copy()
    try:
        values = np.asarray(f, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"f must be an ngsolve.LinearForm on fes or an array of {fes.ndof} numbers, "
                        f"got {type(f).__name__}") from None
    if values.shape != (fes.ndof,) or not np.all(np.isfinite(values)):
        raise ValueError(f"f: expected {fes.ndof} finite numbers (one per dof of fes), got shape {values.shape}")
    return values.copy()


def _unit_vector(value, dim: int) -> np.ndarray:
    """``normal``: dim finite numbers, not all zero, scaled to unit length."""
    if dim == 2:
        return np.asarray(_unit_pair(value, "normal"), dtype=float)
    ok = isinstance(value, (list, tuple)) and len(value) == dim and all(
        isinstance(c, (int, float)) and not isinstance(c, bool) and math.isfinite(c) for c in value)
    norm = math.sqrt(sum(c * c for c in value)) if ok else 0.0
    if norm == 0.0:
        raise ValueError(f"normal = {value!r}; accepted: None or {dim} finite numbers, not all 0")
    return np.asarray(value, dtype=float) / norm


def _gap_values(gap, mesh: ng.Mesh, xc: np.ndarray) -> np.ndarray:
    """g at the contact nodes: a CoefficientFunction at the node, anything else at its (x, y) (as in 3D scenes);
    ValueError naming ``gap`` for bad or non-finite values."""
    if isinstance(gap, ng.CoefficientFunction):
        g = np.array([float(gap(mesh(*x))) for x in xc])
    else:
        func = as_function(gap, "gap")
        try:
            g = np.array([float(func(x[0], x[1])) if callable(func) else func for x in xc])
        except Exception as err:
            raise ValueError(f"gap: evaluating it at the contact nodes failed: {err}") from None
    if not np.all(np.isfinite(g)):
        raise ValueError(f"gap: not finite at the contact nodes {xc[~np.isfinite(g)].tolist()}")
    return g


def _longest_edge(mesh: ng.Mesh) -> float:
    """The mesh size h: the longest edge."""
    points = np.array(mesh.ngmesh.Coordinates())
    ends = np.array([[v.nr for v in e.vertices] for e in mesh.edges])
    return float(np.linalg.norm(points[ends[:, 0]] - points[ends[:, 1]], axis=1).max()) if len(ends) else math.nan
