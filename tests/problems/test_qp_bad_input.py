"""The QP plug-in refuses bad input with an error that names the parameter (issue #16), table-driven."""
import numpy as np
import pytest
import scipy.io
import scipy.sparse as sp

from admmkit.problems.qp import QP, load_mat, random_qp

I3 = sp.identity(3, format="csc")
Q, L, U = np.zeros(3), -np.ones(3), np.ones(3)


@pytest.mark.parametrize("call, needle", [
    (lambda: QP(sp.diags([1.0, -10.0, 1.0]).tocsc(), Q, I3, L, U), r"P must be positive semidefinite.*about -10"),
    (lambda: QP(I3, Q + 1j, I3, L, U), "q must be real"),
    (lambda: QP(I3 * (1 + 1j), Q, I3, L, U), "P must be real"),
    (lambda: QP(I3, Q, I3, L, U, r=np.nan), "r .* must be one finite number"),
    (lambda: QP("eye", Q, I3, L, U), "P must be an array of numbers"),
    (lambda: QP(I3, Q, I3, L, U, sigma="1e-6"), "sigma must be a finite number >= 0"),
    (lambda: QP(I3, Q, I3, L, U, r="x"), "r must be an array of numbers"),
    (lambda: QP(sp.csc_matrix((0, 0)), np.zeros(0), sp.csc_matrix((0, 0)), np.zeros(0), np.zeros(0)), "n >= 1"),
    (lambda: random_qp(-1, 3), "n must be an integer >= 1"),
    (lambda: random_qp(2.5, 3), "n must be an integer >= 1"),
    (lambda: random_qp(3, 0), "m must be an integer >= 1"),
    (lambda: random_qp(3, 3, seed=-1), "seed must be an integer >= 0"),
    (lambda: random_qp(3, 3, seed=1.5), "seed must be an integer >= 0"),
    (lambda: random_qp(100_000, 100_000), "would need about .* GiB"),
])
def test_bad_qp_input_names_the_parameter(call, needle):
    with pytest.raises(ValueError, match=needle):
        call()


def test_a_psd_but_singular_p_is_accepted():
    G = np.array([[1.0, 2.0, 0.0]])
    QP(sp.csc_matrix(G.T @ G), Q, I3, L, U)            # rank 1: convex, not strictly
    QP(sp.csc_matrix((3, 3)), Q, I3, L, U)             # an LP


@pytest.mark.parametrize("fields, needle", [
    ({"q": "abc"}, r"text_q.mat: the field q holds text 'abc', not numbers"),
    ({"A": None}, "lacks the field"),
    ({"r": np.ones(2)}, "r must be one number"),
])
def test_bad_mat_files_name_the_file(tmp_path, fields, needle):
    data = {"P": I3, "q": Q, "A": I3, "l": L, "u": U, "r": 0.0} | fields
    data = {k: v for k, v in data.items() if v is not None}
    path = tmp_path / ("text_q.mat" if "q" in fields else "bad.mat")
    scipy.io.savemat(path, data)
    with pytest.raises(ValueError, match=needle):
        load_mat(path)


def test_an_empty_r_is_zero_and_a_corrupt_file_is_named(tmp_path):
    scipy.io.savemat(tmp_path / "empty_r.mat", {"P": I3, "q": Q, "A": I3, "l": L, "u": U, "r": np.zeros((0, 0))})
    assert load_mat(tmp_path / "empty_r.mat").r == 0.0
    (tmp_path / "corrupt.mat").write_bytes(b"garbage" * 10)
    with pytest.raises(ValueError, match="corrupt.mat is not a readable MAT file"):
        load_mat(tmp_path / "corrupt.mat")


# ---------------------------------------------------------------- issue #46: the QP's entry, sparse formats and ranges
@pytest.mark.parametrize("fmt", ["dok", "lil", "coo", "csr", "bsr", "dia"])
@pytest.mark.parametrize("kind", [sp.csc_matrix, sp.csc_array])
def test_any_scipy_sparse_format_is_accepted(fmt, kind):
    from admmkit.problems.qp import solve_qp
    qp = random_qp(6, 8, seed=4)
    P, A = kind(qp.P).asformat(fmt), kind(qp.A).asformat(fmt)
    other = QP(P, qp.q, A, qp.l, qp.u)
    assert sp.isspmatrix_csc(other.P) and sp.isspmatrix_csc(other.A)
    assert (other.P != qp.P).nnz == 0 and (other.A != qp.A).nnz == 0
    assert np.array_equal(solve_qp(other).x, solve_qp(qp).x)


@pytest.mark.parametrize("A", [np.ones(3), np.ones((2, 3, 1)), np.float64(1.0)])
def test_an_A_that_is_not_2d_is_named(A):
    with pytest.raises(ValueError, match=r"A must be a 2-D matrix of shape \(m, n\) with n = 3 \(from P\), got an "
                                         r"array of shape"):
        QP(I3, Q, A, -np.ones(1), np.ones(1))


@pytest.mark.parametrize("rho", [0, -1, np.inf, np.nan])
def test_solve_qp_refuses_a_rho_outside_its_range(rho):
    from admmkit.problems.qp import solve_qp
    with pytest.raises(ValueError, match=r"rho must be a number in \(0, inf\), got"):
        solve_qp(random_qp(4, 4, seed=2), rho=rho)


@pytest.mark.parametrize("rho", ["1", True, [0.1]])
def test_solve_qp_refuses_a_rho_that_is_not_a_number(rho):
    from admmkit.problems.qp import solve_qp
    with pytest.raises(TypeError, match=r"rho must be a number \(in \(0, inf\)\)"):
        solve_qp(random_qp(4, 4, seed=2), rho=rho)


@pytest.mark.parametrize("change, error, needle", [
    (dict(rho=0.0), ValueError, "rho must be a finite number > 0"),
    (dict(rho=np.inf), ValueError, "rho must be a finite number > 0"),
    (dict(rho=True), TypeError, "rho must be a number"),
    (dict(rho="0.1"), TypeError, "rho must be a number"),
    (dict(sigma=-1e-6), ValueError, "sigma must be a finite number >= 0"),
    (dict(sigma="1e-6"), TypeError, "sigma must be a number"),
    (dict(alpha=2.0), ValueError, r"alpha must be in \(0, 2\)"),
    (dict(eps_abs=np.nan), ValueError, "eps_abs must be a finite number >= 0"),
    (dict(eps_rel="1e-3"), TypeError, "eps_rel must be a number"),
    (dict(eps_prim_inf=-1.0), ValueError, "eps_prim_inf must be a finite number > 0"),
    (dict(eps_dual_inf=np.inf), ValueError, "eps_dual_inf must be a finite number > 0"),
    (dict(time_limit="1"), TypeError, "time_limit must be a number"),
])
def test_osqp_settings_are_range_checked_at_construction(change, error, needle):
    from admmkit.problems.qp import osqp_settings
    with pytest.raises(error, match=needle):
        osqp_settings(**change)


def test_osqp_settings_take_numpy_numbers():
    from admmkit.problems.qp import osqp_settings
    settings = osqp_settings(rho=np.float32(0.2), eps_abs=np.float64(1e-4), max_iter=np.int64(50))
    assert settings.rho == np.float32(0.2) and settings.max_iter == 50


def test_a_nan_warm_start_of_solve_qp_is_named():
    from admmkit.problems.qp import solve_qp
    qp = random_qp(4, 4, seed=2)
    first = solve_qp(qp)
    first.x = np.full(4, np.nan)
    with pytest.raises(ValueError, match="warm_start.x must be finite, got 4 NaN or infinite entries"):
        solve_qp(qp, warm_start=first)


def _cell():
    cell = np.empty((1, 2), dtype=object)
    cell[0, 0], cell[0, 1] = np.eye(3), "x"
    return cell


@pytest.mark.parametrize("fields, needle", [
    ({"P": "eye"}, r"P.mat: the field P holds text 'eye', not numbers"),
    ({"P": _cell()}, r"P.mat: the field P holds a cell array of shape \(1, 2\), not numbers"),
    ({"A": {"rows": 1.0}}, r"P.mat: the field A holds a struct \(fields rows\), not numbers"),
    ({"r": "zero"}, r"P.mat: the field r holds text 'zero', not a number"),
])
def test_a_mat_field_that_holds_no_numbers_is_named(tmp_path, fields, needle):
    from admmkit.problems.qp.mat import read_matrices
    data = {"P": I3, "q": Q, "A": I3, "l": L, "u": U, "r": 0.0} | fields
    scipy.io.savemat(tmp_path / "P.mat", data)
    with pytest.raises(ValueError, match=needle):
        load_mat(tmp_path / "P.mat")
    if "r" not in fields:
        with pytest.raises(ValueError, match=needle):
            read_matrices(tmp_path / "P.mat")
