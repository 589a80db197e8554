"""The QP's compiled passes over its CSC arrays give what the scipy/numpy steps give (problems/qp/sparse_kernels.py)."""
import numpy as np
import pytest
import scipy.sparse as sp

pytest.importorskip("numba")
from admmkit import kernels  # noqa: E402
from admmkit.problems.qp import QP, kkt, residuals, validate, xstep_forms  # noqa: E402


def awkward_qp(seed: int, sigma: float = 1e-6, **options) -> QP:
    """A random convex QP whose matrices are not canonical: duplicates, unsorted rows, explicit zeros, a P
    column without its diagonal, infinite bounds."""
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(1, 9)), int(rng.integers(1, 12))
    G = sp.random(n + 2, n, density=0.5, random_state=seed).toarray()
    P = G.T @ G
    P[0, 0] = 0.0 if n > 1 and not P[0, 1:].any() else P[0, 0]
    P = sp.coo_matrix(P)
    P = sp.coo_matrix((np.r_[P.data, 0.0, 0.0], (np.r_[P.row, 0, n - 1], np.r_[P.col, n - 1, 0])), shape=(n, n))
    A = sp.random(m, n, density=0.4, random_state=seed + 1).tocoo()
    half = A.data / 2                                        # each entry stored twice, as two halves (duplicates)
    A = sp.coo_matrix((np.r_[half, half, 0.0], (np.r_[A.row, A.row, 0], np.r_[A.col, A.col, 0])), shape=(m, n))
    A = sp.csc_matrix(A)
    A = sp.csc_matrix((np.concatenate([A.data[a:b][::-1] for a, b in zip(A.indptr, A.indptr[1:])] + [[]]),
                       np.concatenate([A.indices[a:b][::-1] for a, b in zip(A.indptr, A.indptr[1:])] + [[]]).astype(int),
                       A.indptr), shape=A.shape)                  # rows in descending order within each column
    l, u = -rng.uniform(0, 2, m), rng.uniform(0, 2, m)
    l[rng.random(m) < 0.3], u[rng.random(m) < 0.3] = -np.inf, np.inf
    return QP(sp.csc_matrix(P), rng.standard_normal(n), A, l, u, sigma=sigma, **options)


@pytest.mark.parametrize("seed", range(30))
@pytest.mark.parametrize("sigma", [0.0, 1e-6])
@pytest.mark.parametrize("upper", [True, False])
@pytest.mark.parametrize("scaling", [0, 10])
def test_the_kkt_matrix_is_the_scipy_assembly_entry_for_entry(seed, sigma, upper, scaling, monkeypatch):
    qp = awkward_qp(seed, sigma=sigma, scaling=scaling)
    K, slots = xstep_forms._kkt_pattern(qp, upper)
    monkeypatch.setattr(xstep_forms, "NUMBA", False)
    K_ref, slots_ref = xstep_forms._kkt_pattern(qp, upper)
    assert np.array_equal(K.indptr, K_ref.indptr) and np.array_equal(K.indices, K_ref.indices)
    assert np.array_equal(K.data, K_ref.data) and np.array_equal(slots, slots_ref)


def test_validation_keeps_the_users_matrices_and_makes_them_canonical():
    P = sp.csc_matrix((np.array([1.0, 1.0]), np.array([0, 0]), np.array([0, 2])), shape=(1, 1))   # a duplicate
    qp = QP(P, [1.0], sp.csc_matrix([[1.0]]), [-1.0], [1.0])
    assert P.nnz == 2 and qp.P.nnz == 1 and qp.P[0, 0] == 2.0 and qp.P.has_canonical_format


@pytest.mark.parametrize("seed", range(40))
def test_the_symmetry_defect_is_max_abs_p_minus_its_transpose(seed, monkeypatch):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 8)) if seed < 20 else int(rng.integers(20, 60))
    M = sp.random(n, n, density=0.5 if seed < 30 else 0.05, random_state=seed).toarray()
    M = M + M.T
    if seed % 2:
        M[rng.integers(n), rng.integers(n)] += rng.uniform(0.5, 1.0)     # one entry off its mirror
    M = validate._canonical(sp.csc_matrix(M))
    compiled = validate._symmetry_defect(M)
    monkeypatch.setattr(validate, "NUMBA", False)
    assert compiled == pytest.approx(validate._symmetry_defect(M), abs=1e-15)
    assert (compiled[0] > 0) == bool(seed % 2 and np.abs(M - M.T).max() > 0)


def test_an_asymmetric_p_is_still_refused():
    with pytest.raises(ValueError, match="P must be symmetric"):
        QP(sp.csc_matrix([[1.0, 0.5], [0.0, 1.0]]), [0.0, 0.0], sp.csc_matrix([[1.0, 0.0]]), [0.0], [1.0])


@pytest.mark.parametrize("seed", range(30))
def test_kkt_and_neutral_measures_are_the_numpy_steps(seed, monkeypatch):
    qp = awkward_qp(seed, scaling=10, row_weights="osqp")
    rng = np.random.default_rng(seed)
    x, z, lam = rng.standard_normal(qp.n), rng.standard_normal(qp.m), rng.standard_normal(qp.m)
    y = qp.multiplier(lam)
    got_kkt, got_neutral = qp.kkt(x, z, lam), residuals.neutral_residuals(qp, x, y)
    monkeypatch.setattr(kkt, "NUMBA", False)
    monkeypatch.setattr(residuals, "NUMBA", False)
    assert got_kkt == qp.kkt(x, z, lam)                                      # bit for bit
    ref = residuals.neutral_residuals(qp, x, y)
    assert got_neutral["primal"] == ref["primal"] and got_neutral["dual"] == ref["dual"]
    assert got_neutral["gap"] == pytest.approx(ref["gap"], rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("seed", range(30))
def test_osqps_residuals_are_the_numpy_steps_bit_for_bit(seed, monkeypatch):
    """osqp_residuals' compiled norms and numpy's dot products equal the numpy steps, every entry bit for bit, with
    multipliers inside OSQP's dead zone, pushing against infinite bounds, and a NaN."""
    qp = awkward_qp(seed)
    rng = np.random.default_rng(seed)
    x, z, y = rng.standard_normal(qp.n), rng.standard_normal(qp.m), rng.standard_normal(qp.m)
    y[rng.random(qp.m) < 0.3] = 1e-16 * rng.choice([-1.0, 1.0])
    cases = [(x, z, y)]
    if qp.m > 1:
        y_nan = y.copy()
        y_nan[-1] = np.nan
        cases.append((x, z, y_nan))
    for case in cases:
        got = kkt.osqp_residuals(qp, *case)
        with monkeypatch.context() as m:
            m.setattr(kkt, "NUMBA", False)
            ref = kkt.osqp_residuals(qp, *case)
        assert got.keys() == ref.keys()
        for key in ref:
            assert np.array_equal(got[key], ref[key], equal_nan=True), key


@pytest.mark.parametrize("seed", range(20))
def test_the_infeasibility_tests_decide_as_the_numpy_steps(seed, monkeypatch):
    from admmkit.problems.qp import infeasibility
    from admmkit.problems.qp.generate import infeasible_qp, unbounded_qp
    rng = np.random.default_rng(seed)
    qp = (infeasible_qp, unbounded_qp)[seed % 2](12, 18, seed=seed)
    for _ in range(10):
        dy = rng.standard_normal(qp.m) * (rng.random(qp.m) < 0.5)
        dx = rng.standard_normal(qp.n) * (rng.random(qp.n) < 0.5)
        for eps in (1e-4, 1.0, 1e3):
            got = infeasibility.primal_certificate(qp, dy, eps), infeasibility.dual_certificate(qp, dx, eps)
            with monkeypatch.context() as patch:
                patch.setattr(infeasibility, "NUMBA", False)
                ref = infeasibility.primal_certificate(qp, dy, eps), infeasibility.dual_certificate(qp, dx, eps)
            for a, b in zip(got, ref):
                assert (a is None) == (b is None) and (a is None or np.array_equal(a, b))


@pytest.mark.parametrize("seed", range(20))
def test_the_compiled_x_step_is_qdldls_solve_bit_for_bit(seed, monkeypatch):
    from admmkit.problems.qp import segment
    qp = awkward_qp(seed, scaling=10, row_weights="osqp", xstep="kkt", backend="qdldl")
    rng = np.random.default_rng(seed)
    xp, z, lam = rng.standard_normal(qp.n), rng.standard_normal(qp.m), rng.standard_normal(qp.m)
    got = xstep_forms.x_step_solution(qp, xp, z, lam, 0.37)          # (x~, z~)
    monkeypatch.setattr(segment, "AVAILABLE", False)              # the Python path: qdldl's own solve
    with kernels.compiled_code(False):
        want = xstep_forms.x_step_solution(qp, xp, z, lam, 0.37)
    assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])


def test_a_qp_builds_its_scaled_data_only_when_used():
    qp = awkward_qp(3, scaling=10, row_weights="osqp")
    assert qp._built is False and qp.options["scaling"] == 10
    assert qp.As.shape == qp.A.shape and qp._built is True            # built at the first use
    with pytest.raises(ValueError, match="scaling must be an integer >= 0"):
        awkward_qp(3, scaling=-1)                                     # options are still checked at construction


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("alpha, scaling, weights", [(1.6, 10, "osqp"), (1.0, 0, "uniform"), (1.3, 0, "osqp")])
def test_the_dual_change_is_the_numpy_steps(seed, alpha, scaling, weights, monkeypatch):
    from admmkit import solve
    from admmkit.problems.qp import infeasibility
    qp = awkward_qp(seed, scaling=scaling, row_weights=weights)
    rec = solve(qp, rho=0.1, alpha=alpha, max_iter=7).last_record
    got = infeasibility.iterate_deltas(qp, rec)
    monkeypatch.setattr(infeasibility, "NUMBA", False)
    ref = infeasibility.iterate_deltas(qp, rec)
    assert np.array_equal(got[1], ref[1]) and np.array_equal(got[0], ref[0])


@pytest.mark.parametrize("seed", range(6))
def test_a_small_dense_p_is_judged_by_dense_cholesky_as_by_its_eigenvalues(seed):
    """Rank-deficient PSD (accepted) and one eigenvalue -1e-3 (refused), n 5-60, stored full."""
    from admmkit.problems.qp.convexity import check_convex
    rng = np.random.default_rng(seed)
    n = int(rng.integers(5, 60))
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    eigenvalues = np.abs(rng.standard_normal(n))
    eigenvalues[: n // 3] = 0.0                                  # singular, still PSD
    psd = (Q * eigenvalues) @ Q.T
    check_convex(sp.csc_matrix((psd + psd.T) / 2))
    eigenvalues[0] = -1e-3
    bad = (Q * eigenvalues) @ Q.T
    with pytest.raises(ValueError, match="positive semidefinite.*about -0.001"):
        check_convex(sp.csc_matrix((bad + bad.T) / 2))


@pytest.mark.parametrize("seed", range(30))
@pytest.mark.parametrize("scaling", [0, 10])
def test_the_loops_products_are_scipys_bit_for_bit(seed, scaling):
    from admmkit.kernels import compiled_code
    qp = awkward_qp(seed, scaling=scaling, row_weights="osqp")
    rng = np.random.default_rng(seed)
    x, y = rng.standard_normal(qp.n), rng.standard_normal(qp.m)
    with compiled_code(True):                      # the compiled kernels
        Ax, norm = qp.apply_A(x), qp.adjoint_norm(y)
    assert np.array_equal(Ax, qp.As @ x)
    with compiled_code(False):                     # the library path they replace: scipy
        assert np.array_equal(Ax, qp.apply_A(x)) and norm == qp.adjoint_norm(y)
    assert norm == float(np.linalg.norm(qp.As.T.tocsr() @ (qp.w * y)))


def test_a_factorised_matrix_is_left_as_the_caller_gave_it():
    from admmkit.linalg.linsolve import factorize
    M = sp.csc_matrix((np.array([1.0, 1.0, 3.0]), np.array([0, 0, 1]), np.array([0, 2, 3])), shape=(2, 2))
    x = factorize(M, "superlu")(np.array([2.0, 3.0]))
    assert np.allclose(x, [1.0, 1.0]) and M.nnz == 3       # the duplicate summed in a copy, not in M


@pytest.mark.parametrize("seed", range(4))
def test_inf_norms_are_numpys(seed):
    """Row and column inf-norms of a CSC matrix in one compiled pass: numpy's maxima, and those of the pure
    Python run of the same kernel."""
    from admmkit.problems.qp.sparse_kernels import inf_norms
    M = sp.random(30, 17, 0.2, format="csc", random_state=seed) - 0.5 * sp.random(30, 17, 0.1, format="csc",
                                                                                  random_state=seed + 9)
    M = sp.csc_matrix(M)
    rows, cols = inf_norms(M.indptr, M.indices, M.data, M.shape[0])
    assert np.array_equal(rows, abs(M).max(axis=1).toarray().ravel())
    assert np.array_equal(cols, abs(M).max(axis=0).toarray().ravel())
    with kernels.compiled_code(False):
        again = inf_norms(M.indptr, M.indices, M.data, M.shape[0])
    assert np.array_equal(again[0], rows) and np.array_equal(again[1], cols)
