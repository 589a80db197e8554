"""Anderson's kernel, restructured for speed (a Cholesky factor a column at a time, the Gram pass over padded
columns), must keep every bit of the textbook loops it replaced: the compiled segment's runs stay the Python
loop's, and a run's iterates stay what they were."""
import math

import numpy as np
import pytest

from admmkit import kernels
from admmkit.kernels import AVAILABLE, compiled_code
from admmkit.loop.anderson_kernel import VECTOR, AndersonArrays, _gram_row_and_rhs, _solve_gram
from tests.conftest import anderson_inner

WAYS = [False, pytest.param(True, marks=pytest.mark.skipif(not AVAILABLE, reason="numba not installed"))]


def textbook_solve(gram, count, regularization, rhs):
    """(G + reg max diag(G) I)^-1 rhs by a Cholesky factor a row at a time, each sum over c in the order of c; None
    where the factor fails (a pivot not positive or not finite) or gamma is not finite."""
    top = max([0.0] + [gram[a, a] for a in range(count)])
    shift = regularization * top
    L = np.zeros((count, count))
    for a in range(count):
        for b in range(a + 1):
            s = gram[a, b] + (shift if a == b else 0.0)
            for c in range(b):
                s -= L[a, c] * L[b, c]
            if a == b:
                if not (s > 0.0) or not math.isfinite(s):
                    return None
                L[a, a] = math.sqrt(s)
            else:
                L[a, b] = s / L[b, b]
    gamma = np.zeros(count)
    for a in range(count):
        s = rhs[a]
        for c in range(a):
            s -= L[a, c] * gamma[c]
        gamma[a] = s / L[a, a]
    for a in range(count - 1, -1, -1):
        s = gamma[a]
        for c in range(a + 1, count):
            s -= L[c, a] * gamma[c]
        gamma[a] = s / L[a, a]
    return gamma if np.isfinite(gamma).all() else None


@pytest.mark.parametrize("compiled", WAYS)
def test_the_column_cholesky_is_the_row_one_bit_for_bit(compiled):
    rng = np.random.default_rng(11)
    mem, failed = 10, 0
    for trial in range(400):
        count = int(rng.integers(1, mem + 1))
        X = rng.standard_normal((int(rng.integers(1, 30)), mem)) * 10.0 ** rng.integers(-6, 6, mem)
        gram = X.T @ X
        if trial % 5 == 0:                          # not positive definite: a negative or a zero pivot
            gram[trial % count, trial % count] = -1.0 if trial % 10 else 0.0
        rhs = rng.standard_normal(mem)
        regularization = (0.0, 1e-10, 1e-3)[trial % 3]
        chol, gamma = np.full((mem, mem), np.nan), np.full(mem, np.nan)
        with compiled_code(compiled):
            ok = _solve_gram(gram, count, regularization, rhs, chol, gamma)
        want = textbook_solve(gram, count, regularization, rhs)
        assert ok == (want is not None)
        if ok:
            assert np.array_equal(gamma[:count], want)
        failed += not ok
    assert 40 <= failed < 400                       # both ways were taken


@pytest.mark.parametrize("compiled", WAYS)
@pytest.mark.parametrize("m", [1, 10, 37])
def test_the_padded_gram_pass_adds_each_sum_in_order(compiled, m):
    """AndersonArrays pads the memory's columns to whole vectors (10 -> 12); the columns past ``count`` hold old
    (here random) differences; each Gram entry and right side is still its own sum over i in order."""
    mem, rho = 10, 0.37
    arrays = AndersonArrays(mem, 2 * m)
    assert arrays.dG.shape == (2 * m, 12) and arrays.acc.shape[1] % VECTOR == 0
    rng = np.random.default_rng(m)
    w, g = rng.uniform(0.1, 3, m), rng.standard_normal(2 * m)
    arrays.dG[:, :mem] = rng.standard_normal((2 * m, mem))

    def inner(a, b):
        return anderson_inner(w, rho, a, b)

    for p, count, extrapolate in ((3, 10, True), (6, 7, True), (0, 1, False), (-1, 5, True), (8, 9, False)):
        gram, rhs = np.full((mem, mem), np.nan), np.full(mem, np.nan)
        with compiled_code(compiled):
            _gram_row_and_rhs(w, rho, arrays.dG, g, p, count, extrapolate, gram, rhs, arrays.acc)
        for q in range(count):
            if p >= 0:
                assert gram[p, q] == gram[q, p] == inner(arrays.dG[:, p], arrays.dG[:, q])
            assert (rhs[q] == inner(arrays.dG[:, q], g)) if extrapolate else np.isnan(rhs[q])
        assert np.isnan(rhs[count:]).all() and np.isnan(gram[:, count:]).all()


@pytest.mark.skipif(not kernels.AVAILABLE, reason="numba is not installed")
def test_a_private_option_numba_does_not_know_is_dropped():
    """Anderson's kernels ask for numba's private ``_nrt=False``; a numba without that option compiles them without
    it instead of failing (admmkit.kernels.known_options)."""
    assert kernels.known_options({"cache": True, "_nrt": False}) == {"cache": True, "_nrt": False}
    assert kernels.known_options({"cache": False, "_no_such_option": 1}) == {"cache": False}

    @kernels.kernel(cache=False, _no_such_option=1)
    def twice(x):
        return 2.0 * x
    with kernels.compiled_code(True):
        assert twice(1.5) == 3.0 and twice._dispatcher is not None
