"""admmkit.linalg.amd (a port of SuiteSparse AMD) gives qdldl's own permutation, and qdldl's phases as kernels
(admmkit.linalg.ldl.qdldl_symbolic, qdldl_numeric) in that order give qdldl's factors bit for bit.

The Maros-Meszaros tests skip when ../shared/data/maros_meszaros is absent; the comparisons skip without qdldl.
"""
import warnings
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from admmkit.linalg.amd import _amd_order, amd_order
from admmkit.linalg.ldl import ldl_factor, qdldl_numeric, qdldl_symbolic

MM = Path(__file__).resolve().parents[3] / "shared" / "data" / "maros_meszaros"
needs_mm = pytest.mark.skipif(not MM.is_dir(), reason=f"Maros-Meszaros data not found at {MM}")
#: the KKT matrices compared: n + m at most this
MAX_SIZE = 3000


def qdldl_or_skip():
    """The qdldl module, or skip the test."""
    return pytest.importorskip("qdldl", reason="qdldl is not installed (the reference ordering and factors)")


def kkt_upper(P, A, sigma=1e-6, rho=0.1):
    """The upper triangle (CSC, sorted, no stored zeros) of [[P + sigma I, A'], [A, -I/rho]]."""
    n, m = P.shape[0], A.shape[0]
    K = sp.bmat([[sp.triu(P) + sigma * sp.eye(n), A.T], [None, -sp.eye(m) / rho]], format="csc")
    K.sum_duplicates()
    K.eliminate_zeros()
    K.sort_indices()
    return K


def full(U):
    """The symmetric matrix whose upper triangle is U (both triangles stored, CSC, sorted)."""
    K = sp.csc_matrix(U + sp.triu(U, k=1).T)
    K.sort_indices()
    return K


def qdldl_factor(U, perm):
    """(Lp, Li, Lx, D) of the upper triangle U in the order perm, by qdldl's phases as kernels."""
    Kp, Ki = U.indptr.astype(np.int64), U.indices.astype(np.int64)
    Cp, Ci, to_C, parent, Lp = qdldl_symbolic(Kp, Ki, np.asarray(perm, np.int64))
    Cx = np.zeros(Ci.shape[0])
    Cx[to_C[to_C >= 0]] = U.data[to_C >= 0]
    n = U.shape[0]
    Li, Lx = np.empty(Lp[-1], np.int64), np.empty(Lp[-1])
    D, Dinv, y = np.empty(n), np.empty(n), np.empty(n)
    marked = np.zeros(n, np.bool_)
    scratch = [np.empty(n, np.int64) for _ in range(3)]
    assert qdldl_numeric(Cp, Ci, Cx, parent, Lp, Li, Lx, D, Dinv, y, marked, *scratch) == -1
    return Lp, Li, Lx, D


@pytest.fixture(scope="module")
def maros_meszaros():
    """[(name, upper triangle of the KKT matrix)] of every Maros-Meszaros problem with n + m <= MAX_SIZE."""
    if not MM.is_dir():
        pytest.skip(f"Maros-Meszaros data not found at {MM}")
    from admmkit.problems.qp import load_mat
    from admmkit.problems.qp.mat import read_matrices
    out = []
    for path in sorted(MM.glob("*.mat")):
        P, A = read_matrices(path)                       # sizes first: the large files are not loaded whole
        if P.shape[0] + A.shape[0] > MAX_SIZE:
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")              # VALUES's P is slightly indefinite: the KKT matrix is fine
            qp = load_mat(path, allow_nonconvex=True)
        out.append((path.stem, kkt_upper(sp.csc_matrix(qp.P), sp.csc_matrix(qp.A))))
    return out


@needs_mm
def test_permutation_is_qdldls_on_maros_meszaros(maros_meszaros):
    qdldl = qdldl_or_skip()
    assert len(maros_meszaros) >= 70                     # 78 with the set of 138 problems
    differ = [name for name, U in maros_meszaros
              if not np.array_equal(amd_order(U.indptr, U.indices, U.shape[0]),
                                    qdldl.Solver(U, upper=True).factors()[2])]
    assert differ == []


@needs_mm
def test_ldl_in_qdldls_order_is_qdldls_factor_bit_for_bit(maros_meszaros):
    qdldl = qdldl_or_skip()
    differ = []
    for name, U in maros_meszaros:
        L, D, perm = qdldl.Solver(U, upper=True).factors()
        order = amd_order(U.indptr, U.indices, U.shape[0])
        Lp, Li, Lx, d = qdldl_factor(U, order)
        L = sp.csc_matrix(L)
        same = (np.array_equal(order, perm) and np.array_equal(Lp, L.indptr) and np.array_equal(Li, L.indices)
                and np.array_equal(Lx.view(np.uint64), np.asarray(L.data, np.float64).view(np.uint64))
                and np.array_equal(d.view(np.uint64), np.asarray(D, np.float64).view(np.uint64)))
        if not same:
            differ.append(name)
    assert differ == []


@needs_mm
def test_garbage_collection_of_amds_workspace_is_exercised(maros_meszaros):
    U = dict(maros_meszaros)["PRIMAL3"]
    perm, collections = _amd_order(U.shape[0], U.indptr.astype(np.int64), U.indices.astype(np.int64), False)
    assert collections >= 1                              # Iw compressed at least once (the elbow room ran out)


def random_upper(n, degree, dense_rows=0, isolated=0, seed=0):
    """The upper triangle of a random symmetric, diagonally dominant n x n matrix: about ``degree`` nonzeros a
    row, ``dense_rows`` rows (and columns) filled at 80%, ``isolated`` rows and columns with only their diagonal."""
    rng = np.random.default_rng(seed)
    B = sp.random(n, n, density=min(1.0, degree / (2 * n)), random_state=rng, format="coo")
    S = sp.lil_matrix(B + B.T)
    for r in rng.choice(n, dense_rows, replace=False):
        cols = rng.choice(n, int(0.8 * n), replace=False)
        S[r, cols] = 1.0
        S[cols, r] = 1.0
    for r in rng.choice(n, isolated, replace=False):
        S[r, :] = 0.0
        S[:, r] = 0.0
    S = sp.csc_matrix(S)
    S.setdiag(0.0)
    S.eliminate_zeros()
    S.data[:] = rng.uniform(-1.0, 1.0, S.nnz)
    S = sp.triu(S, k=1) + sp.triu(S, k=1).T
    U = sp.triu(S + sp.diags(np.asarray(abs(S).sum(axis=1)).ravel() + 1.0), format="csc")
    U.sort_indices()
    return U


CASES = {f"random{seed}": dict(n=20 + 29 * seed, degree=1 + seed % 7, isolated=seed % 4, seed=seed) for seed in range(20)}
CASES.update({
    "dense_rows": dict(n=400, degree=4, dense_rows=3, seed=1),          # 0.8 n = 320 > 10 sqrt(n) = 200: set aside
    "dense_and_isolated": dict(n=300, degree=2, dense_rows=2, isolated=30, seed=2),
    "mostly_isolated": dict(n=50, degree=0.2, isolated=40, seed=3),
    "diagonal": dict(n=10, degree=0, seed=4),
    "n2": dict(n=2, degree=2, seed=5),
    "n1": dict(n=1, degree=0, seed=6),
})


@pytest.mark.parametrize("case", list(CASES))
def test_permutation_and_factors_are_qdldls_on_random_patterns(case):
    qdldl = qdldl_or_skip()
    U = random_upper(**CASES[case])
    perm = amd_order(U.indptr, U.indices, U.shape[0])
    assert np.array_equal(np.sort(perm), np.arange(U.shape[0]))
    assert np.array_equal(perm, qdldl.Solver(U, upper=True).factors()[2])
    Lp, Li, Lx, d = qdldl_factor(U, perm)
    L, D, _ = qdldl.Solver(U, upper=True).factors()
    assert np.array_equal(Lx.view(np.uint64), np.asarray(L.data, np.float64).view(np.uint64))
    assert np.array_equal(d.view(np.uint64), np.asarray(D, np.float64).view(np.uint64))


def test_empty_columns_and_no_diagonal_give_qdldls_order():
    qdldl = qdldl_or_skip()
    U = random_upper(n=300, degree=3, dense_rows=2, isolated=40, seed=9)
    strict = sp.triu(U, k=1, format="csc")              # AMD ignores the diagonal: the 40 isolated columns now empty
    strict.sort_indices()
    assert (np.diff(strict.indptr) + np.diff(strict.tocsr().indptr) == 0).sum() >= 40
    assert np.array_equal(amd_order(strict.indptr, strict.indices, 300), qdldl.Solver(U, upper=True).factors()[2])


def test_dense_rows_are_ordered_last():
    U = random_upper(n=400, degree=4, dense_rows=3, seed=1)
    S = full(U)
    degree = np.diff(S.indptr) - 1
    dense = np.flatnonzero(degree > 10 * np.sqrt(400))
    assert dense.size == 3
    perm = amd_order(U.indptr, U.indices, 400)
    assert np.array_equal(perm[-3:], dense)              # in their own order, after every other row


def test_unsorted_columns_are_ordered_as_qdldl_does():
    qdldl = qdldl_or_skip()
    U = random_upper(n=200, degree=4, seed=7)
    rng = np.random.default_rng(0)
    indices, data = U.indices.copy(), U.data.copy()
    for j in range(200):                                 # the rows of each column shuffled (amd_preprocess runs)
        s = slice(U.indptr[j], U.indptr[j + 1])
        if U.indptr[j + 1] - U.indptr[j] > 1:
            shuffle = rng.permutation(U.indptr[j + 1] - U.indptr[j])
            indices[s], data[s] = indices[s][shuffle], data[s][shuffle]
    J = sp.csc_matrix((data, indices, U.indptr), shape=U.shape)
    assert not J.has_sorted_indices
    assert np.array_equal(amd_order(J.indptr, J.indices, 200), qdldl.Solver(J, upper=True).factors()[2])


def test_any_triangle_gives_a_permutation_of_the_same_quality():
    U = random_upper(n=300, degree=5, seed=8)
    for pattern in (U, sp.csc_matrix(U.T), full(U)):     # the order of A + A' may break ties differently
        perm = amd_order(pattern.indptr, pattern.indices, 300)
        assert np.array_equal(np.sort(perm), np.arange(300))
        fill = ldl_factor(full(U), perm).Lp[-1]
        natural = ldl_factor(full(U)).Lp[-1]
        assert fill < natural


def test_n0_gives_the_empty_permutation():
    perm = amd_order(np.zeros(1, np.int64), np.zeros(0, np.int64), 0)
    assert perm.shape == (0,) and perm.dtype == np.int64


@pytest.mark.parametrize("indptr, indices, n, match", [
    ([0, 1], [0], -1, "n must be an integer >= 0"),
    ([0, 1], [0], 1.5, "n must be an integer >= 0"),
    ([0, 1], [0], 2, "indptr must have length n \\+ 1"),
    ([1, 1], [0], 1, "indptr must start at 0"),
    ([0, 2, 1], [0, 1], 2, "not decrease"),
    ([0, 5, 2], [0, 1], 2, "not decrease"),               # the decrease after a column that reads past indices
    ([0, 3], [0], 1, "end at most at len\\(indices\\) = 1"),
    ([0, 1, 2], [0, 2], 2, "indices must lie in 0..n-1"),
    ([0, 1], [0.0], 1, "indices must be a 1-d integer array"),
])
def test_bad_input_is_refused_naming_the_parameter(indptr, indices, n, match):
    with pytest.raises(ValueError, match=match):
        amd_order(np.array(indptr), np.array(indices), n)
