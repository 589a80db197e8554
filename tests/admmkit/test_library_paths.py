"""Each hand-written kernel beside its library path: both run here, on small cases, and agree.

The library paths (pyamg's V-cycle, numpy's CG updates, scipy's submatrix and
products) are what a machine without numba runs; ``library_kernels()`` and
``ADMMKIT_KERNELS=library`` switch to them with numba installed, so they
cannot rot (issue #48, item 7).
"""
import os
import subprocess
import sys

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from admmkit.linalg.amg import AMGPreconditioner, PencilMatrix
from admmkit.linalg.cg import cg_direction, cg_step, pcg
from admmkit.kernels import hand_written, library_kernels
from admmkit.linalg.submatrix import principal_submatrix
from admmkit.linalg.symmetric import pencil_products


def laplacian(n: int, d: int = 1) -> sp.csr_matrix:
    """The 2-D five-point Laplacian on an n x n grid, for d components numbered node by node."""
    t = sp.diags([-np.ones(n - 1), 2 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1])
    L = sp.kronsum(t, t)
    return sp.kron(L, sp.identity(d)).tocsr()


def both(f):
    """f() with the hand-written kernels, then with the library paths."""
    with library_kernels(False):
        ours = f()
    with library_kernels(True):
        theirs = f()
    return ours, theirs


def test_the_switch_and_its_environment_variable():
    with library_kernels(True):
        assert not hand_written()
        with library_kernels(False):
            assert hand_written()
    code = "from admmkit.kernels import hand_written; print(hand_written())"
    env = dict(os.environ, ADMMKIT_KERNELS="library")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


@pytest.mark.parametrize("d", [1, 2])
def test_vcycle_is_pyamgs_cycle(d):
    """The compiled V-cycle (scalar and 2 x 2 node blocks) gives pyamg's cycle's values."""
    A = laplacian(24, d)
    near_null = np.kron(np.ones((A.shape[0] // d, 1)), np.eye(d))
    r = np.random.default_rng(0).standard_normal(A.shape[0])

    def cycle():
        return AMGPreconditioner(A, near_null, blocksize=d, max_coarse=20)(r)
    ours, theirs = both(cycle)
    assert np.linalg.norm(ours) > 0
    np.testing.assert_allclose(ours, theirs, rtol=1e-10, atol=1e-12 * np.linalg.norm(theirs))


def test_cg_updates_are_numpys():
    rng = np.random.default_rng(1)
    x, r, p, Ap, z = (rng.standard_normal(50) for _ in range(5))

    def updates():
        xx, rr, pp = x.copy(), r.copy(), p.copy()
        cg_step(xx, rr, pp, Ap, 0.3)
        cg_direction(pp, z, 0.7)
        return np.concatenate([xx, rr, pp])
    ours, theirs = both(updates)
    np.testing.assert_array_equal(ours, theirs)


def test_pcg_with_the_amg_cycle_solves_on_both_paths():
    A = laplacian(20)
    b = np.ones(A.shape[0])
    exact = spla.spsolve(A.tocsc(), b)

    def solve():
        M = AMGPreconditioner(A, np.ones((A.shape[0], 1)), max_coarse=20)
        return pcg(A.__matmul__, b, np.zeros_like(b), M, tol=1e-10, maxiter=200)[0]
    for x in both(solve):
        assert np.linalg.norm(x - exact) <= 1e-8 * np.linalg.norm(exact)


def test_principal_submatrix_is_scipys_indexing():
    A = laplacian(9)
    index = np.random.default_rng(2).permutation(A.shape[0])[:40]
    ours, theirs = both(lambda: principal_submatrix(A, index, compiled=True))
    assert ours.nnz == theirs.nnz > 0
    np.testing.assert_array_equal(ours.toarray(), theirs.toarray())


@pytest.mark.parametrize("blocksize", [1, 2])
def test_pencil_products_are_scipys(blocksize):
    K = laplacian(8, blocksize)
    D = sp.diags(np.where(np.arange(K.shape[0]) % 7 == 0, 1.0, 0.0)).tocsr()
    pencil = PencilMatrix(K, D, blocksize=1)
    x = np.random.default_rng(3).standard_normal(K.shape[0])
    ours, theirs = both(lambda: pencil_products(pencil, blocksize)(2.5)(x))
    np.testing.assert_allclose(ours, theirs, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(theirs, (K + 2.5 * D) @ x, rtol=1e-13, atol=1e-13)
