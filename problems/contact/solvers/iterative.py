"""What the contact plug-in's iterative mode needs from the mesh: the AMG's near-null space.

The iterative mode (:class:`admmkit.problems.contact.solvers.problem.IterativeContact`) solves
the x-step (12) with :class:`admmkit.blocks.iterative.IterativeXSolver`, whose
smoothed-aggregation AMG wants the rigid body modes of the body and the dofs
of each node.  Works in 2D and 3D, P1 and P2.
"""
from __future__ import annotations

import numpy as np

from admmkit.blocks.iterative import node_blocks

from admmkit.problems.contact.model.operators import ContactOperators


def rigid_body_modes(points: np.ndarray, component: np.ndarray) -> np.ndarray:
    """Rigid body modes of linear elasticity at the dofs, the near-null space of K.

    ``points`` (n, d) are the coordinates of the node of each dof and
    ``component`` (n,) the displacement component (0..d-1) the dof carries.
    Returns (n, 3) in 2D (two translations, one rotation) and (n, 6) in 3D
    (three translations, three rotations), the rotations about the centroid.
    """
    points = np.asarray(points, dtype=float)
    component = np.asarray(component)
    if points.ndim != 2 or points.shape[1] not in (2, 3) or component.shape != (points.shape[0],):
        raise ValueError(f"points must be (n, 2) or (n, 3) and component (n,), got {points.shape} and {component.shape}")
    d = points.shape[1]
    if component.size and (component.min() < 0 or component.max() >= d):
        raise ValueError(f"component must be in 0..{d - 1}")
    x = points - points.mean(axis=0)
    # rotation about axis a: u = e_a x (x - centroid); each entry: (component, coordinate, sign)
    rotations = [[(0, 1, -1.0), (1, 0, 1.0)]] if d == 2 else [
        [(1, 2, -1.0), (2, 1, 1.0)],     # about x: (0, -z, y)
        [(2, 0, -1.0), (0, 2, 1.0)],     # about y: (z, 0, -x)
        [(0, 1, -1.0), (1, 0, 1.0)]]     # about z: (-y, x, 0)
    modes = np.zeros((points.shape[0], d + len(rotations)))
    for a in range(d):
        modes[component == a, a] = 1.0
    for j, parts in enumerate(rotations):
        for c, coord, sign in parts:
            mask = component == c
            modes[mask, d + j] = sign * x[mask, coord]
    return modes


def dof_geometry(ops: ContactOperators) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(node, component, points, is_vertex) of every free dof.

    NGSolve's VectorH1 numbers all dofs of component 0, then of component 1
    (and 2); within a component the vertex dofs come first (dof = vertex
    number), then, for P2, the hierarchical edge bubbles, whose point is the
    edge midpoint.  Operators that carry ``vertices`` and ``ndof`` (the 3D block
    built from arrays) are read without NGSolve.
    """
    known = getattr(ops, "vertices", None)        # operators built from arrays know their vertices: no NGSolve
    if known is not None:
        dim, vertices = ops.dim, known
        nv, n_scalar = vertices.shape[0], ops.ndof // ops.dim
    else:
        mesh = ops.mesh
        dim, nv, n_scalar = mesh.dim, mesh.nv, ops.fes.ndof // mesh.dim
        vertices = np.array(mesh.ngmesh.Coordinates())[:, :dim]
    component, scalar = np.divmod(ops.free, n_scalar)
    points = np.empty((n_scalar, dim))
    points[:nv] = vertices[:nv]
    if n_scalar > nv:  # P2: one bubble per edge, numbered like the edges
        edges = np.array([[v.nr for v in e.vertices] for e in ops.mesh.edges])
        points[nv:] = vertices[edges].mean(axis=1)[: n_scalar - nv]
    return scalar, component, points[scalar], scalar < nv


def near_null_space(ops: ContactOperators) -> tuple[np.ndarray, np.ndarray | None]:
    """Rigid body modes on the free dofs (zero on P2 bubbles) and the node blocks for the AMG."""
    node, component, points, is_vertex = dof_geometry(ops)
    modes = rigid_body_modes(points, component)
    modes[~is_vertex] = 0.0   # a rigid motion is linear: the vertex hats represent it exactly
    return modes, node_blocks(node, component, ops.dim)
