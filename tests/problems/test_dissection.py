"""Geometric nested dissection: a permutation of the given dofs, separators that separate, less fill."""
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg  # noqa: F401  (sp.linalg)

from admmkit.problems.contact import assemble, example1, example2
from admmkit.problems.contact.solvers.dissection import nested_dissection, permute_symmetric
from admmkit.problems.contact.solvers.schur import minimum_degree_ordering


@pytest.fixture(scope="module", params=["ex1", "ex2"])
def ops(request):
    return assemble({"ex1": example1, "ex2": example2}[request.param](h=1 / 20))


def factor_nnz(K, order):
    """nnz(L) + nnz(U) of SuperLU's LU of K in ``order`` (no pivoting): an independent count of the fill."""
    lu = sp.linalg.splu(sp.csc_matrix(K)[order][:, order].tocsc(), permc_spec="NATURAL", diag_pivot_thresh=0.0,
                        options=dict(SymmetricMode=True))
    return lu.L.nnz + lu.U.nnz


def grid_laplacian(nx, ny):
    """The 5-point Laplacian on an nx x ny grid and its points (row by row)."""
    T = lambda k: sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(k, k))  # noqa: E731
    K = sp.kronsum(T(nx), T(ny)).tocsc()
    y, x = np.divmod(np.arange(nx * ny), nx)
    return K, np.column_stack([x, y]).astype(float)


def test_is_a_permutation_of_the_given_dofs(ops):
    K = sp.csc_matrix(ops.K)
    dofs = np.arange(1, K.shape[0], 3)
    order = nested_dissection(K, dofs, ops.dof_coordinates())
    assert np.array_equal(np.sort(order), dofs)


def test_less_fill_than_minimum_degree_with_the_contact_dofs_last(ops):
    K = sp.csc_matrix(ops.K)
    contact = np.unique(ops.B.indices)
    inner = np.setdiff1d(np.arange(K.shape[0]), contact)
    nd = np.concatenate([nested_dissection(K, inner, ops.dof_coordinates()), contact])
    natural = np.concatenate([inner, contact])
    md = np.concatenate([inner[minimum_degree_ordering(K[inner][:, inner])], contact])
    assert factor_nnz(K, nd) < 0.5 * factor_nnz(K, natural)
    assert factor_nnz(K, nd) < 1.1 * factor_nnz(K, md)


def test_the_last_separator_splits_a_grid_in_two():
    # 20 x 9 grid: the longest side is x, so the last dofs ordered are one grid column that cuts it in two
    K, X = grid_laplacian(20, 9)
    order = nested_dissection(K, np.arange(K.shape[0]), X, leaf=4)
    last = order[-9:]
    assert np.unique(X[last, 0]).size == 1 and np.array_equal(np.sort(X[last, 1]), np.arange(9.0))
    left = X[:, 0] < X[last[0], 0]
    rest = np.setdiff1d(np.arange(K.shape[0]), last)
    coupled = K[rest][:, rest].tocoo()
    assert not np.any(left[rest[coupled.row]] != left[rest[coupled.col]])   # nothing joins the two sides


def test_equal_coordinates_and_leaf_sizes():
    K, X = grid_laplacian(6, 5)
    same = nested_dissection(K, np.arange(30), np.zeros((30, 2)))   # no split possible: one leaf, by index
    assert np.array_equal(same, np.arange(30))
    for leaf in (1, 2, 100):
        assert np.array_equal(np.sort(nested_dissection(K, np.arange(30), X, leaf=leaf)), np.arange(30))
    with pytest.raises(ValueError, match="coordinates"):
        nested_dissection(K, np.arange(30), X[:-1])
    with pytest.raises(ValueError, match="leaf"):
        nested_dissection(K, np.arange(30), X, leaf=0)


def test_dof_coordinates_of_p1_and_p2():
    ops1 = assemble(example1(h=1 / 8))
    X = ops1.dof_coordinates()
    assert X.shape == (ops1.n_free, 2)
    assert np.allclose(ops1.B @ X[:, 1], 0.0)          # the contact dofs sit on the bottom, y = 0
    ops2 = assemble(example1(h=1 / 8, order=2))
    exact = _node_points(ops2)                           # vertex, or the edge's midpoint, node by node
    X2 = ops2.dof_coordinates()
    assert X2.shape == (ops2.n_free, 2)
    vertex = np.isin(ops2.free % (ops2.fes.ndof // 2), np.arange(ops2.mesh.nv))
    assert np.array_equal(X2[vertex], exact[vertex])
    assert np.max(np.linalg.norm(X2 - exact, axis=1)) <= 0.2 * np.sqrt(2) / 8 + 1e-12   # a fifth of a diagonal


def _node_points(ops) -> np.ndarray:
    import ngsolve as ng
    V = np.asarray(ops.mesh.ngmesh.Coordinates())
    points = np.full((ops.fes.ndof, 2), np.nan)
    for i in range(ops.mesh.nv):
        points[list(ops.fes.GetDofNrs(ng.NodeId(ng.VERTEX, i)))] = V[i]
    for edge in ops.mesh.edges:
        a, b = edge.vertices
        points[list(ops.fes.GetDofNrs(edge))] = (V[a.nr] + V[b.nr]) / 2
    return points[ops.free]


def test_p2_schur_complement_is_the_same_in_nested_dissection_order():
    from admmkit.problems.contact.solvers.schur import BoundarySchur
    ops2 = assemble(example1(h=1 / 10, order=2))
    nd = BoundarySchur(ops2.K, ops2.B, backend="superlu", coordinates=ops2.dof_coordinates())
    md = BoundarySchur(ops2.K, ops2.B, backend="superlu", coordinates=None)
    S_nd, S_md = (s.S.toarray() if sp.issparse(s.S) else s.S for s in (nd, md))
    assert np.max(np.abs(S_nd - S_md)) <= 1e-12 * np.max(np.abs(S_md))


def test_permute_symmetric_is_scipys_fancy_indexing_sorted(ops):
    K = sp.csc_matrix(ops.K)
    order = np.random.default_rng(3).permutation(K.shape[0])
    mine = permute_symmetric(K, order)
    ref = K[order][:, order].tocsc()
    ref.sort_indices()
    assert np.array_equal(mine.indptr, ref.indptr) and np.array_equal(mine.indices, ref.indices)
    assert np.array_equal(mine.data, ref.data)
    for bad in (order[:-1], np.r_[order[:-1], order[0]], np.r_[order[:-1], K.shape[0]]):
        with pytest.raises(ValueError, match="order"):
            permute_symmetric(K, bad)


@pytest.mark.parametrize("leaf", [16, 4, 1, 10**6])
@pytest.mark.parametrize("name, h, fe_order", [("ex1", 1 / 10, 1), ("ex2", 1 / 10, 1), ("ex1", 1 / 8, 2)])
def test_the_numpy_twin_orders_as_the_kernel(name, h, fe_order, leaf):
    """Issue #49: a small body is ordered without numba, in the very order of the compiled dissection."""
    from admmkit.problems.contact import example1, example2
    from admmkit.problems.contact.solvers.dissection import use_kernels
    if not use_kernels(1, True):
        pytest.skip("numba is not installed")
    ops = assemble({"ex1": example1, "ex2": example2}[name](h=h, order=fe_order))
    K, X = ops.K.tocsc(), ops.dof_coordinates()
    for dofs in (np.arange(K.shape[0]), np.random.default_rng(1).permutation(K.shape[0])[: K.shape[0] // 2 + 3]):
        compiled = nested_dissection(K, dofs, X, leaf=leaf, compiled=True)
        twin = nested_dissection(K, dofs, X, leaf=leaf, compiled=False)
        assert np.array_equal(compiled, twin)
    order = np.random.default_rng(2).permutation(K.shape[0])
    a, b = permute_symmetric(K, order, compiled=True), permute_symmetric(K, order, compiled=False)
    for attr in ("indptr", "indices", "data"):
        assert np.array_equal(getattr(a, attr), getattr(b, attr)) and getattr(a, attr).dtype == getattr(b, attr).dtype


def test_twin_on_degenerate_sets():
    K = sp.csc_matrix(sp.eye(30) + sp.eye(30, k=1) + sp.eye(30, k=-1))
    X = np.zeros((30, 2))
    X[:, 0] = np.repeat(np.arange(3), 10)                   # ten dofs on each of three points: ties everywhere
    for leaf in (1, 2, 16):
        assert np.array_equal(nested_dissection(K, np.arange(30), X, leaf=leaf, compiled=False),
                              nested_dissection(K, np.arange(30), X, leaf=leaf, compiled=True))
    with pytest.raises(ValueError, match="compiled must be"):
        nested_dissection(K, np.arange(30), X, compiled="no")
