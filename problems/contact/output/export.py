"""Exports of a contact solution: VTU for ParaView and meshio, JSON with provenance.

The VTU (written with meshio, double precision) has one point per mesh vertex
(and, for P2, one per edge midpoint, with quadratic cells), shared by the
cells, so ParaView's "Warp By Vector" and any meshio reader see one connected
body.  Point data:

- ``displacement``: u at every point (3 components; z = 0 in 2D);
- on the contact boundary Gamma_C (NaN elsewhere): ``contact_pressure``
  (lam), ``gap`` (g - u_n), ``initial_gap`` (g), ``normal_displacement``
  (u_n); and ``contact_status``: 1 active, 0 inactive, -1 off Gamma_C;
- with friction (Tresca or Coulomb), also on Gamma_C: ``tangential_traction``
  (q = -sigma_t) and ``slip`` (T u - w) as vectors in x, y, z (3 components,
  sum_j q_j t_j), and ``stick_slip_zone``: 0 separated, 1 stick, 2 slip,
  -1 off Gamma_C (:func:`vtu_fields`).

A node is *active* where the last z-step put p on the obstacle (p = g), the
definition of the KKT's ``active_nodes`` count (problems/contact/solvers/problem.py)
and of the command line's "active nodes": :func:`contact_status` is the one
place that says it.  More boundary arrays (a tangential traction, a slip) are
one more entry in the dict :func:`boundary_fields` returns, or in the
``boundary`` argument of :func:`write_vtu`.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from admmkit.cli.output import jsonable, provenance, result_record
from admmkit.io import atomic_path, is_stream, write_text

#: VTU cell types by (dimension, polynomial order); order 2 uses the points at the edge midpoints
CELL_TYPES = {(2, 1): "triangle", (2, 2): "triangle6", (3, 1): "tetra", (3, 2): "tetra10"}


def contact_status(ops, p: np.ndarray) -> np.ndarray:
    """Boolean mask of the active contact nodes: where the z-step put p on the obstacle (p >= g).

    ``p`` is the last z-step's normal part (``result.z[:n_c]``; with friction z also holds tangential parts).
    """
    p = np.asarray(p, dtype=float)[: ops.n_c]
    if p.shape != ops.g.shape:
        raise ValueError(f"p must have one value per contact node, shape {ops.g.shape}, got {p.shape}")
    return p >= ops.g


def _dim(ops) -> int:
    dim = getattr(ops, "dim", None)          # ContactOperators know it without the mesh (the operator cache)
    return int(ops.mesh.dim if dim is None else dim)


def _order(ops) -> int:
    order = int(getattr(ops.scene, "order", 1))
    return order if order in (1, 2) else 1


def mesh_points(ops) -> tuple[np.ndarray, str, np.ndarray]:
    """(points (n_points, 3), VTU cell type, cells): the vertices, then for P2 the edge midpoints.

    Point ``i < nv`` is vertex ``i``; point ``nv + e`` is the midpoint of edge ``e`` (P2 only),
    the numbering of NGSolve's VectorH1 dofs in each component.
    """
    import ngsolve as ng
    mesh, dim, order = ops.mesh, _dim(ops), _order(ops)
    vertices = np.array(mesh.ngmesh.Coordinates(), dtype=float)[:, :dim]
    cells = np.array([[v.nr for v in el.vertices] for el in mesh.Elements(ng.VOL)], dtype=np.int64)
    points = vertices
    if order == 2:
        ends = np.array([[v.nr for v in mesh[ng.NodeId(ng.EDGE, e)].vertices] for e in range(mesh.nedge)])
        points = np.vstack([vertices, vertices[ends].mean(axis=1)])
        edge_of = {tuple(sorted(pair)): e for e, pair in enumerate(ends.tolist())}
        # VTK order of the mid-edge nodes: triangle6 (01, 12, 20); tetra10 (01, 12, 20, 03, 13, 23)
        pairs = [(0, 1), (1, 2), (2, 0)] if dim == 2 else [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]
        mids = np.array([[mesh.nv + edge_of[tuple(sorted((c[a], c[b])))] for a, b in pairs] for c in cells])
        cells = np.hstack([cells, mids])
    padded = np.zeros((len(points), 3))
    padded[:, :dim] = points
    return padded, CELL_TYPES[dim, order], cells


def point_displacement(ops, u_free: np.ndarray) -> np.ndarray:
    """u at the points of :func:`mesh_points`, shape (n_points, 3) (z = 0 in 2D).

    Vertex values are the vertex dofs (nodal values); P2 midpoint values are the
    finite element function evaluated there (the hat functions and the edge bubble).
    """
    dim, nv = _dim(ops), ops.mesh.nv
    full = ops.full_vector(np.asarray(u_free, dtype=float))
    block = ops.fes.ndof // dim
    disp = np.zeros((nv, 3))
    for c in range(dim):
        disp[:, c] = full[c * block:c * block + nv]
    if _order(ops) == 2:
        points, _, _ = mesh_points(ops)
        mids = points[nv:, :dim]
        gf = ops.to_gridfunction(u_free)
        values = np.asarray(gf(ops.mesh(*mids.T)), dtype=float).reshape(len(mids), dim)
        disp = np.vstack([disp, np.pad(values, ((0, 0), (0, 3 - dim)))])
    return disp


def contact_point_index(ops, points: np.ndarray | None = None) -> np.ndarray:
    """Index of each contact node among the points of :func:`mesh_points` (matched by coordinates)."""
    from scipy.spatial import cKDTree
    points = mesh_points(ops)[0] if points is None else points
    dim = ops.xc.shape[1]
    dist, index = cKDTree(points[:, :dim]).query(ops.xc)
    scale = max(float(np.ptp(points, axis=0).max()), 1e-300)
    if dist.size and dist.max() > 1e-9 * scale:
        raise ValueError(f"contact nodes do not lie on mesh points (largest distance {dist.max():.3e})")
    return index


def free_dof_map(ops) -> dict[str, np.ndarray]:
    """For every free dof: its displacement ``component`` (0 = x, 1 = y, 2 = z) and its ``point`` in the VTU."""
    dim = _dim(ops)
    block = ops.fes.ndof // dim
    free = np.asarray(ops.free)
    return {"component": free // block, "point": free % block}


def boundary_fields(ops, u_free: np.ndarray, lam: np.ndarray, p: np.ndarray) -> dict[str, np.ndarray]:
    """Per contact node: pressure lam, gap g - u_n, initial gap g, u_n and the status (1 active, 0 inactive).

    ``lam`` and ``p`` are the result's multiplier and z; their first n_c entries are the normal parts.
    With friction (``ops.friction``) also :func:`friction_fields`.
    """
    un = ops.B @ np.asarray(u_free, dtype=float)
    fields = {"contact_pressure": np.asarray(lam, dtype=float)[: ops.n_c], "gap": ops.g - un,
              "initial_gap": ops.g.copy(), "normal_displacement": un,
              "contact_status": contact_status(ops, p).astype(np.int8)}
    if getattr(ops, "friction", None) is not None:
        fields |= friction_fields(ops, u_free, lam, p)
    return fields


def friction_fields(ops, u_free: np.ndarray, lam: np.ndarray, z: np.ndarray) -> dict[str, np.ndarray]:
    """Per contact node, with friction: ``tangential_traction`` q = lam_t, ``slip`` T u - w (both along the
    tangents t of ``ops.tangents``: shape (n_c,) in 2D, (n_c, 2) in 3D), ``slip_bound`` s (the last one used:
    Tresca's, or mu p_n of Coulomb's last fixed-point step) and ``stick_slip_zone`` (0 separated, 1 stick,
    2 slip; ``admmkit.problems.contact.solvers.friction.stick_slip``)."""
    from admmkit.problems.contact.solvers.friction import stick_slip
    n_c, friction = ops.n_c, ops.friction
    lam, z = np.asarray(lam, dtype=float), np.asarray(z, dtype=float)
    if lam.shape != (ops.T.shape[0] + n_c,) or z.shape != lam.shape:
        raise ValueError(f"lam and z must hold the normal and tangential parts ({ops.T.shape[0] + n_c} values), "
                         f"got shapes {lam.shape} and {z.shape}")
    w = 0.0 if friction.slide is None else friction.slide.T
    q = lam[n_c:].reshape(-1, n_c)
    slip = (ops.T @ np.asarray(u_free, dtype=float)).reshape(-1, n_c) - w
    squeeze = (lambda a: a[0]) if len(q) == 1 else (lambda a: a.T.copy())   # 2D: (n_c,); 3D: (n_c, 2)
    return {"tangential_traction": squeeze(q), "slip": squeeze(slip), "slip_bound": friction.s.copy(),
            "stick_slip_zone": stick_slip(z, ops.g, friction.slide).astype(np.int8)}


def tangential_vector(ops, components: np.ndarray) -> np.ndarray:
    """(n_c, 3): sum_j c_j t_j, the tangential components of :func:`friction_fields` as vectors in x, y, z."""
    c = np.asarray(components, dtype=float).reshape(ops.n_c, -1)
    vectors = np.einsum("ij,ijk->ik", c, ops.tangents)
    return np.pad(vectors, ((0, 0), (0, 3 - vectors.shape[1])))


def vtu_fields(ops, fields: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The boundary fields as the VTU carries them: the tangential traction and the slip as 3-vectors in
    x, y, z (:func:`tangential_vector`), so that ParaView draws them as glyphs; the rest unchanged."""
    out = dict(fields)
    for name in ("tangential_traction", "slip"):
        if name in out:
            out[name] = tangential_vector(ops, out[name])
    return out


def write_vtu(path: str | Path, ops, u_free: np.ndarray, boundary: dict[str, np.ndarray] | None = None,
              cells: dict[str, np.ndarray] | None = None) -> Path:
    """Write the displacement, the boundary arrays (one value per contact node) and the cell arrays (one value
    per element, e.g. error indicators) as a VTU file.

    Written with meshio in double precision, whole or not at all (a temporary
    file renamed into place).  Returns the path (``.vtu`` appended to a file name without it; a stream, see
    :mod:`admmkit.io`, keeps its name).
    """
    import meshio
    path = Path(path)
    if path.suffix.lower() != ".vtu" and not is_stream(path):
        path = path.with_name(path.name + ".vtu")       # the Python API's stem (the CLI refuses other names)
    points, cell_type, elements = mesh_points(ops)
    data = {"displacement": point_displacement(ops, u_free)}
    if boundary:
        where = contact_point_index(ops, points)
        for name, values in boundary.items():
            values = np.asarray(values)
            if values.shape[:1] != (ops.n_c,):
                raise ValueError(f"boundary array {name!r} must have one value per contact node ({ops.n_c}), "
                                 f"got shape {values.shape}")
            integer = np.issubdtype(values.dtype, np.integer)
            full = np.full((len(points),) + values.shape[1:], -1 if integer else np.nan,
                           dtype=np.int32 if integer else float)
            full[where] = values
            data[name] = full
    cell_data = {}
    for name, values in (cells or {}).items():
        values = np.asarray(values, dtype=float)
        if values.shape != (len(elements),):
            raise ValueError(f"cell array {name!r} must have one value per element ({len(elements)}), "
                             f"got shape {values.shape}")
        cell_data[name] = [values]
    mesh = meshio.Mesh(points, [(cell_type, elements)], point_data=data, cell_data=cell_data)
    with atomic_path(path) as tmp:
        meshio.write(tmp, mesh, file_format="vtu")
    return path


def scene_parameters(scene) -> dict:
    """The scene's fields as JSON values (expressions as their text)."""
    import dataclasses
    if not dataclasses.is_dataclass(scene):
        return {"scene": str(scene)}
    return jsonable({f.name: getattr(scene, f.name) for f in dataclasses.fields(scene) if f.name != "geometry"}
                    | {"geometry": None if getattr(scene, "geometry", None) is None else "netgen geometry"})


def write_json(path: str | Path, sol, args=None, **extra) -> Path:
    """JSON of a solved scene (a :class:`~admmkit.problems.contact.solvers.methods.ContactSolution`).

    Keys: ``provenance`` (admmkit version, UTC date, command line, policy,
    order, rho_0, stopping rule, max_iter), ``scene`` (its parameters),
    ``result`` (status, iterations, rho, KKT, work, times), ``sizes`` and
    ``arrays``: ``u`` (free dofs), ``dof_component`` and ``dof_point``
    (free dof -> component and VTU point), ``contact_point`` (contact node ->
    VTU point), ``contact_xy`` and the boundary fields of :func:`boundary_fields`.
    With friction also ``arrays.tangents`` (n_c, d-1, d), ``sizes.stick_nodes`` and
    ``sizes.slip_nodes``, ``result.friction`` (law, mu, tangential force sum M_c q);
    with Coulomb ``result.coulomb`` (the outer fixed point: Tresca solves, ADMM
    iterations per solve, change of s per solve, converged) and ``result.converged``
    then says whether both the last ADMM run and the fixed point converged.
    """
    ops, r = sol.ops, sol.result
    dofs = free_dof_map(ops)
    fields = boundary_fields(ops, r.x, r.lam, r.z)
    arrays = {"u": r.x, "dof_component": dofs["component"], "dof_point": dofs["point"],
              "contact_point": contact_point_index(ops), "contact_xy": ops.xc, "z": r.z, "lam": r.lam, **fields}
    sizes = {"n_free": int(ops.n_free), "n_c": int(ops.n_c), "n_points": int(len(mesh_points(ops)[0])),
             "active_nodes": int(fields["contact_status"].sum())}
    record = result_record(r) | {"mode": sol.mode, "setup_time": sol.setup_time}
    if ops.friction is not None:
        arrays["tangents"] = ops.tangents
        zones = fields["stick_slip_zone"]
        sizes |= {"stick_nodes": int(np.sum(zones == 1)), "slip_nodes": int(np.sum(zones == 2))}
        record["friction"] = {"law": ops.friction.law, "mu": ops.friction.mu,
                              "tangential_force": ops.mc @ np.asarray(fields["tangential_traction"]).reshape(ops.n_c, -1)}
    coulomb = getattr(sol, "coulomb", None)
    if coulomb is not None:
        record["coulomb"] = {"converged": coulomb.converged, "tol": coulomb.tol,
                             "outer_iterations": coulomb.outer_iterations,
                             "total_iterations": coulomb.total_iterations,
                             "inner_iterations": coulomb.inner_iterations, "changes": coulomb.changes,
                             "summary": coulomb.summary()}
        record["converged"] = bool(sol.converged)
    data = {"provenance": provenance(args, **extra), "scene": scene_parameters(ops.scene),
            "result": jsonable(record), "sizes": sizes, "arrays": jsonable(arrays)}
    return write_text(path, json.dumps(data, indent=1) + "\n")
