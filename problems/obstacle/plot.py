"""Plots of an obstacle solution: a section through u and psi, the contact set over u_h, and the adapted mesh.

The contact set {u_h = psi} is drawn in one style everywhere: the triangles
whose three vertices touch the obstacle, filled red and hatched
(:data:`CONTACT_STYLE`, legend "contact set u = psi").
"""
from __future__ import annotations

import math

import numpy as np

from admmkit.figures import pyplot, save_figure
from admmkit.problems.mesh_plot import check_indicators, draw_size_panels

from .scene import A_STAR, has_radial_exact

#: how the contact set is drawn: a red hatched fill, never white, distinct from the colour maps beneath it
CONTACT_STYLE = dict(facecolor=(0.84, 0.15, 0.16, 0.45), edgecolor="darkred", hatch="////", linewidth=0.0)
CONTACT_LABEL = "contact set u = psi"


def contact_triangles(problem, z) -> np.ndarray:
    """The triangles (rows of ``problem.tri``) whose three vertices are in the contact set of ``z``."""
    touching = np.zeros(len(problem.nodes), dtype=bool)
    touching[problem.free[problem.contact_set(z)]] = True
    return problem.tri[touching[problem.tri].all(axis=1)]


def draw_contact_set(ax, problem, z) -> None:
    """The contact set as a hatched red region, with its legend entry (also when it is empty: 0 triangles)."""
    from matplotlib.collections import PolyCollection
    cells = contact_triangles(problem, z)
    ax.add_collection(PolyCollection(problem.nodes[cells], **CONTACT_STYLE,
                                     label=f"{CONTACT_LABEL} ({len(cells)} triangles)"))


def draw_free_boundary(ax, problem, style: str = "k--", lw: float = 1.2) -> None:
    """The exact free boundary r = a* (radial scene only)."""
    if has_radial_exact(problem.scene):
        t = np.linspace(0, 2 * math.pi, 200)
        ax.plot(A_STAR * np.cos(t), A_STAR * np.sin(t), style, lw=lw, label="r = a* (exact free boundary)")


def solution_figure(problem, u, z):
    """The figure of :func:`plot_solution` (open; the caller saves or closes it)."""
    plt = pyplot()
    full = problem.full_vector(u)
    x, y = problem.nodes.T
    psi_all = problem.scene.evaluate("psi", x, y)
    x0, x1, y0, y1 = problem.scene.box
    yc = y[np.argmin(np.abs(y - (y0 + y1) / 2))]
    line = np.flatnonzero(np.isclose(y, yc))
    line = line[np.argsort(x[line])]

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.8))
    ax1.plot(x[line], full[line], "b-", label="u_h")
    ax1.plot(x[line], psi_all[line], "k--", label="obstacle psi")
    if problem.scene.exact is not None:
        xs = np.linspace(x0, x1, 801)
        ax1.plot(xs, problem.scene.evaluate("exact", xs, np.full_like(xs, yc)), "r:", label="exact u")
    touching = problem.contact_set(z)
    on_line = np.isin(line, problem.free[touching])
    ax1.plot(x[line][on_line], full[line][on_line], "o", ms=3, color=CONTACT_STYLE["edgecolor"],
             label=CONTACT_LABEL)
    ax1.set_xlabel("x"); ax1.set_ylabel("height: u_h, psi")
    ax1.set_title(f"section y = {yc:g}"); ax1.grid(alpha=0.3); ax1.legend(fontsize=8)

    shade = ax2.tricontourf(x, y, full, levels=30, cmap="viridis")
    fig.colorbar(shade, ax=ax2, label="u_h")
    draw_contact_set(ax2, problem, z)
    draw_free_boundary(ax2, problem)
    ax2.set_aspect("equal"); ax2.set_xlabel("x"); ax2.set_ylabel("y")
    ax2.set_title(f"{problem.scene.name}: u_h and the contact set")
    ax2.legend(loc="upper right", fontsize=8, framealpha=0.9)
    fig.tight_layout()
    return fig


def plot_solution(problem, u, z, path):
    """Write a PNG: u_h and psi along the line y = centre, and u_h over the box with the contact set hatched red."""
    return save_figure(solution_figure(problem, u, z), path, ("png",), dpi=120)[0]


def adapted_figure(problem, indicators, z):
    """The figure of :func:`plot_adapted` (open; the caller saves or closes it)."""
    points, tri = problem.nodes[:problem.mesh.nv], problem.tri
    check_indicators(indicators, len(tri))
    plt = pyplot()
    fig, ((mesh, zoom1), (eta, zoom2)) = plt.subplots(2, 2, figsize=(13, 11))
    draw_size_panels(fig, mesh, (zoom1, zoom2), points, tri)
    draw_free_boundary(mesh, problem, "k:", 0.9)                     # thin: the refinement along it shows
    mesh.legend(loc="upper right", fontsize=8, framealpha=0.9)
    mesh.set_title(f"{problem.scene.name}: adapted mesh, {len(tri)} triangles, {problem.n} unknowns", fontsize=10)

    shade = eta.tripcolor(points[:, 0], points[:, 1], tri, facecolors=np.log10(np.maximum(indicators, 1e-16)),
                          cmap="YlGnBu", edgecolors="none")
    fig.colorbar(shade, ax=eta, label="log10 eta_T (ZZ indicator)")
    draw_contact_set(eta, problem, z)
    draw_free_boundary(eta, problem)
    eta.set_aspect("equal"); eta.set_xlabel("x"); eta.set_ylabel("y")
    eta.set_title("ZZ error indicators and the contact set", fontsize=10)
    eta.legend(loc="upper right", fontsize=8, framealpha=0.9)
    fig.tight_layout()
    return fig


def plot_adapted(problem, indicators, z, path):
    """Write a PNG: the adapted mesh coloured by log10 h_T and two zooms on its finest triangles
    (:func:`admmkit.problems.mesh_plot.draw_size_panels`), and the ZZ indicators with the contact set (hatched red)
    and r = a*."""
    return save_figure(adapted_figure(problem, indicators, z), path, ("png",), dpi=130)[0]

