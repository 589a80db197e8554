"""The condensed mode's SuperLU path (issue #49): half solves with U alone, splu_natural's panel size, A' once."""
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg  # noqa: F401  (sp.linalg)

from admmkit.problems.contact import assemble, contact_problem, example1, example2
from admmkit.problems.contact.solvers import lapack, schur
from admmkit.problems.contact.solvers.schur import BoundarySchur


@pytest.fixture(scope="module", params=["ex1", "ex2"])
def ops(request):
    return assemble({"ex1": example1, "ex2": example2}[request.param](h=1 / 12))


def random_upper(n, seed):
    """A well-conditioned upper triangular U as (its diagonal, its CSC arrays with the diagonal zero, U dense)."""
    rng = np.random.default_rng(seed)
    U = np.triu(sp.random(n, n, density=0.3, random_state=seed).toarray()) + np.diag(rng.uniform(1, 2, n))
    d = np.diag(U).copy()
    A = sp.csc_matrix(U)
    A.sort_indices()
    ends = A.indptr[1:] - 1                     # the diagonal closes each column
    A.data[ends] = 0.0
    return d, (A.data, A.indices.astype(np.intc), A.indptr.astype(np.intc)), U


@pytest.mark.parametrize("trans", [False, True])
def test_upper_solve_solves_with_U_and_its_transpose(trans):
    d, arrays, U = random_upper(30, 4)
    b = np.random.default_rng(5).standard_normal(30)
    x = lapack.upper_solve(d, *arrays, b, trans=trans)
    assert np.allclose((U.T if trans else U) @ x, b, rtol=0, atol=1e-12)


def test_upper_solve_checks_the_right_hand_side():
    d, arrays, _ = random_upper(5, 1)
    with pytest.raises(ValueError, match=r"b must have shape \(5,\)"):
        lapack.upper_solve(d, *arrays, np.ones(4))


def test_superlu_loads_with_a_half_solve(ops):
    """Fails before: the load was a whole SuperLU solve ("solution") and the final u another one."""
    s = BoundarySchur(ops.K, ops.B, backend="superlu", coordinates=ops.dof_coordinates())
    e0, u0_c = s.load(ops.f)
    assert s._load[0] == "forward"
    u0 = sp.linalg.spsolve(sp.csc_matrix(ops.K), ops.f)
    assert e0 == pytest.approx(ops.f @ u0, rel=1e-12)
    assert np.abs(u0_c - u0[s.contact_dofs]).max() <= 1e-10 * np.abs(u0).max()
    v = np.random.default_rng(3).standard_normal(s.contact_dofs.size)
    rhs = 2.0 * ops.f
    rhs[s.contact_dofs] += v
    u = sp.linalg.spsolve(sp.csc_matrix(ops.K), rhs)
    assert np.linalg.norm(s.solve_load(2.0, v) - u) <= 1e-10 * np.linalg.norm(u)


class FakeLU:
    """What _half_solves reads of a SuperLU object: its permutations."""

    def __init__(self, perm_c, perm_r=None):
        self.perm_c, self.perm_r = perm_c, perm_c if perm_r is None else perm_r


def test_half_solves_need_the_contact_dofs_last_and_the_diagonal_closing_each_column():
    d, (data, indices, indptr), _ = random_upper(6, 2)
    data[indptr[1:] - 1] = d                    # U with its diagonal, as SuperLU gives it
    n, m = 6, 2
    got = schur._half_solves(FakeLU(np.arange(n)), data.copy(), indices, indptr, m)
    assert got is not None and np.array_equal(got[0], d) and got[2] is None
    moved = np.array([0, 1, 2, 3, 5, 4])        # the last m renumbered: the trailing block is not S's
    assert schur._half_solves(FakeLU(moved), data.copy(), indices, indptr, m) is None
    assert schur._half_solves(FakeLU(np.arange(n), moved), data.copy(), indices, indptr, m) is None
    inner = np.array([1, 0, 2, 3, 4, 5])        # the inner dofs renumbered (SuperLU's postorder): still fine
    assert np.array_equal(schur._half_solves(FakeLU(inner), data.copy(), indices, indptr, m)[2], inner)


def test_half_solves_in_any_inner_order(ops):
    """An inner order at random (not an elimination tree's postorder): the half solves give K^{-1}'s results (the
    factor in our numbering, as scipy's SuperLU reports: perm_c the identity)."""
    s0 = BoundarySchur(ops.K, ops.B, backend="superlu")
    contact = s0.contact_dofs
    inner = np.setdiff1d(np.arange(ops.K.shape[0]), contact)
    order = np.concatenate([np.random.default_rng(7).permutation(inner), contact])
    s = BoundarySchur(ops.K, ops.B, backend="superlu", order=order)
    assert s._impl._halves is not None
    K = sp.csc_matrix(ops.K)
    e, x_c = s.load(ops.f)
    u0 = sp.linalg.spsolve(K, ops.f)
    assert e == pytest.approx(ops.f @ u0, rel=1e-12)
    assert np.abs(x_c - u0[contact]).max() <= 1e-10 * np.abs(u0).max()
    v = np.linspace(-1, 1, contact.size)
    rhs = 0.5 * ops.f
    rhs[contact] += v
    u = sp.linalg.spsolve(K, rhs)
    assert np.linalg.norm(s.solve_load(0.5, v) - u) <= 1e-10 * np.linalg.norm(u)
    assert np.allclose(s.S, s0.S, rtol=1e-10, atol=1e-10 * np.abs(s0.S).max())


def test_splu_natural_takes_the_panel_size_as_splu_does():
    import scipy.sparse.linalg as spla
    A = sp.csc_matrix(sp.random(60, 60, density=0.1, random_state=2) + 10 * sp.eye(60))
    A = (A + A.T).tocsc()
    A.sort_indices()
    b = np.arange(60.0)
    ref = spla.splu(A, permc_spec="NATURAL", diag_pivot_thresh=0.0, panel_size=4, options=dict(SymmetricMode=True))
    assert np.array_equal(lapack.splu_natural(A.copy(), panel_size=4).solve(b), ref.solve(b))


def test_the_result_reads_A_transpose_made_once():
    """Fails before: kkt and kkt_relative each built A.T (a new scipy matrix each time)."""
    problem = contact_problem(assemble(example1(h=1 / 8)), "condensed")
    assert problem._adjoint() is problem._adjoint()
    u = np.linspace(0, 1, problem.ops.n_free)
    lam = np.ones(problem.A.shape[0])
    stat = problem.ops.K @ u - problem.ops.f + problem.A.T @ (problem.w * lam)
    z = np.zeros(problem.A.shape[0])
    assert problem.kkt(u, z, lam)["stationarity"] == np.abs(stat).max() / np.abs(problem.ops.f).max()

