"""Figures of a contact solution: the deformed body over the obstacle, pressure and gap on Gamma_C."""
from __future__ import annotations

from pathlib import Path

import numpy as np


def vertex_displacement(ops, u_free: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vertex coordinates, vertex displacements, triangles) of the mesh for plotting."""
    gf = ops.to_gridfunction(u_free)
    mesh = ops.mesh
    xy = np.array([v.point for v in mesh.vertices])
    disp = np.array([gf(mesh(*p)) for p in xy])
    tris = np.array([[v.nr for v in el.vertices] for el in mesh.Elements()])
    return xy, disp, tris


def plot_solution(sol, path: str | Path, magnify: float = 10.0) -> Path:
    """Deformed body (displacement x ``magnify``) with the rigid obstacle, and pressure/gap along Gamma_C."""
    import matplotlib.pyplot as plt

    ops, res = sol.ops, sol.result
    xy, disp, tris = vertex_displacement(ops, res.x)
    fig, (ax, bx) = plt.subplots(2, 1, figsize=(8, 7), gridspec_kw=dict(height_ratios=[2, 1]))
    deformed = xy + magnify * disp
    ax.triplot(deformed[:, 0], deformed[:, 1], tris, lw=0.3, color="tab:blue")
    order = np.argsort(ops.xc[:, 0])
    xc, g = ops.xc[order], ops.g[order]
    # the foundation lies at distance g from Gamma_C along the outward normal
    obstacle = xc + (g[:, None] * ops.normals[order]) * magnify
    ax.plot(obstacle[:, 0], obstacle[:, 1], color="k", lw=1.5, label=f"obstacle (gap x{magnify:g})")
    ax.set_aspect("equal")
    ax.set_title(f"{ops.scene.name}: deformed body, displacement x{magnify:g} ({res.status}, {res.iterations} it.)")
    ax.legend(loc="upper right", fontsize=8)
    un = ops.B @ res.x
    bx.plot(xc[:, 0], res.lam[order], label="contact pressure lambda", color="tab:red")
    bx.set_xlabel("x on Gamma_C")
    bx.set_ylabel("pressure")
    tx = bx.twinx()
    tx.plot(xc[:, 0], (ops.g - un)[order], color="tab:green", label="gap g - u_n")
    tx.set_ylabel("gap")
    bx.legend(loc="upper left", fontsize=8)
    tx.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return path
