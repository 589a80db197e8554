"""What the contact plug-in's iterative mode needs from the mesh: the AMG's near-null space.

The iterative mode (:class:`problems.contact.problem.IterativeContact`) solves
the x-step (12) with :class:`admmkit.iterative.IterativeXSolver`, whose
smoothed-aggregation AMG wants the rigid body modes of the body and the dofs
of each node.  Works in 2D and 3D, P1 and P2.
"""
from __future__ import annotations

import numpy as np

from admmkit.iterative import node_blocks, rigid_body_modes

from .assembly import ContactOperators


def dof_geometry(ops: ContactOperators) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(node, component, points, is_vertex) of every free dof.

    NGSolve's VectorH1 numbers all dofs of component 0, then of component 1
    (and 2); within a component the vertex dofs come first (dof = vertex
    number), then, for P2, the hierarchical edge bubbles, whose point is the
    edge midpoint.
    """
    mesh = ops.mesh
    dim = mesh.dim
    n_scalar = ops.fes.ndof // dim
    component, scalar = np.divmod(ops.free, n_scalar)
    vertices = np.array(mesh.ngmesh.Coordinates())[:, :dim]
    points = np.empty((n_scalar, dim))
    nv = mesh.nv
    points[:nv] = vertices[:nv]
    if n_scalar > nv:  # P2: one bubble per edge, numbered like the edges
        edges = np.array([[v.nr for v in e.vertices] for e in mesh.edges])
        points[nv:] = vertices[edges].mean(axis=1)[: n_scalar - nv]
    return scalar, component, points[scalar], scalar < nv


def near_null_space(ops: ContactOperators) -> tuple[np.ndarray, np.ndarray | None]:
    """Rigid body modes on the free dofs (zero on P2 bubbles) and the node blocks for the AMG."""
    node, component, points, is_vertex = dof_geometry(ops)
    modes = rigid_body_modes(points, component)
    modes[~is_vertex] = 0.0   # a rigid motion is linear: the vertex hats represent it exactly
    return modes, node_blocks(node, component, ops.mesh.dim)
