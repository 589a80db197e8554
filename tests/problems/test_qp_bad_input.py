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
    ({"q": "abc"}, r"text_q.mat: q must be an array of numbers"),
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
