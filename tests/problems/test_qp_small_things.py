"""#26 item 6: a slightly nonconvex QP solved on request, with a warning; a warm start of the wrong size named."""
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from admmkit.problems.qp import QP, load_mat, solve_qp

VALUES = Path(__file__).resolve().parents[3] / "shared" / "data" / "maros_meszaros" / "VALUES.mat"


def nonconvex_qp(**options):
    P = sp.diags([2.0, -1e-3])                       # one slightly negative eigenvalue
    A = sp.identity(2, format="csc")
    return QP(P, np.array([1.0, 1.0]), A, -np.ones(2), np.ones(2), **options)


def test_a_nonconvex_p_is_refused_by_default_with_the_way_out():
    with pytest.raises(ValueError, match="positive semidefinite.*allow_nonconvex=True"):
        nonconvex_qp()


def test_allow_nonconvex_warns_and_solves():
    with pytest.warns(RuntimeWarning, match="allow_nonconvex=True"):
        qp = nonconvex_qp(allow_nonconvex=True)
    res = solve_qp(qp, eps_abs=1e-8, eps_rel=0.0)
    # a stationary point of the box-constrained problem: x0 = -0.5 (interior), x1 at the lower bound -1
    assert np.allclose(res.x, [-0.5, -1.0], atol=1e-5)


@pytest.mark.skipif(not VALUES.exists(), reason="needs ../shared/data/maros_meszaros")
def test_values_is_solved_on_request():
    with pytest.raises(ValueError, match="positive semidefinite"):
        load_mat(VALUES)
    with pytest.warns(RuntimeWarning):
        qp = load_mat(VALUES, allow_nonconvex=True)
    res = solve_qp(qp, max_iter=4000)
    assert np.all(np.isfinite(res.x))


def test_a_warm_start_of_the_wrong_size_names_warm_start():
    small = QP(sp.identity(2), np.ones(2), sp.identity(2, format="csc"), -np.ones(2), np.ones(2))
    big = QP(sp.identity(3), np.ones(3), sp.identity(3, format="csc"), -np.ones(3), np.ones(3))
    with pytest.raises(ValueError, match=r"warm_start.*\(3,\)"):
        solve_qp(big, warm_start=solve_qp(small))
