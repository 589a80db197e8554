"""Drawing an adapted triangle mesh so that its refinement shows (the obstacle's and the contact's --plot).

Each triangle T is coloured by log10 h_T, h_T its longest edge, so the refined
triangles stand out from the coarse ones however many there are.  Two zooms
centred on the smallest triangle follow the grading down: the first a square
a quarter of the mesh's shorter side across, the second one that holds about
:data:`ZOOM_TRIANGLES` triangles (at most a quarter of the first); each panel
marks the next one's window with a square of that zoom's colour.
"""
from __future__ import annotations

import numpy as np

#: the colour map of log10 h_T: the smallest triangles are bright yellow, the largest dark purple
SIZE_CMAP = "viridis_r"
#: the second zoom's window holds about this many triangles
ZOOM_TRIANGLES = 200
#: the frame colours of the first and the second zoom
ZOOM_COLOURS = ("red", "magenta")


def element_sizes(points: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """h_T: the longest edge of every triangle (points (n, 2), tri (cells, 3) vertex numbers)."""
    p = points[tri]                                                   # (cells, 3, 2)
    edges = p - np.roll(p, 1, axis=1)
    return np.sqrt((edges ** 2).sum(axis=2)).max(axis=1)


def zoom_windows(points: np.ndarray, tri: np.ndarray, count: int = ZOOM_TRIANGLES) -> list[tuple[float, float, float]]:
    """[(cx, cy, w), (cx, cy, w)]: the two zoom squares (centre, half-width) around the smallest triangle, each
    moved inside the mesh's bounding box (module docstring)."""
    centres = points[tri].mean(axis=1)
    cx, cy = centres[np.argmin(element_sizes(points, tri))]
    (x0, y0), (x1, y1) = points.min(axis=0), points.max(axis=0)
    w1 = min(x1 - x0, y1 - y0) / 8
    reach = np.sort(np.max(np.abs(centres - (cx, cy)), axis=1))       # the half-width that takes in each triangle
    w2 = min(float(reach[min(count, len(reach)) - 1]), w1 / 4)
    return [(float(np.clip(cx, x0 + w, x1 - w)), float(np.clip(cy, y0 + w, y1 - w)), max(w, 1e-12))
            for w in (w1, w2)]


def draw_sizes(ax, points: np.ndarray, tri: np.ndarray, norm=None):
    """The triangles coloured by log10 h_T with their edges drawn; returns the collection (for a colour bar)."""
    return ax.tripcolor(points[:, 0], points[:, 1], tri, facecolors=np.log10(element_sizes(points, tri)),
                        cmap=SIZE_CMAP, norm=norm, edgecolors="#00000070", linewidth=0.2)


def draw_size_panels(fig, ax, zooms, points: np.ndarray, tri: np.ndarray) -> None:
    """``ax``: the whole mesh by log10 h_T with a colour bar; ``zooms``: two axes with the same colours on the
    :func:`zoom_windows`, each window framed in the panel before it."""
    from matplotlib.patches import Rectangle
    shade = draw_sizes(ax, points, tri)
    fig.colorbar(shade, ax=ax, label="log10 h_T (longest edge of the triangle)")
    h = element_sizes(points, tri)
    before = ax
    for k, (zoom, (cx, cy, w), colour) in enumerate(zip(zooms, zoom_windows(points, tri), ZOOM_COLOURS), 1):
        before.add_patch(Rectangle((cx - w, cy - w), 2 * w, 2 * w, fill=False, ec=colour, lw=1.5,
                                   label=f"zoom {k} window"))
        draw_sizes(zoom, points, tri, norm=shade.norm)
        zoom.set_xlim(cx - w, cx + w); zoom.set_ylim(cy - w, cy + w)
        for side in zoom.spines.values():
            side.set_edgecolor(colour); side.set_linewidth(1.5)
        inside = (np.abs(points[tri].mean(axis=1) - (cx, cy)) <= w).all(axis=1)
        zoom.set_title(f"zoom {k}: {2 * w:.2g} x {2 * w:.2g} around the smallest triangle\n"
                       f"h_T from {h[inside].min():.2g} to {h[inside].max():.2g}", fontsize=9)
        before = zoom
    for a in (ax, *zooms):
        a.set_aspect("equal"); a.set_xlabel("x"); a.set_ylabel("y")
        a.ticklabel_format(useOffset=False)


def check_indicators(indicators, cells: int) -> None:
    """One indicator per triangle, or a ValueError saying what does not match (e.g. a mesh refined since)."""
    if len(indicators) != cells:
        raise ValueError(f"{len(indicators)} error indicators for a mesh of {cells} triangles: the indicators "
                         "belong to another mesh (one refined after they were computed?)")
