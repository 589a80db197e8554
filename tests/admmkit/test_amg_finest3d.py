"""The compiled finest level of the 3-D smoothed aggregation (admmkit/linalg/amg_finest3d.py): pyamg's arrays."""
import numpy as np
import pytest
import scipy.sparse as sp

from admmkit.kernels import library_kernels
from admmkit.linalg import amg_finest3d
from admmkit.linalg.amg import AMGPreconditioner


def block3d(h):
    """K + rho D of the 3-D block in the solver's node order, its rigid-body modes, D."""
    from admmkit.problems.contact.model.assembly3d import assemble3d
    from admmkit.problems.contact.model.scene3d import example2_3d
    from admmkit.problems.contact.solvers.problem import contact_problem
    solver = contact_problem(assemble3d(example2_3d(h=h)), mode="iterative").solver
    return solver.matrix(1e3), solver.near_null, solver.D


def chain(n_nodes, seed=0):
    """An SPD matrix in 3 x 3 blocks coupling node i to i - 1 and i + 1: the aggregates of every row come in
    ascending order, so P takes bsr_minus_bsr's canonical path."""
    rng = np.random.default_rng(seed)
    off = [rng.standard_normal((3, 3)) * 0.3 for _ in range(n_nodes - 1)]
    blocks = [[None] * n_nodes for _ in range(n_nodes)]
    for i in range(n_nodes):
        s = rng.standard_normal((3, 3)) * 0.1
        blocks[i][i] = np.eye(3) * 4.0 + s + s.T              # dense: no entry of a block left out
    for i, b in enumerate(off):
        blocks[i][i + 1], blocks[i + 1][i] = b, b.T
    A = sp.bmat(blocks, format="csr")
    A.sort_indices()
    return A, rng.standard_normal((3 * n_nodes, 6)), sp.csr_matrix(A.shape)


def same(M, N) -> bool:
    """The same sparse type, format, index dtype and arrays, bit for bit."""
    return (type(M) is type(N) and M.format == N.format and M.indices.dtype == N.indices.dtype
            and np.array_equal(M.indptr, N.indptr) and np.array_equal(M.indices, N.indices)
            and M.data.shape == N.data.shape and np.array_equal(M.data, N.data))


@pytest.mark.parametrize("case", ["block3d h = 1/16", "block3d h = 1/10", "chain"])
def test_the_compiled_finest_level_is_pyamgs_bit_for_bit(case, monkeypatch):
    A, B, D = chain(700) if case == "chain" else block3d(1 / 16 if "16" in case else 1 / 10)
    calls = []
    real = amg_finest3d.smoothed_prolongator
    monkeypatch.setattr(amg_finest3d, "smoothed_prolongator", lambda *a: calls.append(a[9]) or real(*a))
    options = dict(blocksize=3, max_coarse=500 if case != "chain" else 100, D=D, rho=1e3, spectral_steps=10)
    pyamgs, mine = AMGPreconditioner(A, B, finest3d=False, **options), AMGPreconditioner(A, B, **options)
    assert calls == [case == "chain"]              # canonical only for the chain; the compiled level was made
    assert mine.levels == pyamgs.levels >= 2
    for a, b in zip(pyamgs.ml.levels, mine.ml.levels):
        assert same(a.A, b.A)
        assert np.array_equal(a.B, b.B)
        if hasattr(a, "P"):
            assert same(a.P, b.P) and same(a.R, b.R)
    r = np.random.default_rng(1).standard_normal(A.shape[0])
    assert np.array_equal(pyamgs(r), mine(r))


def test_where_the_compiled_level_does_not_apply_pyamg_sets_up(monkeypatch):
    A, B, D = chain(700)
    assert amg_finest3d.finest_level(A, B[:, :3], lambda op: 1.0, 100) is None          # not six vectors
    assert amg_finest3d.finest_level(A, B, lambda op: 1.0, 1000) is None                # already coarse
    holed = A.copy()
    holed.data[1] = 0.0
    holed.eliminate_zeros()                                                            # a block with a hole
    assert amg_finest3d.finest_level(holed, B, lambda op: 1.0, 100) is None
    made = []
    real = amg_finest3d.finest_level
    monkeypatch.setattr(amg_finest3d, "finest_level", lambda *a: made.append(real(*a)) or made[-1])
    options = dict(blocksize=3, max_coarse=100, D=D, rho=1e3, spectral_steps=10)
    with library_kernels():                                                            # the library path
        assert AMGPreconditioner(A, B, **options).levels >= 2 and made == []
    assert AMGPreconditioner(A, B, spectral_steps=None, **{k: v for k, v in options.items()
                                                            if k != "spectral_steps"}).levels >= 2 and made == []
    assert AMGPreconditioner(holed, B, **options).levels >= 2 and made == [None]        # tried, pyamg's then
    assert AMGPreconditioner(A, B, **options).levels >= 2 and made[-1] is not None


def test_the_scaled_products_are_scipys():
    A, B, _ = block3d(1 / 8)
    dinv = amg_finest3d.inverse_diagonal(A.indptr, A.indices, A.data)
    assert np.array_equal(dinv, 1 / A.diagonal())
    v = np.random.default_rng(2).random((A.shape[0], 1))
    scaled = sp.csr_matrix(A).tobsr(blocksize=(3, 3))
    scaled.data *= dinv.reshape(-1, 3, 1)[np.repeat(np.arange(A.shape[0] // 3), np.diff(scaled.indptr))]
    assert np.array_equal(amg_finest3d.ScaledRows(A, dinv) @ v, scaled @ v)
