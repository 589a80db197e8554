"""The contact-boundary Schur complement of K, from one sparse factorisation.

Order the dofs that B touches (the contact dofs, index set c) last and the
others (i) first by nested dissection (METIS, via pymetis).  An LU
factorisation K = L U in that order, without pivoting (K is SPD), has trailing
blocks with L_cc U_cc = S = K_cc - K_ci K_ii^{-1} K_ic, the Schur complement,
and (K^{-1})_cc = S^{-1}.  So the compliance on Gamma_C,

    C = B K^{-1} B' = B_c S^{-1} B_c',

costs one factorisation instead of n_c solves.
"""
from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla


def contact_last_ordering(K: sp.csr_matrix, contact_dofs: np.ndarray) -> np.ndarray:
    """A fill-reducing ordering of K's dofs with ``contact_dofs`` last (nested dissection inside)."""
    import pymetis

    n = K.shape[0]
    inner = np.setdiff1d(np.arange(n), contact_dofs)
    graph = K[inner][:, inner].tocsr()
    graph.setdiag(0)
    graph.eliminate_zeros()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # the xadj/adjncy form works on every pymetis
        perm, _ = pymetis.nested_dissection(xadj=graph.indptr, adjncy=graph.indices)
    return np.concatenate([inner[np.asarray(perm)], contact_dofs])


class BoundarySchur:
    """One factorisation of K, ordered contact-last, giving S and solves with K.

    Attributes: ``contact_dofs`` (the dofs B touches), ``S`` (dense Schur
    complement on them), ``setup_time``.
    """

    def __init__(self, K: sp.spmatrix, B: sp.spmatrix):
        K = sp.csr_matrix(K)
        self.contact_dofs = np.unique(sp.csc_matrix(B).nonzero()[1])
        n, m = K.shape[0], self.contact_dofs.size
        self.order = contact_last_ordering(K, self.contact_dofs)
        Kp = K[self.order][:, self.order].tocsc()
        try:
            self._lu = spla.splu(Kp, permc_spec="NATURAL", diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
        except RuntimeError as err:
            raise np.linalg.LinAlgError(f"K is singular (is the body clamped?): {err}") from None
        # trailing blocks of the factors; slicing L and U copies only their last columns
        L_cc = _trailing_block(self._lu.L, m)
        U_cc = _trailing_block(self._lu.U, m)
        self.S = L_cc @ U_cc
        self.S = 0.5 * (self.S + self.S.T)

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """K^{-1} rhs (rhs in the original dof order)."""
        x = self._lu.solve(np.asarray(rhs, dtype=float)[self.order])
        out = np.empty_like(x)
        out[self.order] = x
        return out

    def compliance(self, B: sp.spmatrix) -> np.ndarray:
        """C = B K^{-1} B' (dense, n_c x n_c, symmetric positive definite)."""
        Bc = sp.csr_matrix(B)[:, self.contact_dofs].toarray()
        factor = sla.cho_factor(self.S)
        C = Bc @ sla.cho_solve(factor, Bc.T)
        return 0.5 * (C + C.T)


def _trailing_block(F: sp.spmatrix, m: int) -> np.ndarray:
    F = sp.csc_matrix(F)
    return F[-m:, -m:].toarray()
