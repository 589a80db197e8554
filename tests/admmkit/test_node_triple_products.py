"""The 3-D x-step's products: CG's product with K + rho D in 3 x 3 node blocks
(admmkit.linalg.symmetric.NodeTriplePattern), the values of the upper-triangle CSR product bit for bit, and the
AMG set-up's coarse D_l = P' D P from D's support (admmkit.linalg.amg.galerkin_on_support), scipy's bit for bit."""
import numpy as np
import pytest
import scipy.sparse as sp

pytest.importorskip("numba")
pytest.importorskip("pyamg")

from admmkit.linalg.amg import PencilMatrix  # noqa: E402
from admmkit.linalg.symmetric import NodeTriplePattern, SymmetricPattern, pencil_products  # noqa: E402
from tests.conftest import assert_block_product_is_symmetric_patterns  # noqa: E402
from tests.test_vcycle import _elasticity3d  # noqa: E402


def _stiffness():
    """A 3-D P1 stiffness numbered node by node (sorted CSR), shifted to be safely nonsingular."""
    A, _ = _elasticity3d(5)
    A = sp.csr_matrix(A + 10.0 * sp.eye(A.shape[0]))
    A.sort_indices()
    return A


def test_node_triple_products_equal_the_upper_triangle_products():
    A = _stiffness()
    x = np.random.default_rng(1).standard_normal(A.shape[0])
    # the same values bit for bit, also with holes inside the 3 x 3 blocks and node couplings
    assert_block_product_is_symmetric_patterns(NodeTriplePattern, A, x, every=4)


def test_node_triple_pencil_products_follow_rho_in_place():
    K = _stiffness()
    rows = np.arange(2, K.shape[0], 9)            # D on some dofs and on couplings inside and across nodes
    D = sp.csr_matrix((np.linspace(1, 2, rows.size), (rows, rows)), shape=K.shape)
    off = sp.csr_matrix((np.full(rows.size - 1, 0.25), (rows[:-1], rows[:-1] - 1)), shape=K.shape)   # in a node
    across = sp.csr_matrix((np.full(rows.size - 1, 0.125), (rows[:-1], rows[:-1] + 3)), shape=K.shape)  # next node
    D = sp.csr_matrix(D + off + off.T + across + across.T)
    pencil = PencilMatrix(K, D)
    assert pencil.changed_entries().size == D.nnz            # D inside K's pattern: its entries are found, not gathered
    at = pencil_products(pencil, 3)
    x = np.random.default_rng(2).standard_normal(K.shape[0])
    product = at(0.5)
    for rho in (0.5, 3e4, 7.0):
        product = at(rho, into=product)          # D's entries rewritten in place for rho
        expected = SymmetricPattern(pencil.pattern).product(pencil.at(rho))(x)
        assert np.array_equal(product(x), expected)
        assert np.array_equal(at(rho)(x), expected)
        assert np.linalg.norm(expected - (K + rho * D) @ x) <= 1e-13 * np.linalg.norm((K + rho * D) @ x)


def test_node_triple_pattern_needs_whole_nodes():
    with pytest.raises(ValueError, match="divisible by 3"):
        NodeTriplePattern(sp.csr_matrix(sp.eye(4)))


@pytest.mark.parametrize("blocks", [True, False])
def test_galerkin_on_support_is_scipys_product_bit_for_bit(blocks):
    from admmkit.linalg.amg import AMGPreconditioner, galerkin_on_support
    A, B = _elasticity3d(6)
    A = sp.csr_matrix(A)
    P = AMGPreconditioner(A, B, blocksize=3, max_coarse=50).ml.levels[0].P
    P = P if blocks else sp.csr_matrix(P)
    rows = np.arange(1, A.shape[0], 11)            # a D on a few scattered dofs, coupled to their neighbours
    D = sp.csr_matrix((np.linspace(1, 2, rows.size), (rows, rows)), shape=A.shape)
    D = sp.csr_matrix(D + sp.csr_matrix((np.full(rows.size - 1, 0.5), (rows[:-1], rows[1:])), shape=A.shape)
                      + sp.csr_matrix((np.full(rows.size - 1, 0.5), (rows[1:], rows[:-1])), shape=A.shape))
    ours, scipys = galerkin_on_support(D, P), sp.csr_matrix(P.T @ D @ P)
    ours.sort_indices()
    scipys.sort_indices()
    assert np.array_equal(ours.indptr, scipys.indptr) and np.array_equal(ours.indices, scipys.indices)
    assert np.array_equal(ours.data, scipys.data)
