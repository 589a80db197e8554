"""Finite-element pieces the NGSolve plug-ins (contact, obstacle) share."""
from __future__ import annotations

import ngsolve as ng
import numpy as np


def facet_sizes(mesh: ng.Mesh) -> ng.GridFunction:
    """h_E on every facet: its length (2D) or the square root of its area (3D), as a FacetFESpace function."""
    facets = ng.FacetFESpace(mesh, order=0)
    v = facets.TestFunction()
    lf = ng.LinearForm(facets)
    lf += v * ng.dx(skeleton=True)
    lf += v * ng.ds(skeleton=True)
    lf.Assemble()
    gf = ng.GridFunction(facets)
    gf.vec.FV().NumPy()[:] = np.abs(lf.vec.FV().NumPy()) ** (1.0 / (mesh.dim - 1))
    return gf
