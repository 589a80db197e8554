"""Shared test fixtures: a tiny problem written against the public protocol only.

The contact plug-in's operator cache (problems/contact/model/operator_cache.py) goes to a folder of this test
process (inherited by the processes it starts), never to the user's ~/.cache/admmkit.
"""
import atexit
import os
import shutil
import tempfile

import numpy as np
import pytest

os.environ["ADMMKIT_CACHE_DIR"] = tempfile.mkdtemp(prefix="admmkit-test-cache-")
atexit.register(shutil.rmtree, os.environ["ADMMKIT_CACHE_DIR"], True)

from admmkit import Problem


class Obstacle1D(Problem):
    """min 1/2 x'Dx - b'x  s.t.  x <= g, split as x - z = 0 in the weighted inner product (.,.)_M.

    D and M are diagonal, so every step is explicit and the iterates can be
    computed by hand.  This is the contact problem with K = D, B = I, M_c = M.
    """

    def __init__(self, d, b, g, m):
        self.d, self.b, self.g, self.m = (np.asarray(v, dtype=float) for v in (d, b, g, m))
        self.n = self.d.size

    def x_step(self, z, lam, rho, x):
        return (self.b - self.m * lam + rho * self.m * z) / (self.d + rho * self.m)

    def z_step(self, Ax, lam, rho, z):
        return np.minimum(self.g, Ax + lam / rho)

    def apply_A(self, x):
        return x.copy()

    def inner(self, a, b):
        return float(np.sum(self.m * a * b))

    def adjoint_norm(self, y):
        return float(np.linalg.norm(self.m * y))

    def solution(self):
        x = np.minimum(self.g, self.b / self.d)
        lam = (self.b - self.d * x) / self.m
        return x, lam


@pytest.fixture
def scalar_problem():
    """a = 2, b = 4, g = 1, M = 1: solution x = 1, lam = 2."""
    return Obstacle1D([2.0], [4.0], [1.0], [1.0])


@pytest.fixture
def vector_problem():
    rng = np.random.default_rng(3)
    n = 12
    return Obstacle1D(rng.uniform(1, 3, n), rng.uniform(-2, 4, n), rng.uniform(0.2, 1.0, n), rng.uniform(0.5, 2, n))


def anderson_inner(w, rho, a, b) -> float:
    """(a, b)_W of :mod:`admmkit.loop.anderson_kernel`'s docstring, one sum at a time (the oracle of its Gram pass):
    rho sum_{i<m} w_i a_i b_i + (sum_{i<m} w_i a_{m+i} b_{m+i}) / rho."""
    m = len(w)
    su = sl = 0.0
    for i in range(m):
        su += w[i] * a[i] * b[i]
    for i in range(m):
        sl += w[i] * a[m + i] * b[m + i]
    return rho * su + sl / rho


def assert_block_product_is_symmetric_patterns(pattern, A, x, every: int) -> None:
    """A node-block product layout (``pattern``: :class:`admmkit.linalg.symmetric.NodePairPattern` or
    ``NodeTriplePattern``) gives y = A x with :class:`~admmkit.linalg.symmetric.SymmetricPattern`'s values bit
    for bit, on A and on A with holes inside its node blocks (every ``every``-th stored entry dropped, then the
    pattern made symmetric again), and A x to round-off."""
    import scipy.sparse as sp
    from admmkit.linalg.symmetric import SymmetricPattern
    holes = sp.csr_matrix(A, copy=True)     # its own arrays: A is checked below too
    holes.data[::every] = 0.0
    holes.eliminate_zeros()
    holes = sp.csr_matrix(holes + holes.T)
    holes.sort_indices()
    for M in (A, holes):
        y = pattern(M).product(M)(x)
        assert np.array_equal(y, SymmetricPattern(M).product(M)(x))
        assert np.linalg.norm(y - M @ x) <= 1e-13 * np.linalg.norm(M @ x)
