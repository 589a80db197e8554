"""The compiled V-cycle and CG products (admmkit.linalg.vcycle) against pyamg's and scipy's."""
import numpy as np
import pytest
import scipy.sparse as sp

pytest.importorskip("numba")
pyamg = pytest.importorskip("pyamg")

from admmkit.linalg.amg import AMGPreconditioner, short_spectral_radius  # noqa: E402
from admmkit.linalg.vcycle import THREADS_VARIABLE, VCycle, csr_product  # noqa: E402
from tests.conftest import assert_block_product_is_symmetric_patterns  # noqa: E402


def _elasticity():
    A, B = pyamg.gallery.linear_elasticity((40, 40), format="csr")
    return sp.csr_matrix(A), B


def _elasticity3d(n=10):
    """3-D P1 elasticity on the unit cube cut into n^3 cubes of 6 tetrahedra, clamped at x = 0, numbered node by
    node (3 x 3 blocks), with its six rigid-body modes."""
    from pyamg.gallery.elasticity import linear_elasticity_p1
    g = np.arange(n + 1)
    I, J, K = np.meshgrid(g, g, g, indexing="ij")
    vertices = np.column_stack([I.ravel(), J.ravel(), K.ravel()]) / n
    vid = lambda i, j, k: (i * (n + 1) + j) * (n + 1) + k  # noqa: E731
    i, j, k = (a.ravel() for a in np.meshgrid(*(np.arange(n),) * 3, indexing="ij"))
    c = [vid(i, j, k), vid(i, j, k + 1), vid(i, j + 1, k + 1), vid(i, j + 1, k), vid(i + 1, j, k),
         vid(i + 1, j, k + 1), vid(i + 1, j + 1, k + 1), vid(i + 1, j + 1, k)]
    tets = np.vstack([np.column_stack([c[a] for a in t]) for t in
                      ((0, 4, 5, 6), (0, 6, 7, 4), (0, 3, 7, 6), (0, 1, 6, 5), (0, 1, 2, 6), (0, 3, 6, 2))])
    # positively oriented tetrahedra: pyamg's element matrix carries det(J)'s sign, so a negatively oriented
    # one adds a negative definite block (with these six every K was negative definite)
    edges = vertices[tets[:, 1:]] - vertices[tets[:, :1]]
    flip = np.linalg.det(edges) < 0
    tets[flip, 2:4] = tets[flip, 3:1:-1]
    A, B = linear_elasticity_p1(vertices, tets, E=5000.0, nu=0.49, format="csr")
    free = np.flatnonzero(np.repeat(vertices[:, 0] > 0, 3))
    return sp.csr_matrix(A)[free][:, free], np.ascontiguousarray(B[free])


def test_elasticity3d_fixture_is_spd():
    """The 3-D fixture is the stiffness of positively oriented tetrahedra: symmetric positive definite."""
    A, _ = _elasticity3d(3)
    assert abs(A - A.T).max() <= 1e-9 * abs(A).max()
    assert np.linalg.eigvalsh(A.toarray()).min() > 0


def _pyamg_cycle(ml, r):
    z = np.zeros_like(r)
    ml._MultilevelSolver__solve(0, z, r, "V")
    return z


def test_vcycle_matches_pyamg_cycle():
    A, B = _elasticity()
    amg = AMGPreconditioner(A, B, blocksize=2, max_coarse=50)
    assert amg.levels >= 3
    r = np.random.default_rng(0).standard_normal(A.shape[0])
    z_ref = _pyamg_cycle(amg.ml, r)
    z = VCycle(amg.ml)(r)
    assert np.linalg.norm(z - z_ref) <= 1e-12 * np.linalg.norm(z_ref)
    assert np.array_equal(amg(r), z)                       # the preconditioner applies the compiled cycle


def test_single_precision_cycle_is_close_and_symmetric():
    A, B = _elasticity()
    amg = AMGPreconditioner(A, B, blocksize=2, max_coarse=50, cycle_values="float32")
    rng = np.random.default_rng(1)
    u, v = rng.standard_normal((2, A.shape[0]))
    z_ref = _pyamg_cycle(amg.ml, u)
    assert np.linalg.norm(amg(u) - z_ref) <= 1e-4 * np.linalg.norm(z_ref)
    assert abs(v @ amg(u) - u @ amg(v)) <= 1e-10 * abs(u @ amg(u))  # still a symmetric operator


def test_threads_do_not_change_values(monkeypatch):
    from numba import config
    A, B = _elasticity()
    amg = AMGPreconditioner(A, B, blocksize=2, max_coarse=50)
    r = np.random.default_rng(2).standard_normal(A.shape[0])
    monkeypatch.setenv(THREADS_VARIABLE, "1")
    one, Ar1 = amg(r), csr_product(A)(r)
    monkeypatch.setenv(THREADS_VARIABLE, str(config.NUMBA_NUM_THREADS))
    assert np.array_equal(amg(r), one)
    assert np.array_equal(csr_product(A)(r), Ar1)
    assert np.array_equal(Ar1, A @ r)                      # scipy's values


def test_short_spectral_radius_is_scoped():
    from pyamg.aggregation import smooth
    original = smooth.approximate_spectral_radius
    with short_spectral_radius(10):
        assert smooth.approximate_spectral_radius is not original
    assert smooth.approximate_spectral_radius is original
    A, B = _elasticity()
    short = AMGPreconditioner(A, B, blocksize=2, max_coarse=50, spectral_steps=10)
    assert short.levels >= 3


def test_symmetric_product_from_upper_triangle():
    from admmkit.linalg.symmetric import SymmetricPattern
    A, _ = _elasticity()
    A = sp.csr_matrix(A + 3 * sp.eye(A.shape[0]))
    A.sort_indices()
    x = np.random.default_rng(3).standard_normal(A.shape[0])
    product = SymmetricPattern(A).product(A)
    assert np.linalg.norm(product(x) - A @ x) <= 1e-14 * np.linalg.norm(A @ x)
    B = sp.csr_matrix((2 * A.data, A.indices, A.indptr), shape=A.shape)   # another matrix on the pattern
    assert np.linalg.norm(SymmetricPattern(A).product(B)(x) - B @ x) <= 1e-14 * np.linalg.norm(B @ x)


@pytest.mark.parametrize("lag_shift", [0, 7])
def test_forward_restrict_is_sweep_residual_and_restriction(lag_shift):
    """The fused descent equals its three passes: a forward sweep from zero, r = b - A x, P' r."""
    from pyamg.relaxation.relaxation import gauss_seidel
    from admmkit.linalg.vcycle import _bandwidth, _diagonal_positions, _forward_restrict
    A, B = _elasticity()
    A = sp.csr_matrix(A)
    A.sort_indices()
    amg = AMGPreconditioner(A, B, blocksize=2, max_coarse=50)
    P = sp.csr_matrix(amg.ml.levels[0].P)
    P.sort_indices()
    b = np.random.default_rng(4).standard_normal(A.shape[0])
    diagonal = _diagonal_positions(A.indptr, A.indices)
    width = _bandwidth(A.indptr, A.indices)
    rows, cols = A.nonzero()
    assert width == np.abs(rows - cols).max()
    x, coarse_b = np.empty_like(b), np.empty(P.shape[1])
    # a lag beyond the bandwidth is still right (only later); the bandwidth itself is the earliest
    _forward_restrict(A.indptr, A.indices, A.data, diagonal, 1.0 / A.data[diagonal], b, x,
                      P.indptr, P.indices, P.data, coarse_b, width + lag_shift)
    x_ref = np.zeros_like(b)
    gauss_seidel(A, x_ref, b, iterations=1, sweep="forward")
    assert np.linalg.norm(x - x_ref) <= 1e-13 * np.linalg.norm(x_ref)
    r_ref = P.T @ (b - A @ x_ref)
    assert np.linalg.norm(coarse_b - r_ref) <= 1e-11 * np.linalg.norm(P.T @ b)


@pytest.mark.parametrize("fmt", ["bsr", "csr"])
def test_arnoldi_spectral_radius_is_pyamgs_number(fmt):
    from pyamg.util.linalg import approximate_spectral_radius
    from admmkit.linalg.arnoldi import arnoldi_spectral_radius
    A, _ = pyamg.gallery.linear_elasticity((30, 30), format=fmt)
    A1, A2 = A.copy(), A.copy()
    np.random.seed(5)
    ours = arnoldi_spectral_radius(A1, 10)
    np.random.seed(5)
    theirs = approximate_spectral_radius(A2, maxiter=10, restart=0)
    assert ours == theirs and A1.rho == ours                  # bit for bit, cached where pyamg looks
    dense = np.linalg.eigvalsh(A.toarray())
    assert 0.5 * dense.max() < ours <= dense.max() * (1 + 1e-12)
    with pytest.raises(ValueError, match="steps"):
        arnoldi_spectral_radius(A.copy(), 0)


def test_pencil_products_are_the_products_of_the_pencil_matrices():
    from admmkit.linalg.amg import PencilMatrix
    from admmkit.linalg.symmetric import SymmetricPattern
    A, _ = _elasticity()
    K = sp.csr_matrix(A + sp.eye(A.shape[0]))
    K.sort_indices()
    rows = np.arange(0, K.shape[0], 37)
    D = sp.csr_matrix((np.linspace(1, 2, rows.size), (rows, rows)), shape=K.shape)
    D = sp.csr_matrix(D + sp.csr_matrix((np.full(rows.size - 1, 0.25), (rows[:-1], rows[:-1] + 1)), shape=K.shape)
                      + sp.csr_matrix((np.full(rows.size - 1, 0.25), (rows[:-1] + 1, rows[:-1])), shape=K.shape))
    pencil = PencilMatrix(K, D)
    at = SymmetricPattern(pencil.pattern).pencil_products(pencil.K_data, pencil.D_data)
    x = np.random.default_rng(6).standard_normal(K.shape[0])
    for rho in (0.5, 3e4):
        gathered = SymmetricPattern(pencil.pattern).product(pencil.at(rho))(x)
        assert np.array_equal(at(rho)(x), gathered)               # the same values, bit for bit
        assert np.linalg.norm(gathered - (K + rho * D) @ x) <= 1e-13 * np.linalg.norm((K + rho * D) @ x)


@pytest.mark.parametrize("values", [np.float64, np.float32])
def test_block_finest_level_gives_the_csr_cycle_bit_for_bit(values, monkeypatch):
    from admmkit.linalg.vcycle_blocks import BlockLevel
    A, B = _elasticity()
    amg = AMGPreconditioner(A, B, blocksize=2, max_coarse=50)
    r = np.random.default_rng(7).standard_normal(A.shape[0])
    from admmkit.linalg.vcycle_blocks3 import BlockLevel3
    blocks = VCycle(amg.ml, values=values)
    assert blocks.first is not None                        # 2 x 2 blocks of A, 2 x 3 of P: the block path
    assert isinstance(blocks.block[1], BlockLevel3)         # below it 3 x 3 blocks (three rigid modes)
    monkeypatch.setattr(BlockLevel, "eligible", staticmethod(lambda A, P: False))
    monkeypatch.setattr(BlockLevel3, "eligible", staticmethod(lambda A, P: False))
    rows = VCycle(amg.ml, values=values)
    assert rows.first is None and not any(rows.block)
    assert np.array_equal(blocks(r), rows(r))
    amg.refresh(sp.csr_matrix(A + 0.5 * sp.eye(A.shape[0])))   # new values on the same pattern
    assert np.array_equal(blocks.refreshed(amg.ml)(r), rows.refreshed(amg.ml)(r))


def test_block_level_is_used_only_where_it_applies():
    from admmkit.linalg.vcycle_blocks import BlockLevel
    A, B = _elasticity()
    P3 = sp.bsr_matrix(sp.random(A.shape[0], 30, density=0.1, random_state=0), blocksize=(2, 3))
    assert BlockLevel.eligible(A, P3)
    assert not BlockLevel.eligible(A, sp.csr_matrix(P3))                     # P not in blocks
    assert not BlockLevel.eligible(A, sp.bsr_matrix(sp.csr_matrix(P3)[:, :20], blocksize=(2, 2)))
    scalar = AMGPreconditioner(sp.csr_matrix(pyamg.gallery.poisson((30, 30))), None, max_coarse=50)
    assert VCycle(scalar.ml).first is None                                     # a scalar problem: CSR levels


def test_refreshed_cycle_reuses_kept_patterns_and_equals_a_new_one():
    A, B = _elasticity()
    A = sp.csr_matrix(A)
    rows = np.arange(0, A.shape[0], 11)
    D = sp.csr_matrix((np.ones(rows.size), (rows, rows)), shape=A.shape)
    from admmkit.linalg.amg import PencilMatrix
    pencil = PencilMatrix(A, D)
    amg = AMGPreconditioner(pencil.at(1.0), B, blocksize=2, max_coarse=50, D=D, rho=1.0)
    r = np.random.default_rng(8).standard_normal(A.shape[0])
    cycle = VCycle(amg.ml, values=np.float32)
    for rho in (3.0, 9.0):
        amg.refresh(pencil.at(rho), rho)
        again = cycle.refreshed(amg.ml)
        assert again._diagonal[0] is cycle._diagonal[0]           # the finest pattern kept: not searched again
        assert np.array_equal(again(r), VCycle(amg.ml, values=np.float32)(r))
        cycle = again


def test_node_pair_products_equal_the_upper_triangle_products():
    from admmkit.linalg.symmetric import NodePairPattern
    A, _ = _elasticity()
    A = sp.csr_matrix(A + 2 * sp.eye(A.shape[0]))
    A.sort_indices()
    x = np.random.default_rng(9).standard_normal(A.shape[0])
    assert_block_product_is_symmetric_patterns(NodePairPattern, A, x, every=5)   # and with holes in 2 x 2 blocks
    with pytest.raises(ValueError, match="even order"):
        NodePairPattern(sp.csr_matrix(sp.eye(3)))


@pytest.mark.parametrize("values", [np.float64, np.float32])
def test_3d_block_levels_give_the_csr_cycle_to_round_off(values):
    from admmkit.linalg.vcycle_blocks3d import CoarseLevel6, FinestLevel3D
    A, B = _elasticity3d()
    assert B.shape[1] == 6
    amg = AMGPreconditioner(A, B, blocksize=3, max_coarse=50, cycle_values=np.dtype(values).name)
    blocks, rows = VCycle(amg.ml, values=values), VCycle(amg.ml, values=values, blocks3d=False)
    assert isinstance(blocks.block[0], FinestLevel3D) and isinstance(blocks.block[1], CoarseLevel6)
    assert not any(rows.block) and blocks.first is None       # the 2-D finest level's own storage: not this one
    r = np.random.default_rng(8).standard_normal(A.shape[0])
    z, z_rows = blocks(r), rows(r)
    assert not np.array_equal(z, z_rows)                      # the backward sweep sums in another order
    assert np.linalg.norm(z - z_rows) <= 1e-13 * np.linalg.norm(z_rows)
    assert np.linalg.norm(z - _pyamg_cycle(amg.ml, r)) <= (1e-13 if values == np.float64 else 1e-5) * np.linalg.norm(z)
    assert abs(r @ blocks(z) - z @ blocks(r)) <= 1e-12 * abs(r @ blocks(z))    # still symmetric
    amg.refresh(sp.csr_matrix(A + 0.5 * sp.eye(A.shape[0])))    # new values on the same pattern
    fresh, refreshed = VCycle(amg.ml, values=values), blocks.refreshed(amg.ml)
    assert np.array_equal(refreshed(r), fresh(r))


def test_3d_descent_is_the_csr_descent():
    from admmkit.linalg.vcycle import _forward_restrict
    A, B = _elasticity3d()
    amg = AMGPreconditioner(A, B, blocksize=3, max_coarse=50)
    blocks, rows = VCycle(amg.ml), VCycle(amg.ml, blocks3d=False)
    level, b = blocks.block[0], np.random.default_rng(9).standard_normal(A.shape[0])
    x, coarse_b, x_rows, coarse_rows = (np.empty(n) for n in (A.shape[0], level.P_shape[1]) * 2)
    lag = (blocks._bandwidth[0] + 2) // 3
    level.descent(level.indptr, level.indices, level.data, level.block_diagonal, blocks._inverse[0], b, x,
                  level.P_indptr, level.P_indices, level.P_data, coarse_b, lag)
    M, P = rows.A[0], rows.P[0]
    _forward_restrict(M.indptr, M.indices, M.data, rows._diagonal[0], rows._inverse[0], b, x_rows,
                      P.indptr, P.indices, P.data, coarse_rows, rows._bandwidth[0])
    assert np.array_equal(x, x_rows)                         # the sweep: CSR's sums in CSR's order
    assert np.linalg.norm(coarse_b - coarse_rows) <= 1e-13 * np.linalg.norm(coarse_rows)   # the residual: round-off
    assert not np.array_equal(coarse_b, coarse_rows)       # from the lower triangle, in another order


def test_amg_option_keeps_the_csr_cycle_of_3d_problems():
    A, B = _elasticity3d(6)
    r = np.random.default_rng(10).standard_normal(A.shape[0])
    off = AMGPreconditioner(A, B, blocksize=3, max_coarse=50, cycle_blocks3d=False)
    z = off(r)
    assert not any(off._cycle.block)
    assert np.array_equal(z, VCycle(off.ml, blocks3d=False)(r))
