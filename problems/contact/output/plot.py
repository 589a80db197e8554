"""Plots of a contact solution: the deformed body with the obstacle, pressure and gap along Gamma_C, and with
friction the tangential traction with the stick and slip zones (2D scenes)."""
from __future__ import annotations

import numpy as np

from admmkit.figures import pyplot, save_figure

from admmkit.problems.contact.model.operators import ContactOperators


def vertex_displacement(ops: ContactOperators, u_free: np.ndarray):
    """(points (nv, 2), triangles (nt, 3), displacement at the vertices (nv, 2)).

    VectorH1 numbers all x-component dofs first, then all y; in each component
    the first nv dofs belong to the vertices (P1 nodal values; for P2 the edge
    bubbles vanish at the vertices), so the vertex values are read off the dofs.
    """
    import ngsolve as ng
    mesh = ops.mesh
    points = np.array([v.point[:2] for v in mesh.vertices])
    triangles = np.array([[v.nr for v in el.vertices] for el in mesh.Elements(ng.VOL)])
    full = ops.full_vector(u_free)
    nv, half = mesh.nv, ops.fes.ndof // 2
    return points, triangles, np.column_stack([full[:nv], full[half:half + nv]])


def plot_deformed(ax, ops: ContactOperators, u_free: np.ndarray, magnify: float, title: str = ""):
    """The deformed triangulation (coloured by |u|), the undeformed outline and the obstacle."""
    import matplotlib.tri as mtri
    points, triangles, disp = vertex_displacement(ops, u_free)
    moved = points + magnify * disp
    tri = mtri.Triangulation(moved[:, 0], moved[:, 1], triangles)
    pc = ax.tripcolor(tri, np.linalg.norm(disp, axis=1), shading="gouraud", cmap="viridis")
    ax.triplot(tri, color="k", lw=0.25, alpha=0.5)
    L, H = ops.scene.L, ops.scene.H
    ax.plot([0, L, L, 0, 0], [0, 0, H, H, 0], "k--", lw=0.8, label="undeformed body")
    x = np.linspace(-0.05 * L, 1.05 * L, 400)
    g = np.array([ops.scene.gap_at(xi, 0.0) for xi in x])
    ax.plot(x, -magnify * g, "r-", lw=1.6, label=f"obstacle y = -g(x) (x{magnify:g}, like u)")
    ax.fill_between(x, -magnify * g, -magnify * g.max() - 0.08 * H, color="r", alpha=0.12, lw=0)
    ax.set_aspect("equal")
    ax.set_xlabel("x"); ax.set_ylabel("y")
    ax.set_title(title or f"deformed body, displacement x{magnify:g}")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2, fontsize=8, frameon=False)
    return pc


def plot_pressure_gap(axes, ops: ContactOperators, u_free: np.ndarray, lam: np.ndarray, p: np.ndarray | None = None):
    """The contact pressure lam and the gap g - u_n along Gamma_C against x (two axes).

    With ``p`` (the last z-step, ``result.z``) the active nodes are marked: p = g,
    the one definition of :func:`admmkit.problems.contact.output.export.contact_status`.
    """
    from admmkit.problems.contact.output.export import contact_status
    x = ops.xc[:, 0]
    un = ops.B @ u_free
    gap = ops.g - un
    ax1, ax2 = axes
    ax1.plot(x, lam, "b.-", ms=3, label="contact pressure lam")
    if p is not None:
        active = contact_status(ops, p)
        ax1.plot(x[active], lam[active], "o", mfc="none", mec="r", ms=5,
                 label=f"active ({int(active.sum())} nodes: p = g after the last z-step)")
    ax1.set_ylabel("contact pressure lam"); ax1.legend(fontsize=8); ax1.grid(alpha=0.3)
    ax2.plot(x, gap, "g.-", ms=3, label="gap g - u_n")
    ax2.plot(x, ops.g, "k--", lw=0.8, label="initial gap g")
    ax2.axhline(0, color="k", lw=0.5)
    ax2.set_ylabel("gap g - u_n"); ax2.set_xlabel("x on Gamma_C (y = 0)"); ax2.legend(fontsize=8); ax2.grid(alpha=0.3)


#: colours of the zones of admmkit.problems.contact.solvers.friction.stick_slip: 0 separated, 1 stick, 2 slip
ZONE_STYLE = {0: ("separated", "0.6"), 1: ("stick", "tab:green"), 2: ("slip", "tab:red")}


def plot_friction(ax, ops: ContactOperators, fields: dict):
    """The tangential traction q and the bounds +-s along Gamma_C against x, the stick and slip zones marked.

    ``fields`` are :func:`admmkit.problems.contact.output.export.boundary_fields` with friction
    (``tangential_traction``, ``slip_bound``, ``stick_slip_zone``); each node is
    marked by its zone and the stretches of Gamma_C where it sticks or slips are shaded.
    """
    x = ops.xc[:, 0]
    q = np.asarray(fields["tangential_traction"], dtype=float)
    s = np.asarray(fields["slip_bound"], dtype=float)
    zones = np.asarray(fields["stick_slip_zone"])
    ax.plot(x, q, "k-", lw=1.0, label="tangential traction q")
    ax.plot(x, s, "k--", lw=0.7, label="slip bound +-s")
    ax.plot(x, -s, "k--", lw=0.7)
    spacing = np.diff(x).min(initial=0.0) / 2 if len(x) > 1 else 0.0
    for zone, (label, colour) in ZONE_STYLE.items():
        at = zones == zone
        ax.plot(x[at], q[at], "o", ms=4, color=colour, label=f"{label} ({int(at.sum())} nodes)")
        if zone:
            for xi in x[at]:
                ax.axvspan(xi - spacing, xi + spacing, color=colour, alpha=0.12, lw=0)
    ax.axhline(0, color="k", lw=0.5)
    ax.set_ylabel("tangential traction q"); ax.set_xlabel("x on Gamma_C")
    ax.legend(fontsize=8, ncol=2); ax.grid(alpha=0.3)


def figure_deformed(ops, u, magnify, title, path, svg=True):
    """The paper's Figs 1 / 3."""
    plt = pyplot()
    L, H = ops.scene.L, ops.scene.H
    fig, ax = plt.subplots(figsize=(min(3.6 * L / H + 1.5, 13), 5.0))
    pc = plot_deformed(ax, ops, u, magnify, title)
    fig.colorbar(pc, ax=ax, label="|u|", fraction=0.025, pad=0.02)
    fig.tight_layout()
    return save_figure(fig, path, ("png", "svg") if svg else ("png",))


def figure_pressure_gap(ops, u, lam, title, path, svg=True, p=None):
    """The contact pressure lam and the gap g - u_n along Gamma_C (active nodes marked when ``p`` is given)."""
    plt = pyplot()
    fig, axes = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    plot_pressure_gap(axes, ops, u, lam, p)
    axes[0].set_title(title)
    fig.tight_layout()
    return save_figure(fig, path, ("png", "svg") if svg else ("png",))


def figure_solution(ops, u, lam, magnify, title, path, p=None, friction=None):
    """Deformed body over contact pressure and gap in one PNG (the CLI's --plot; active nodes marked with ``p``).

    ``friction``: the boundary fields with friction (:func:`admmkit.problems.contact.output.export.friction_fields`) add a
    panel with the tangential traction and the stick/slip zones (:func:`plot_friction`).  2D scenes only.
    """
    if ops.mesh.dim != 2:
        raise ValueError("figure_solution draws 2D scenes only; write a VTU file (write_vtu) for a 3D one")
    with_friction = friction is not None and "tangential_traction" in friction
    plt = pyplot()
    fig = plt.figure(figsize=(9, 11.0 if with_friction else 8.5))
    gs = fig.add_gridspec(4 if with_friction else 3, 1, height_ratios=[2.2, 1, 1] + [1.2] * with_friction)
    ax0 = fig.add_subplot(gs[0])
    pc = plot_deformed(ax0, ops, u, magnify, title)
    fig.colorbar(pc, ax=ax0, label="|u|", fraction=0.025, pad=0.02)
    ax1 = fig.add_subplot(gs[1]); ax2 = fig.add_subplot(gs[2], sharex=ax1)
    plot_pressure_gap((ax1, ax2), ops, u, lam, p)
    if with_friction:
        plot_friction(fig.add_subplot(gs[3], sharex=ax1), ops, friction)
    fig.tight_layout()
    return save_figure(fig, path, ("png",))[0]


def adapted_figure(ops, u, lam, indicators, title):
    """The figure of :func:`figure_adapted` (open; the caller saves or closes it)."""
    from admmkit.problems.mesh_plot import check_indicators, draw_size_panels
    points, triangles, _ = vertex_displacement(ops, u)
    check_indicators(indicators, len(triangles))
    plt = pyplot()
    fig = plt.figure(figsize=(13, 10))
    gs = fig.add_gridspec(3, 2, width_ratios=[2.2, 1], height_ratios=[2, 2, 1.3])
    mesh, eta, bx = fig.add_subplot(gs[0, 0]), fig.add_subplot(gs[1, 0]), fig.add_subplot(gs[2, 0])
    draw_size_panels(fig, mesh, (fig.add_subplot(gs[0, 1]), fig.add_subplot(gs[1, 1])), points, triangles)
    mesh.set_title(title, fontsize=10)
    mesh.legend(loc="upper right", fontsize=8, framealpha=0.9)
    shade = eta.tripcolor(points[:, 0], points[:, 1], triangles, facecolors=np.log10(np.maximum(indicators, 1e-300)),
                          cmap="YlGnBu", edgecolors="none")
    fig.colorbar(shade, ax=eta, label="log10 eta_T (ZZ indicator)")
    eta.set_aspect("equal"); eta.set_xlabel("x"); eta.set_ylabel("y")
    eta.set_title("ZZ error indicators", fontsize=10)
    order = np.argsort(ops.xc[:, 0])
    bx.plot(ops.xc[order, 0], lam[:ops.n_c][order], "b.-", ms=3, label="contact pressure lam")
    bx.set_xlabel("x on Gamma_C"); bx.set_ylabel("contact pressure lam"); bx.grid(alpha=0.3)
    bx.set_xlim(mesh.get_xlim()); bx.legend(fontsize=8)
    fig.tight_layout()
    return fig


def figure_adapted(ops, u, lam, indicators, title, path):
    """Write a PNG: the adapted mesh coloured by log10 h_T (top left) with two zooms on its finest triangles (right;
    :func:`admmkit.problems.mesh_plot.draw_size_panels`), the ZZ indicators (middle) and the contact pressure along
    Gamma_C (bottom)."""
    return save_figure(adapted_figure(ops, u, lam, indicators, title), path, ("png",), dpi=130)[0]
