"""VTU export of an obstacle solution (meshio): u, psi and the contact set at the nodes, the ZZ indicator per triangle."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from admmkit.io import atomic_path, is_stream

from .estimate import zz


def write_vtu(path, problem, u: np.ndarray, indicators: np.ndarray) -> Path:
    """Write the P1 solution (u on the free nodes, u_D on the boundary) and one indicator per triangle, whole or
    not at all; returns the path (``.vtu`` appended to a file name without it; a stream, see admmkit.io, keeps
    its name)."""
    import meshio
    path = Path(path)
    if path.suffix.lower() != ".vtu" and not is_stream(path):
        path = path.with_name(path.name + ".vtu")       # the Python API's stem (the CLI refuses other names)
    triangles = zz(problem).tri
    if np.shape(indicators) != (len(triangles),):
        raise ValueError(f"indicators must have one value per triangle ({len(triangles)}), "
                         f"got shape {np.shape(indicators)}")
    x, y = problem.nodes.T
    contact = np.zeros(len(x), dtype=np.int32)
    contact[problem.free[problem.contact_set(u)]] = 1
    points = np.column_stack([x, y, np.zeros_like(x)])
    mesh = meshio.Mesh(points, [("triangle", triangles)],
                       point_data={"u": problem.full_vector(u), "psi": problem.scene.evaluate("psi", x, y),
                                   "contact": contact},
                       cell_data={"zz_indicator": [np.asarray(indicators, dtype=float)]})
    with atomic_path(path) as tmp:
        meshio.write(tmp, mesh, file_format="vtu")
    return path
