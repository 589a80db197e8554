"""The contact-boundary Schur complement: every backend against a dense computation."""
import numpy as np
import pytest
import scipy.sparse as sp

from problems.contact import assemble, example1, example2
from problems.contact.schur import BoundarySchur, available_schur_backends, compressed_nested_dissection


@pytest.fixture(scope="module", params=["ex1", "ex2"])
def ops(request):
    return assemble({"ex1": example1, "ex2": example2}[request.param](h=1 / 10))


def dense_schur(K, c):
    """S = K_cc - K_ci K_ii^{-1} K_ic, dense, straight from the definition."""
    K = K.toarray()
    i = np.setdiff1d(np.arange(K.shape[0]), c)
    return K[np.ix_(c, c)] - K[np.ix_(c, i)] @ np.linalg.solve(K[np.ix_(i, i)], K[np.ix_(i, c)])


@pytest.mark.parametrize("backend", available_schur_backends())
def test_schur_and_compliance_match_dense(ops, backend):
    schur = BoundarySchur(ops.K, ops.B, backend=backend)
    assert schur.backend == backend
    S_ref = dense_schur(ops.K, schur.contact_dofs)
    assert np.abs(schur.S - S_ref).max() <= 1e-10 * np.abs(S_ref).max()
    C_ref = ops.B.toarray() @ np.linalg.solve(ops.K.toarray(), ops.B.toarray().T)
    assert np.abs(schur.compliance(ops.B) - C_ref).max() <= 1e-10 * np.abs(C_ref).max()
    u = schur.solve(ops.f)
    assert np.linalg.norm(ops.K @ u - ops.f) <= 1e-10 * np.linalg.norm(ops.f)
    assert set(schur.timings) == {"ordering", "factorisation", "schur"}


def test_compressed_ordering_is_a_permutation_keeping_vertex_dofs_together(ops):
    K = sp.csr_matrix(ops.K)
    perm = compressed_nested_dissection(K)
    assert np.array_equal(np.sort(perm), np.arange(K.shape[0]))
    # dofs with equal row patterns (the x and y dofs of a vertex) come out next to each other
    K.sort_indices()
    rows = {tuple(K.indices[K.indptr[r]:K.indptr[r + 1]]) for r in range(K.shape[0])}
    assert len(rows) < K.shape[0]
    position = np.empty_like(perm)
    position[perm] = np.arange(perm.size)
    patterns = {}
    for r in range(K.shape[0]):
        patterns.setdefault(tuple(K.indices[K.indptr[r]:K.indptr[r + 1]]), []).append(position[r])
    assert all(max(p) - min(p) == len(p) - 1 for p in patterns.values())


def test_unknown_or_missing_backend_is_refused(ops):
    with pytest.raises(ValueError, match="schur backend"):
        BoundarySchur(ops.K, ops.B, backend="mumps")


@pytest.mark.parametrize("backend", available_schur_backends())
def test_singular_K_is_reported(ops, backend):
    K = sp.csr_matrix(ops.K).tolil()
    K[0, :] = 0.0
    K[:, 0] = 0.0
    with pytest.raises(np.linalg.LinAlgError, match="singular"):
        BoundarySchur(K.tocsr(), ops.B, backend=backend)
