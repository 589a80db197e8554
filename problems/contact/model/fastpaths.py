"""Faster paths of the contact assembly at a million unknowns (issue #25), each a drop-in for a slower step.

Measured on Example 1 at h = 1/500 (1,002,000 free unknowns, 1000 contact nodes):

- :func:`admmkit.problems.fe.ngsolve_tasks`: NGSolve's task manager around the bilinear form's
  assembly (2.6 -> 1.5 s with the second core free; about the same time when
  another process holds it);
- :func:`free_dofs`: the free dofs from NGSolve's projector applied to ones,
  7 ms, where converting the ``BitArray`` element by element took 0.14-0.23 s;
- :func:`component_map`: the maps u -> sum_c w_c u_c(x_i) (B, T) built from
  the entries of the point evaluation, 3 ms, where stacking sparse matrices
  and selecting 1e6 columns took 0.2-0.5 s.
"""
from __future__ import annotations

import ngsolve as ng
import numpy as np
import scipy.sparse as sp


def free_dofs(fes: ng.comp.FESpace) -> np.ndarray:
    """Indices of the free dofs of ``fes``, in order (what ``np.flatnonzero(fes.FreeDofs())`` gives)."""
    ones = ng.BaseVector(fes.ndof)
    ones.FV().NumPy()[:] = 1.0
    out = ones.CreateVector()
    out.data = ng.Projector(fes.FreeDofs(), True) * ones
    return np.flatnonzero(out.FV().NumPy())


def component_map(E: sp.spmatrix, weights: np.ndarray, free: np.ndarray, n_dofs: int) -> sp.csr_matrix:
    """(n_points, n_free): u_free -> sum_c weights[i, c] u_c(x_i) for a vector space numbering its components
    one after the other (component c's dofs at c n_scalar + j), from the scalar point evaluation E
    (n_points, n_scalar); explicit zeros dropped, as ``eliminate_zeros`` would."""
    E = sp.coo_matrix(E)
    n_scalar = E.shape[1]
    position = np.full(n_dofs, -1, dtype=np.int64)
    position[free] = np.arange(free.size)
    rows, cols, vals = [], [], []
    for c in range(weights.shape[1]):
        col = position[c * n_scalar + E.col]
        val = weights[E.row, c] * E.data
        keep = (col >= 0) & (val != 0)
        rows.append(E.row[keep])
        cols.append(col[keep])
        vals.append(val[keep])
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(E.shape[0], free.size))
