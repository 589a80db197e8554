"""Meshes of the rectangle (0, L) x (0, H) with boundary names bottom/right/top/left.

FreeFEM's ``square(nx, ny, [L*x, H*y])`` with the default ``flags=0`` cuts every
grid square along the diagonal x - y = const, i.e. from its lower-left to its
upper-right corner (FreeFEM documentation, "Mesh Generation", the note on
``flags=icase``: "0. will produce a mesh where all quads are split with diagonal
x-y=constant"; FreeFem/FreeFem-doc, source/documentation/mesh-generation.rst).
``ngsolve.meshes.MakeStructured2DMesh(quads=False)`` cuts along x + y = const by
default; with ``flip_triangles=True`` it cuts along x - y = const, which is the
FreeFEM triangulation, so we use it.
"""
from __future__ import annotations

import ngsolve as ng
from ngsolve.meshes import MakeStructured2DMesh

BOUNDARY_NAMES = ("bottom", "right", "top", "left")


def grid_counts(L: float, H: float, h: float) -> tuple[int, int]:
    """Numbers of squares (nx, ny) = (round(L/h), round(H/h)), at least 1 each."""
    return max(1, round(L / h)), max(1, round(H / h))


def structured_rectangle(L: float, H: float, h: float) -> ng.Mesh:
    """FreeFEM-like ``square`` mesh: nx x ny squares, each cut along x - y = const."""
    nx, ny = grid_counts(L, H, h)
    return MakeStructured2DMesh(quads=False, nx=nx, ny=ny, flip_triangles=True,
                                mapping=lambda x, y: (L * x, H * y))


def unstructured_rectangle(L: float, H: float, h: float) -> ng.Mesh:
    """Netgen (OCC) triangulation of the rectangle with maxh = h."""
    from netgen.occ import OCCGeometry, Rectangle, X, Y
    face = Rectangle(L, H).Face()
    face.edges.Min(Y).name = "bottom"
    face.edges.Max(Y).name = "top"
    face.edges.Min(X).name = "left"
    face.edges.Max(X).name = "right"
    return ng.Mesh(OCCGeometry(face, dim=2).GenerateMesh(maxh=h))


def geometry_mesh(geometry, h: float) -> ng.Mesh:
    """Mesh a netgen geometry object (OCCGeometry, SplineGeometry, ...) with maxh = h."""
    return ng.Mesh(geometry.GenerateMesh(maxh=h))
