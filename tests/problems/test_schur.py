"""The contact-boundary Schur complement: every backend against a dense computation."""
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg  # noqa: F401  (sp.linalg)

from admmkit.problems.contact import assemble, example1, example2
from admmkit.problems.contact.solvers.schur import BoundarySchur, available_schur_backends, minimum_degree_ordering


@pytest.fixture(scope="module", params=["ex1", "ex2"])
def ops(request):
    return assemble({"ex1": example1, "ex2": example2}[request.param](h=1 / 10))


def dense_schur(K, c):
    """S = K_cc - K_ci K_ii^{-1} K_ic, dense, straight from the definition."""
    K = K.toarray()
    i = np.setdiff1d(np.arange(K.shape[0]), c)
    return K[np.ix_(c, c)] - K[np.ix_(c, i)] @ np.linalg.solve(K[np.ix_(i, i)], K[np.ix_(i, c)])


@pytest.mark.parametrize("backend", available_schur_backends())
def test_schur_and_compliance_match_dense(ops, backend):
    schur = BoundarySchur(ops.K, ops.B, backend=backend)
    assert schur.backend == backend
    S_ref = dense_schur(ops.K, schur.contact_dofs)
    assert np.abs(schur.S - S_ref).max() <= 1e-10 * np.abs(S_ref).max()
    C_ref = ops.B.toarray() @ np.linalg.solve(ops.K.toarray(), ops.B.toarray().T)
    assert np.abs(schur.compliance(ops.B) - C_ref).max() <= 1e-10 * np.abs(C_ref).max()
    u = schur.solve(ops.f)
    assert np.linalg.norm(ops.K @ u - ops.f) <= 1e-10 * np.linalg.norm(ops.f)
    assert set(schur.timings) == {"ordering", "factorisation", "schur"}


def test_nested_dissection_order_gives_the_same_schur_and_solves(ops):
    schur = BoundarySchur(ops.K, ops.B, backend="superlu", coordinates=ops.dof_coordinates())
    plain = BoundarySchur(ops.K, ops.B, backend="superlu")
    assert not np.array_equal(schur.order, plain.order)
    S_ref = dense_schur(ops.K, schur.contact_dofs)
    assert np.abs(schur.S - S_ref).max() <= 1e-10 * np.abs(S_ref).max()
    assert np.abs(schur.S - plain.S).max() <= 1e-12 * np.abs(plain.S).max()
    u = schur.solve(ops.f)
    assert np.linalg.norm(ops.K @ u - ops.f) <= 1e-10 * np.linalg.norm(ops.f)


def test_minimum_degree_ordering_is_a_fill_reducing_permutation(ops):
    K = sp.csc_matrix(ops.K)
    order = minimum_degree_ordering(K)
    assert np.array_equal(np.sort(order), np.arange(K.shape[0]))
    # fewer nonzeros in the factors than the assembly order gives (an independent count: SuperLU's own)
    def fill(A):
        lu = sp.linalg.splu(sp.csc_matrix(A), permc_spec="NATURAL", diag_pivot_thresh=0.0,
                            options=dict(SymmetricMode=True))
        return lu.L.nnz + lu.U.nnz
    assert fill(K[order][:, order]) < 0.8 * fill(K)


def test_csr_and_csc_input_give_the_same_schur(ops):
    a = BoundarySchur(sp.csr_matrix(ops.K), ops.B, backend="superlu")
    b = BoundarySchur(sp.csc_matrix(ops.K), ops.B, backend="superlu")
    assert np.array_equal(a.order, b.order)
    # K is symmetric to round-off (1e-16 relative), so the two read it differently only at that level
    assert np.abs(a.S - b.S).max() <= 1e-12 * np.abs(a.S).max()


def test_unknown_or_missing_backend_is_refused(ops):
    with pytest.raises(ValueError, match="schur backend"):
        BoundarySchur(ops.K, ops.B, backend="mumps")


@pytest.mark.parametrize("backend", available_schur_backends())
def test_singular_K_is_reported(ops, backend):
    K = sp.csr_matrix(ops.K).tolil()
    K[0, :] = 0.0
    K[:, 0] = 0.0
    with pytest.raises(np.linalg.LinAlgError, match="singular"):
        BoundarySchur(K.tocsr(), ops.B, backend=backend)


def test_ldl_and_superlu_give_the_same_schur_and_solves(ops):
    X = ops.dof_coordinates()
    ldl = BoundarySchur(ops.K, ops.B, backend="ldl", coordinates=X)
    lu = BoundarySchur(ops.K, ops.B, backend="superlu", coordinates=X)
    assert ldl.backend == "ldl" and np.array_equal(ldl.order, lu.order)
    assert np.abs(ldl.S - lu.S).max() <= 1e-12 * np.abs(lu.S).max()
    C = lu.compliance(ops.B)   # C ~ S^{-1}: S's round-off times its condition (5e-12 at Ex. 2)
    assert np.abs(ldl.compliance(ops.B) - C).max() <= 1e-10 * np.abs(C).max()
    u_ref = sp.linalg.spsolve(sp.csc_matrix(ops.K), ops.f)
    assert np.linalg.norm(ldl.solve(ops.f) - u_ref) <= 1e-10 * np.linalg.norm(u_ref)   # cond(K) ~ 1e6
    assert set(ldl.timings) == {"ordering", "factorisation", "schur"}


def test_auto_with_compiled_picks_ldl_or_superlu_by_the_mean_column_length(ops, monkeypatch):
    from admmkit.problems.contact.solvers import schur as module
    if available_schur_backends()[0] == "cholmod":
        pytest.skip("auto takes CHOLMOD here")
    if "ldl" not in available_schur_backends():
        pytest.skip("numba is not installed")
    X = ops.dof_coordinates()
    assert BoundarySchur(ops.K, ops.B, coordinates=X, compiled=True).backend == "ldl"   # h = 1/10: short columns
    monkeypatch.setattr(module, "LDL_MAX_COLUMN_LENGTH", 1.0)
    assert BoundarySchur(ops.K, ops.B, coordinates=X, compiled=True).backend == "superlu"
    monkeypatch.setattr(module, "LDL_MAX_COLUMN_LENGTH", 1e9)
    monkeypatch.setattr(module, "LDL_MAX_DOFS", 10)
    assert BoundarySchur(ops.K, ops.B, coordinates=X, compiled=True).backend == "superlu"


@pytest.mark.parametrize("compiled", ["auto", False])
def test_auto_takes_superlu_unless_compiled_is_true(ops, compiled):
    """Issue #49: the compiled ldl costs a fresh process ~0.7 s of numba for a few ms saved, so "auto" (without
    CHOLMOD) takes SuperLU unless compiled=True; its order is the same with the kernels or their numpy twins."""
    if available_schur_backends()[0] == "cholmod":
        pytest.skip("auto takes CHOLMOD here")
    X = ops.dof_coordinates()
    auto = BoundarySchur(ops.K, ops.B, coordinates=X, compiled=compiled)
    ref = BoundarySchur(ops.K, ops.B, coordinates=X, backend="superlu", compiled=True)
    assert auto.backend == "superlu" and np.array_equal(auto.order, ref.order)
    assert np.array_equal(auto.S, ref.S) and np.array_equal(auto.compliance(ops.B), ref.compliance(ops.B))
    with pytest.raises(ValueError, match="compiled must be 'auto', True or False"):
        BoundarySchur(ops.K, ops.B, coordinates=X, compiled="yes")


def test_indefinite_K_is_reported_by_ldl(ops):
    K = sp.csr_matrix(ops.K).tolil()
    K[5, 5] = -K[5, 5]                     # a negative pivot, not a zero one: LDL' exists but K is not SPD
    with pytest.raises(np.linalg.LinAlgError, match="positive definite"):
        BoundarySchur(K.tocsr(), ops.B, backend="ldl")


def test_contact_solution_is_the_same_with_every_backend(ops):
    import admmkit
    from admmkit import RelativeChange, policies
    from admmkit.problems.contact.solvers.problem import contact_problem
    order, rule = policies.method("sadmm")
    u = {}
    for backend in available_schur_backends():
        problem = contact_problem(ops, mode="condensed", backend=backend)
        assert problem.schur.backend == backend
        result = admmkit.solve(problem, rho=1e3, policy=rule, order=order, stop=RelativeChange(1e-5), max_iter=2000)
        u[backend] = result.x                   # the displacement (finalize applied)
    ref = u["superlu"]
    for backend, x in u.items():
        assert np.linalg.norm(x - ref) <= 1e-10 * np.linalg.norm(ref), backend


@pytest.mark.parametrize("backend", available_schur_backends())
def test_load_and_solve_load_match_solves_with_K(ops, backend):
    schur = BoundarySchur(ops.K, ops.B, backend=backend, coordinates=ops.dof_coordinates())
    u0 = sp.linalg.spsolve(sp.csc_matrix(ops.K), ops.f)
    e0, u0_c = schur.load(ops.f)
    assert e0 == pytest.approx(ops.f @ u0, rel=1e-12)
    assert np.abs(u0_c - u0[schur.contact_dofs]).max() <= 1e-10 * np.abs(u0).max()
    v = np.random.default_rng(3).standard_normal(schur.contact_dofs.size)
    rhs = -0.5 * ops.f
    rhs[schur.contact_dofs] += v
    u_ref = sp.linalg.spsolve(sp.csc_matrix(ops.K), rhs)
    assert np.linalg.norm(schur.solve_load(-0.5, v) - u_ref) <= 1e-10 * np.linalg.norm(u_ref)


def test_trailing_block_reads_scipys_slices():
    import scipy.sparse as sp
    from admmkit.problems.contact.solvers.schur import trailing_block
    U = sp.random(40, 40, density=0.2, random_state=3, format="csc") + sp.eye(40, format="csc")
    for m in (1, 7, 40):
        U = sp.csc_array(U)
        assert np.array_equal(trailing_block(U.data, U.indices, U.indptr, m), U[:, -m:][-m:, :].toarray())


def test_contact_columns_are_scipys_column_indexing():
    """B[:, contact_dofs] read off B's arrays where B touches only contact dofs; scipy's indexing otherwise."""
    import scipy.sparse as sp
    from admmkit.problems.contact.solvers.schur import BoundarySchur
    ops = assemble(example1(1 / 8))
    schur = BoundarySchur(ops.K, ops.B, backend="superlu")
    for B in (ops.B, sp.vstack([ops.B, 2 * ops.B]).tocsr(), sp.csr_matrix(np.eye(ops.K.shape[0])[:3])):
        mine, theirs = schur.contact_columns(B), sp.csr_matrix(B)[:, schur.contact_dofs]
        assert mine.shape == theirs.shape and np.array_equal(mine.indptr, theirs.indptr)
        assert np.array_equal(mine.indices, theirs.indices) and np.array_equal(mine.data, theirs.data)
