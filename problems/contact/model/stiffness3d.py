"""The stiffness matrix of P1 tetrahedra in compiled loops (numba), in NGSolve's ``VectorH1`` numbering.

NGSolve's symbolic assembly of linear elasticity took 10 s of CPU for the
5.9e5 tetrahedra of the 3D block at h = 1/32 (``BilinearForm.Assemble``),
about 17 us an element.  For P1 the element matrix is closed-form: with
G_a = grad(phi_a) (constant on the tetrahedron T) the block of vertices a, b is

    K_ab[c, d] = |T| (mu (G_a . G_b) delta_cd + mu G_a[d] G_b[c] + lam G_a[c] G_b[d]),

the integrand 2 mu eps(u):eps(v) + lam div u div v with u = phi_b e_d,
v = phi_a e_c.  :func:`p1_stiffness` sums these into the 3 x 3 blocks of the
vertex graph (every pair of vertices of a tetrahedron) and reads off the free
rows and columns in NGSolve's order (component c of vertex v is dof
c n_v + v), with the pattern NGSolve gives: every entry of every block, zeros
included.  The values agree with NGSolve's to round-off (a test compares
them).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from admmkit.kernel_cache import numba_stamped
from admmkit.kernels import _u

njit = numba_stamped().njit  # numba with admmkit's cache stamps


@njit(cache=True)
def _vertex_graph(tets, nv, indptr, indices):
    """The vertex graph's rows (each vertex and its neighbours through a tetrahedron, ascending): counted into
    ``indptr`` (its entries 1..nv, when ``indices`` is empty) or written into ``indices``."""
    count = np.zeros(nv + 1, dtype=np.int64)
    for t in range(tets.shape[0]):
        for a in range(4):
            count[_u(tets[t, a] + 1)] += 1
    for v in range(nv):
        count[_u(v + 1)] += count[_u(v)]
    incident = np.empty(count[nv], dtype=np.int64)        # the tetrahedra of each vertex
    fill = count[:nv].copy()
    for t in range(tets.shape[0]):
        for a in range(4):
            v = tets[t, a]
            incident[_u(fill[_u(v)])] = t
            fill[_u(v)] += 1
    seen = np.full(nv, -1, dtype=np.int64)
    row = np.empty(64, dtype=np.int64)
    for v in range(nv):
        m = 0
        for q in range(count[_u(v)], count[_u(v + 1)]):
            t = incident[_u(q)]
            for a in range(4):
                w = tets[t, a]
                if seen[_u(w)] != v:
                    seen[_u(w)] = v
                    if m == row.shape[0]:
                        bigger = np.empty(2 * m, dtype=np.int64)
                        bigger[:m] = row
                        row = bigger
                    row[_u(m)] = w
                    m += 1
        if indices.shape[0] == 0:
            indptr[_u(v + 1)] = m
            continue
        for i in range(1, m):                               # insertion sort: a few dozen neighbours
            w = row[_u(i)]
            j = i - 1
            while j >= 0 and row[_u(j)] > w:
                row[_u(j + 1)] = row[_u(j)]
                j -= 1
            row[_u(j + 1)] = w
        for i in range(m):
            indices[_u(indptr[_u(v)] + i)] = row[_u(i)]


@njit(cache=True)
def _element_blocks(points, tets, mu, lam, indptr, indices, blocks):
    """blocks[9k + 3c + d] += K_ab[c, d] of every tetrahedron for its vertex pairs (a, b) = block k (module
    docstring)."""
    G = np.empty((4, 3))
    for t in range(tets.shape[0]):
        p0 = points[tets[t, 0]]
        J = np.empty((3, 3))
        for r in range(3):
            for c in range(3):
                J[r, c] = points[tets[t, r + 1], c] - p0[c]
        # the gradients of phi_1..3 are the columns of J^-1 (the rows of J are the edge vectors from vertex 0)
        det = (J[0, 0] * (J[1, 1] * J[2, 2] - J[1, 2] * J[2, 1]) - J[0, 1] * (J[1, 0] * J[2, 2] - J[1, 2] * J[2, 0])
               + J[0, 2] * (J[1, 0] * J[2, 1] - J[1, 1] * J[2, 0]))
        inv = 1.0 / det
        G[1, 0] = (J[1, 1] * J[2, 2] - J[1, 2] * J[2, 1]) * inv
        G[1, 1] = (J[1, 2] * J[2, 0] - J[1, 0] * J[2, 2]) * inv
        G[1, 2] = (J[1, 0] * J[2, 1] - J[1, 1] * J[2, 0]) * inv
        G[2, 0] = (J[0, 2] * J[2, 1] - J[0, 1] * J[2, 2]) * inv
        G[2, 1] = (J[0, 0] * J[2, 2] - J[0, 2] * J[2, 0]) * inv
        G[2, 2] = (J[0, 1] * J[2, 0] - J[0, 0] * J[2, 1]) * inv
        G[3, 0] = (J[0, 1] * J[1, 2] - J[0, 2] * J[1, 1]) * inv
        G[3, 1] = (J[0, 2] * J[1, 0] - J[0, 0] * J[1, 2]) * inv
        G[3, 2] = (J[0, 0] * J[1, 1] - J[0, 1] * J[1, 0]) * inv
        for c in range(3):
            G[0, c] = -(G[1, c] + G[2, c] + G[3, c])
        volume = abs(det) / 6.0
        for a in range(4):
            va = tets[t, a]
            for b in range(4):
                vb = tets[t, b]
                k = indptr[_u(va)]
                while indices[_u(k)] != vb:
                    k += 1
                dot = G[a, 0] * G[b, 0] + G[a, 1] * G[b, 1] + G[a, 2] * G[b, 2]
                for c in range(3):
                    for d in range(3):
                        value = mu * G[a, d] * G[b, c] + lam * G[a, c] * G[b, d]
                        if c == d:
                            value += mu * dot
                        blocks[_u(9 * k + 3 * c + d)] += volume * value


@njit(cache=True)
def _free_rows(indptr, indices, blocks, nv, free_index, out_indptr, out_indices, out_data):
    """The free rows and columns of the block matrix in the dof numbering c n_v + v (``free_index``: a dof's
    position among the free ones, -1 if clamped): counted into ``out_indptr`` (``out_data`` empty) or written."""
    row = 0
    w = 0
    for c in range(3):
        for v in range(nv):
            if free_index[_u(c * nv + v)] < 0:
                continue
            for d in range(3):
                for k in range(indptr[_u(v)], indptr[_u(v + 1)]):
                    col = free_index[_u(d * nv + indices[_u(k)])]
                    if col >= 0:
                        if out_data.shape[0]:
                            out_indices[_u(w)] = col
                            out_data[_u(w)] = blocks[_u(9 * k + 3 * c + d)]
                        w += 1
            row += 1
            out_indptr[_u(row)] = w


def lame(E: float, nu: float) -> tuple[float, float]:
    """Lame parameters (mu, lambda) of Young's modulus E and Poisson ratio nu (the formula of
    ``admmkit.problems.contact.model.assembly.lame``, here without that module's NGSolve import)."""
    return E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))


def p1_stiffness(points: np.ndarray, tets: np.ndarray, E: float, nu: float, free: np.ndarray) -> sp.csr_matrix:
    """K of linear elasticity (Young's modulus E, Poisson ratio nu) with P1 tetrahedra ``tets`` (0-based vertex
    numbers of ``points``) on the dofs ``free`` (ascending, in the numbering c n_v + v), as sorted CSR."""
    mu, lam = lame(E, nu)
    points = np.ascontiguousarray(points, dtype=float)
    tets = np.ascontiguousarray(tets, dtype=np.int64)
    nv = points.shape[0]
    indptr = np.zeros(nv + 1, dtype=np.int64)
    _vertex_graph(tets, nv, indptr, np.empty(0, dtype=np.int64))
    indptr = np.cumsum(indptr)
    indices = np.empty(indptr[-1], dtype=np.int64)
    _vertex_graph(tets, nv, indptr, indices)
    blocks = np.zeros(9 * indices.size)
    _element_blocks(points, tets, float(mu), float(lam), indptr, indices, blocks)
    free_index = np.full(3 * nv, -1, dtype=np.int64)
    free_index[free] = np.arange(free.size)
    out_indptr = np.zeros(free.size + 1, dtype=np.int64)
    _free_rows(indptr, indices, blocks, nv, free_index, out_indptr, np.empty(0, dtype=np.int32), np.empty(0))
    index = np.int32 if out_indptr[-1] < 2**31 - 1 else np.int64           # scipy's own choice
    out_indices = np.empty(out_indptr[-1], dtype=index)
    out_data = np.empty(out_indptr[-1])
    _free_rows(indptr, indices, blocks, nv, free_index, out_indptr, out_indices, out_data)
    K = sp.csr_matrix((out_data, out_indices, out_indptr.astype(index)), shape=(free.size, free.size))
    K.has_sorted_indices = True
    return K


__all__ = ["lame", "p1_stiffness"]
