"""Plot of an obstacle solution: a section through u and psi, and the contact set over the mesh."""
from __future__ import annotations

import math

import numpy as np

from admmkit.figures import pyplot, save_figure

from .scene import A_STAR, has_radial_exact


def plot_solution(problem, u, z, path):
    """Write a PNG: u and psi along the line y = centre, and the contact set over the mesh."""
    plt = pyplot()

    full = problem.full_vector(u)
    x, y = problem.nodes.T
    psi_all = problem.scene.evaluate("psi", x, y)
    x0, x1, y0, y1 = problem.scene.box
    yc = y[np.argmin(np.abs(y - (y0 + y1) / 2))]
    line = np.flatnonzero(np.isclose(y, yc))
    line = line[np.argsort(x[line])]
    contact = problem.contact_set(z)

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.5))
    ax1.plot(x[line], full[line], "b-", label="u_h")
    ax1.plot(x[line], psi_all[line], "k--", label="psi")
    if problem.scene.exact is not None:
        xs = np.linspace(x0, x1, 801)
        ax1.plot(xs, problem.scene.exact(xs, np.full_like(xs, yc)), "r:", label="exact u")
    ax1.set_xlabel("x"); ax1.set_title(f"section y = {yc:g}"); ax1.legend()
    tri = ax2.tricontourf(x, y, full, levels=30, cmap="viridis")
    fig.colorbar(tri, ax=ax2, label="u_h")
    free = problem.nodes[problem.free]
    ax2.plot(free[contact, 0], free[contact, 1], "w.", ms=2, label="contact set")
    if has_radial_exact(problem.scene):
        t = np.linspace(0, 2 * math.pi, 200)
        ax2.plot(A_STAR * np.cos(t), A_STAR * np.sin(t), "r-", lw=1, label="r = a*")
    ax2.set_aspect("equal"); ax2.set_title(f"{problem.scene.name}: u_h and contact set"); ax2.legend(loc="upper right")
    fig.tight_layout()
    return save_figure(fig, path, ("png",), dpi=120)[0]


def plot_adapted(problem, indicators, z, path):
    """Write a PNG: the adapted mesh coloured by the ZZ indicators, with the contact set (and r = a*, radial)."""
    plt = pyplot()
    from .estimate import zz
    tri = zz(problem).tri
    x, y = problem.nodes.T
    fig, ax = plt.subplots(figsize=(6.5, 5.5))
    shade = ax.tripcolor(x, y, tri, facecolors=np.log10(np.maximum(indicators, 1e-16)), cmap="magma_r",
                         edgecolors="k", linewidth=0.1)
    fig.colorbar(shade, ax=ax, label="log10 eta_T (ZZ)")
    free = problem.nodes[problem.free]
    contact = problem.contact_set(z)
    ax.plot(free[contact, 0], free[contact, 1], "c.", ms=0.8, alpha=0.5, label="contact set")
    if has_radial_exact(problem.scene):
        t = np.linspace(0, 2 * math.pi, 200)
        ax.plot(A_STAR * np.cos(t), A_STAR * np.sin(t), "b-", lw=1, label="r = a* (exact free boundary)")
    ax.set_aspect("equal"); ax.legend(loc="upper right", fontsize=8)
    ax.set_title(f"{problem.scene.name}: adapted mesh, {len(tri)} triangles, {problem.n} unknowns")
    fig.tight_layout()
    return save_figure(fig, path, ("png",), dpi=130)[0]
