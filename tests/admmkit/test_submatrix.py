"""admmkit.linalg.submatrix.principal_submatrix against scipy's A[index][:, index]."""
import numpy as np
import pytest
import scipy.sparse as sp

from admmkit.linalg.submatrix import principal_submatrix


def _matrix(n, seed=0, sorted_rows=True):
    rng = np.random.default_rng(seed)
    A = sp.random(n, n, density=0.2, format="csr", random_state=seed) + sp.eye(n, format="csr")
    if not sorted_rows:             # the same matrix with each row's entries reversed
        A = sp.csr_matrix(A)
        for i in range(n):
            s = slice(A.indptr[i], A.indptr[i + 1])
            A.indices[s], A.data[s] = A.indices[s][::-1].copy(), A.data[s][::-1].copy()
        A.has_sorted_indices = False
    return A, rng


@pytest.mark.parametrize("kind", ["selection", "permutation", "shuffled selection", "empty"])
@pytest.mark.parametrize("sorted_rows", [True, False])
def test_same_matrix_as_scipy(kind, sorted_rows):
    A, rng = _matrix(60, sorted_rows=sorted_rows)
    index = {"selection": np.flatnonzero(rng.random(60) < 0.7), "permutation": rng.permutation(60),
             "shuffled selection": rng.permutation(60)[:25], "empty": np.empty(0, dtype=int)}[kind]
    B = principal_submatrix(A, index)
    ref = sp.csr_matrix(A[index][:, index]).sorted_indices()
    assert B.shape == ref.shape and B.has_sorted_indices
    assert np.array_equal(B.indptr, ref.indptr) and np.array_equal(B.indices, ref.indices)
    assert np.array_equal(B.data, ref.data)          # the same numbers, copied, never summed
    assert np.all(np.diff(B.indices[B.indptr[0]:B.indptr[1]]) > 0) if B.shape[0] else True


def test_result_owns_its_values():
    A, _ = _matrix(20)
    B = principal_submatrix(A, np.arange(20))
    B.data[:] = 0.0
    assert A.data.any()


@pytest.mark.parametrize("index, message", [
    (np.array([0, 1, 1]), "must not repeat"), (np.array([0, 20]), "0..19"), (np.array([-1]), "0..19"),
    (np.array([[0, 1]]), "one-dimensional"), (np.array([0.5]), "integers")])
def test_bad_index_is_named(index, message):
    A, _ = _matrix(20)
    with pytest.raises(ValueError, match=message):
        principal_submatrix(A, index)


def test_non_square_is_refused():
    with pytest.raises(ValueError, match="square"):
        principal_submatrix(sp.csr_matrix(np.ones((2, 3))), np.array([0]))


@pytest.mark.parametrize("compiled", [True, False, "auto"])
def test_every_setting_gives_the_same_arrays(compiled):
    """Issue #49: scipy's fancy indexing for a small matrix in a process without numba, the same B."""
    A, rng = _matrix(80, seed=3)
    index = rng.permutation(80)[:50]
    B, ref = principal_submatrix(A, index, compiled=compiled), principal_submatrix(A, index, compiled=True)
    for attr in ("indptr", "indices", "data"):
        assert np.array_equal(getattr(B, attr), getattr(ref, attr)) and getattr(B, attr).dtype == getattr(ref, attr).dtype
    assert B.has_sorted_indices
    with pytest.raises(ValueError, match="compiled must be 'auto', True or False"):
        principal_submatrix(A, index, compiled="fast")
