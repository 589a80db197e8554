"""The compiled sparse LDL' (admmkit.linalg.ldl) against scipy on a contact stiffness matrix."""
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from admmkit.linalg.ldl import ldl_analyse, ldl_factor
from admmkit.problems.contact.model.assembly import assemble
from admmkit.problems.contact.model.scene import example1


@pytest.fixture(scope="module")
def K():
    return sp.csc_matrix(assemble(example1(1 / 10)).K)


@pytest.mark.parametrize("how", ["natural", "random", "reversed"])
def test_factors_reproduce_the_permuted_matrix(K, how):
    n = K.shape[0]
    order = {"natural": None, "random": np.random.default_rng(0).permutation(n),
             "reversed": np.arange(n)[::-1]}[how]
    F = ldl_factor(K, order)
    P = np.arange(n) if order is None else order
    unit_L = sp.eye(n) + F.L
    assert np.all(F.L.indices >= np.repeat(np.arange(n), np.diff(F.L.indptr)) + 1)   # strictly lower
    error = unit_L @ sp.diags(F.d) @ unit_L.T - K[P][:, P]
    assert abs(error).max() <= 1e-13 * abs(K).max()
    assert F.d.min() > 0   # K is SPD (the body is clamped)


def test_solves_match_spsolve(K):
    rng = np.random.default_rng(1)
    order = rng.permutation(K.shape[0])
    F = ldl_factor(sp.csr_matrix(K), order)   # CSR input: K symmetric, read as its transpose
    b = rng.standard_normal(K.shape[0])
    x_ref = spla.spsolve(K, b)
    assert np.linalg.norm(F.solve(b) - x_ref) <= 1e-10 * np.linalg.norm(x_ref)
    assert np.allclose(F.solve_permuted(b[order]), x_ref[order], rtol=0, atol=1e-10 * abs(x_ref).max())


def test_trailing_block_is_the_dense_corner_of_unit_L(K):
    F = ldl_factor(K)
    m = 7
    dense = (sp.eye(K.shape[0]) + F.L).toarray()[-m:, -m:]
    assert np.array_equal(F.trailing_block(m), dense)


def test_indefinite_but_factorisable_matrix_gives_negative_pivots():
    A = sp.csc_matrix(np.array([[2.0, 1.0, 0.0], [1.0, -3.0, 1.0], [0.0, 1.0, 1.0]]))
    F = ldl_factor(A)
    assert (F.d < 0).any()
    b = np.array([1.0, 2.0, 3.0])
    assert np.allclose(A @ F.solve(b), b)


@pytest.mark.parametrize("A", [np.array([[0.0, 1.0], [1.0, 0.0]]),                  # needs pivoting
                               np.array([[1.0, 1.0], [1.0, 1.0]]),                  # singular
                               np.array([[1.0, 0.0], [0.0, np.nan]])])              # not finite
def test_zero_or_non_finite_pivot_is_reported(A):
    with pytest.raises(np.linalg.LinAlgError, match="pivot"):
        ldl_factor(sp.csc_matrix(A))


def test_singular_stiffness_is_reported(K):
    K = K.tolil()
    K[3, :] = 0.0
    K[:, 3] = 0.0
    with pytest.raises(np.linalg.LinAlgError, match="singular"):
        ldl_factor(K.tocsc())


def test_bad_order_is_refused(K):
    with pytest.raises(ValueError, match="permutation"):
        ldl_factor(K, np.zeros(K.shape[0], dtype=int))
    with pytest.raises(ValueError, match="square"):
        ldl_factor(sp.csc_matrix((2, 3)))


def test_analysis_predicts_the_factor_and_can_be_reused(K):
    order = np.random.default_rng(2).permutation(K.shape[0])
    analysis = ldl_analyse(K, order)
    F = ldl_factor(K, order, analysis)
    counts = np.diff(F.L.indptr)
    assert np.array_equal(analysis.counts, counts)
    assert analysis.flops == float((counts.astype(float) ** 2).sum())
    assert analysis.mean_column_length == analysis.flops / counts.sum()
    G = ldl_factor(K, order)
    assert np.array_equal(F.Lx, G.Lx) and np.array_equal(F.d, G.d)


def test_forward_and_backward_substitutions(K):
    F = ldl_factor(K)
    unit_L = sp.eye(K.shape[0], format="csc") + F.L
    b = np.random.default_rng(4).standard_normal(K.shape[0])
    assert np.allclose(unit_L @ F.forward(b), b, rtol=0, atol=1e-12 * abs(b).max())
    assert np.allclose(unit_L.T @ F.backward(b), b, rtol=0, atol=1e-12 * abs(b).max())
    tail = np.zeros_like(b)
    tail[-5:] = b[-5:]
    assert np.array_equal(F.forward(tail, start=K.shape[0] - 5), F.forward(tail))   # zeros before start skipped
