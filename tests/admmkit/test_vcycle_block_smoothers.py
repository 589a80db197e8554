"""The block smoothers of the finest level of a 3-D V-cycle (admmkit.linalg.vcycle_blockgs3d, vcycle_jacobi3d)
against numpy cycles."""
import numpy as np
import pytest
import scipy.sparse as sp

pytest.importorskip("numba")
pyamg = pytest.importorskip("pyamg")

from admmkit.linalg.amg import AMGPreconditioner  # noqa: E402
from admmkit.linalg.vcycle import VCycle  # noqa: E402
from admmkit.linalg.vcycle_blocks3d import FinestLevel3D  # noqa: E402
from admmkit.linalg.vcycle_blockgs3d import FinestLevel3DBlockGS  # noqa: E402
from admmkit.linalg.vcycle_jacobi3d import OMEGA_LAMBDA, FinestLevel3DJacobi, largest_eigenvalue  # noqa: E402
from tests.test_vcycle import _elasticity, _elasticity3d  # noqa: E402


def _hierarchy(values="float64"):
    """3-D elasticity (the SPD stiffness of positively oriented tetrahedra) and its AMG."""
    A, B = _elasticity3d(8)
    return A, AMGPreconditioner(A, B, blocksize=3, max_coarse=50, cycle_values=values)


def _block_diagonal(A):
    """D: A's 3 x 3 diagonal node blocks, as a sparse matrix."""
    nb = A.shape[0] // 3
    blocks = np.array([A[3 * I:3 * I + 3, 3 * I:3 * I + 3].toarray() for I in range(nb)])
    return sp.block_diag(blocks, format="csr")


def test_block_jacobi_cycle_is_the_numpy_cycle():
    A, amg = _hierarchy()
    cycle = VCycle(amg.ml, smoother="block_jacobi")
    level = cycle.block[0]
    assert type(level) is FinestLevel3DJacobi
    D = _block_diagonal(A)
    Dinv = sp.csr_matrix(np.linalg.inv(D.toarray()))
    P = amg.ml.levels[0].P
    b = np.random.default_rng(3).standard_normal(A.shape[0])
    x = level.omega * (Dinv @ b)                                       # pre-smoother from zero
    y = x + P @ cycle._correction(0, P.T @ (b - A @ x))               # coarse-grid correction (the same coarse cycle)
    x = y + level.omega * (Dinv @ (b - A @ y))                         # post-smoother, the same M = D / omega
    z = cycle(b)
    assert np.linalg.norm(z - x) <= 1e-12 * np.linalg.norm(x)
    assert not np.allclose(z, VCycle(amg.ml)(b))                       # another smoother than Gauss-Seidel


def test_block_gauss_seidel_cycle_is_the_numpy_cycle():
    A, amg = _hierarchy()
    cycle = VCycle(amg.ml, smoother="block_gauss_seidel")
    assert type(cycle.block[0]) is FinestLevel3DBlockGS
    node = np.arange(A.shape[0]) // 3
    dense = A.toarray()
    lower = np.where(node[:, None] >= node[None, :], dense, 0.0)          # D + L in 3 x 3 node blocks
    upper = np.where(node[:, None] <= node[None, :], dense, 0.0)          # D + L'
    P = amg.ml.levels[0].P
    b = np.random.default_rng(4).standard_normal(A.shape[0])
    x = np.linalg.solve(lower, b)                                         # forward block sweep from zero
    x = x + P @ cycle._correction(0, P.T @ (b - A @ x))
    x = x + np.linalg.solve(upper, b - A @ x)                             # backward block sweep
    z = cycle(b)
    assert np.linalg.norm(z - x) <= 1e-12 * np.linalg.norm(x)
    assert not np.allclose(z, VCycle(amg.ml)(b))                          # not the pointwise sweeps


@pytest.mark.parametrize("smoother", ["block_gauss_seidel", "block_jacobi"])
@pytest.mark.parametrize("values", ["float64", "float32"])
def test_block_cycles_are_symmetric_positive_definite(values, smoother):
    A, amg = _hierarchy(values)
    cycle = VCycle(amg.ml, values=np.dtype(values), smoother=smoother)
    rng = np.random.default_rng(5)
    for _ in range(3):
        u, v = rng.standard_normal((2, A.shape[0]))
        assert abs(v @ cycle(u) - u @ cycle(v)) <= 1e-12 * abs(u @ cycle(u))
        assert u @ cycle(u) > 0
    if smoother != "block_jacobi":
        return
    # omega lambda_max(D^-1 A) = OMEGA_LAMBDA < 2: the smoother converges in the energy norm
    D = _block_diagonal(A).toarray()
    lam = np.linalg.eigvals(np.linalg.solve(D, A.toarray())).real.max()
    level = cycle.block[0]
    estimate = largest_eigenvalue(level.indptr, level.indices, level.data, np.linalg.inv(_diagonal_blocks(D)))
    assert 0.95 * lam <= estimate <= lam * (1 + 1e-9)
    assert cycle.block[0].omega == pytest.approx(OMEGA_LAMBDA / estimate, rel=1e-6)


def _diagonal_blocks(D):
    """The (nb, 3, 3) diagonal blocks of a dense block-diagonal matrix."""
    nb = D.shape[0] // 3
    return np.array([D[3 * I:3 * I + 3, 3 * I:3 * I + 3] for I in range(nb)])


def test_block_smoothers_iteration_counts():
    A, amg = _hierarchy()
    from admmkit.linalg.cg import pcg
    b = np.random.default_rng(2).standard_normal(A.shape[0])
    counts = {}
    for smoother in ("gauss_seidel", "block_gauss_seidel", "block_jacobi"):
        cycle = VCycle(amg.ml, smoother=smoother)
        x, its, *_ = pcg(lambda v: A @ v, b, np.zeros_like(b), cycle, tol=1e-8, maxiter=200)
        assert np.linalg.norm(b - A @ x) <= 1e-6 * np.linalg.norm(b)
        counts[smoother] = its
    assert counts["block_gauss_seidel"] < counts["gauss_seidel"] <= counts["block_jacobi"]
    assert counts["block_jacobi"] <= 1.5 * counts["gauss_seidel"]


@pytest.mark.parametrize("smoother", ["block_gauss_seidel", "block_jacobi"])
def test_updated_entries_give_the_refreshed_level(smoother):
    A, amg = _hierarchy("float32")
    cycle = VCycle(amg.ml, values=np.float32, smoother=smoother)
    level = cycle.block[0]
    # a contact-like change: whole diagonal blocks of some nodes (as rho B'M_c B changes them), on A's pattern
    A = sp.csr_matrix(A)
    A.sort_indices()
    block = 1e3 * np.array([[2.0, 0.5, 0.1], [0.5, 3.0, 0.2], [0.1, 0.2, 4.0]])
    positions, added = [], []
    for I in (0, 7, 40):
        for r in range(3):
            i = 3 * I + r
            for p in range(A.indptr[i], A.indptr[i + 1]):
                if A.indices[p] // 3 == I:
                    positions.append(p)
                    added.append(block[r, A.indices[p] - 3 * I])
    positions = np.array(positions)
    assert positions.size == 27
    A_new = A.copy()
    A_new.data[positions] += added
    inverse = "scaled_inverse" if smoother == "block_jacobi" else "block_inverse"
    before = getattr(level, inverse).copy()
    expected = level.refreshed(A_new)
    cycle.update_entries(0, A_new, positions)
    assert np.array_equal(level.data, expected.data)
    assert not np.array_equal(getattr(level, inverse), before)            # the changed blocks' inverses are new
    assert np.array_equal(getattr(level, inverse), getattr(expected, inverse))
    if smoother == "block_jacobi":
        assert level.omega == expected.omega


def test_smoother_names():
    _, amg = _hierarchy()
    with pytest.raises(ValueError, match="smoother must be one of gauss_seidel, block_gauss_seidel, block_jacobi"):
        VCycle(amg.ml, smoother="jacobi")
    assert type(VCycle(amg.ml).block[0]) is FinestLevel3D                # Gauss-Seidel stays the default
    A2, B2 = _elasticity()                                               # a 2-D finest level keeps Gauss-Seidel
    amg2 = AMGPreconditioner(A2, B2, blocksize=2, max_coarse=50)
    r = np.random.default_rng(0).standard_normal(A2.shape[0])
    assert np.array_equal(VCycle(amg2.ml, smoother="block_jacobi")(r), VCycle(amg2.ml)(r))
    with pytest.raises(ValueError, match="cycle_smoother must be gauss_seidel, block_gauss_seidel or block_jacobi, "
                                         "got 'sor'"):
        AMGPreconditioner(A2, B2, blocksize=2, cycle_smoother="sor")
    A3, B3 = _elasticity3d(6)
    r3 = np.ones(A3.shape[0])
    for smoother, kind in (("block_jacobi", FinestLevel3DJacobi), ("gauss_seidel", FinestLevel3D),
                           (None, FinestLevel3DBlockGS)):               # block Gauss-Seidel: the 3-D default
        options = {} if smoother is None else {"cycle_smoother": smoother}
        pre = AMGPreconditioner(A3, B3, blocksize=3, max_coarse=50, **options)
        pre(r3)
        assert type(pre._cycle.block[0]) is kind
    z = AMGPreconditioner(A2, B2, blocksize=2, max_coarse=50)(r)         # 2-D: the pointwise sweeps, as before
    assert np.array_equal(z, VCycle(amg2.ml)(r))


def _ascent_with_array_sums(level, x, b, coarse_x, lag):
    """The block Gauss-Seidel ascent written with the generic kernels' array of sums
    (vcycle_blocks3d._add_blocks_descending), as it was before its sums were held in scalars."""
    from admmkit.linalg.vcycle_blocks3d import _add_blocks_descending
    from admmkit.linalg.vcycle_jacobi3d import block_times
    nb = level.indptr.size - 1
    for step in range(nb + lag):
        I = nb - 1 - step
        if I >= 0:
            s = np.zeros(3)
            _add_blocks_descending.py_func(level.P_indices, level.P_data, coarse_x, level.P_indptr[I],
                                           level.P_indptr[I + 1] - 1, s, 3, 6, 18)
            x[3 * I:3 * I + 3] = x[3 * I:3 * I + 3] + s
        I = nb - 1 - step + lag
        if I < nb:
            kd, s = level.block_diagonal[I], np.zeros(3)
            _add_blocks_descending.py_func(level.indices, level.data, x, kd + 1, level.indptr[I + 1] - 1, s, 3, 3, 9)
            _add_blocks_descending.py_func(level.indices, level.data, x, level.indptr[I], kd - 1, s, 3, 3, 9)
            x[3 * I:3 * I + 3] = block_times.py_func(level.block_inverse, I, *(b[3 * I:3 * I + 3] - s))
    return x


@pytest.mark.parametrize("values", ["float64", "float32"])
def test_block_gauss_seidel_ascent_keeps_the_array_sums_bits(values):
    from admmkit.linalg.vcycle_blockgs3d import block_prolong_backward
    A, amg = _hierarchy(values)
    cycle = VCycle(amg.ml, values=np.dtype(values), smoother="block_gauss_seidel")
    level = cycle.block[0]
    rng = np.random.default_rng(7)
    x0, b, coarse_x = rng.standard_normal(A.shape[0]), rng.standard_normal(A.shape[0]), rng.standard_normal(
        level.P_shape[1])
    lag = (cycle._bandwidth[0] + 2) // 3
    ours = x0.copy()
    block_prolong_backward(level.indptr, level.indices, level.data, level.block_diagonal, level.block_inverse, ours,
                           b, level.P_indptr, level.P_indices, level.P_data, coarse_x, lag)
    np.testing.assert_array_equal(ours, _ascent_with_array_sums(level, x0.copy(), b, coarse_x, lag))
