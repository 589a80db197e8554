"""Tests of admmkit.linalg.linsolve: each installed backend, the rho cache, bad inputs."""
import numpy as np
import pytest
import scipy.sparse as sp

from admmkit.linalg import linsolve
from admmkit.linalg.linsolve import CachedFactorization, available_backends, factorize

BACKENDS = available_backends()


def laplacian_2d(m):
    """5-point Laplacian on an m x m grid with Dirichlet boundary (SPD, n = m^2)."""
    T = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(m, m))
    I = sp.identity(m)
    return (sp.kron(T, I) + sp.kron(I, T)).tocsc()


def penalized(rho, m=12):
    """An ADMM-like x-step matrix K + rho * B^T B, B picking the first grid row."""
    K = laplacian_2d(m)
    B = sp.identity(m * m, format="csr")[:m]
    return (K + rho * (B.T @ B)).tocsc()


def rel_residual(A, x, b):
    return np.linalg.norm(A @ x - b) / np.linalg.norm(b)


def test_superlu_always_available():
    assert "superlu" in BACKENDS


@pytest.mark.parametrize("backend", BACKENDS)
def test_solves_spd_system(backend):
    A = laplacian_2d(15)
    b = np.random.default_rng(0).standard_normal(A.shape[0])
    x = factorize(A, backend)(b)
    assert x.shape == b.shape
    assert rel_residual(A, x, b) < 1e-10


@pytest.mark.parametrize("backend", BACKENDS)
def test_solves_several_rhs(backend):
    A = penalized(3.0)
    B = np.random.default_rng(1).standard_normal((A.shape[0], 3))
    X = factorize(A, backend)(B)
    assert X.shape == B.shape
    assert np.linalg.norm(A @ X - B) / np.linalg.norm(B) < 1e-10


@pytest.mark.parametrize("backend", BACKENDS)
def test_cache_one_factorization_per_rho(backend):
    cache = CachedFactorization(penalized, backend=backend)
    assert cache.backend == backend
    b = np.ones(144)
    for rho in [1.0, 1.0, 10.0, 10.0, 1.0, 100.0, 1.0, 10.0]:
        x = cache.solve(rho, b)
        assert rel_residual(penalized(rho), x, b) < 1e-10
    assert cache.factorizations == 3
    assert cache.solves == 8
    assert cache.factor_time > 0 and cache.solve_time > 0


@pytest.mark.parametrize("backend", BACKENDS)
def test_held_is_the_solve_the_cache_uses(backend):
    cache = CachedFactorization(penalized, backend=backend)
    held = cache.held(10.0)                         # factorised now
    assert cache.factorizations == 1 and 10.0 in cache
    assert cache.held(10) is held and cache.factorizations == 1
    b = np.ones(144)
    assert np.array_equal(held(b), cache.solve(10.0, b))
    with pytest.raises(ValueError, match="rho must be a finite number > 0"):
        cache.held(0.0)


def test_cache_keys_on_float_value():
    cache = CachedFactorization(penalized)
    b = np.ones(144)
    cache.solve(2, b)
    cache.solve(2.0, b)
    cache.solve(np.float64(2.0), b)
    assert cache.factorizations == 1
    cache.solve(2.0 + 1e-12, b)
    assert cache.factorizations == 2


def test_auto_resolves_to_first_available():
    assert CachedFactorization(penalized).backend == BACKENDS[0]


def test_lru_eviction():
    calls = []

    def matrix(rho):
        calls.append(rho)
        return penalized(rho)

    cache = CachedFactorization(matrix, max_cached=2)
    b = np.ones(144)
    cache.solve(1.0, b)
    cache.solve(2.0, b)
    cache.solve(1.0, b)  # 1.0 is now the most recently used
    cache.solve(3.0, b)  # evicts 2.0
    assert len(cache) == 2 and 1.0 in cache and 3.0 in cache and 2.0 not in cache
    cache.solve(1.0, b)  # still cached
    assert cache.factorizations == 3
    cache.solve(2.0, b)  # refactorised
    assert cache.factorizations == 4
    assert calls == [1.0, 2.0, 3.0, 2.0]


def test_unknown_backend():
    with pytest.raises(ValueError, match="backend.*superlu"):
        factorize(laplacian_2d(3), backend="magic")
    with pytest.raises(ValueError, match="backend"):
        CachedFactorization(penalized, backend="magic")


def test_backend_not_installed(monkeypatch):
    monkeypatch.setattr(linsolve.sparse_backends, "_importable", lambda module: module == "scipy")
    assert available_backends() == ["superlu"]
    assert CachedFactorization(penalized).backend == "superlu"
    with pytest.raises(ValueError, match="'qdldl' is not installed.*superlu"):
        factorize(laplacian_2d(3), backend="qdldl")


@pytest.mark.parametrize("rho", [0.0, -1.0, np.nan, np.inf, -np.inf])
def test_bad_rho(rho):
    cache = CachedFactorization(penalized)
    with pytest.raises(ValueError, match="rho must be a finite number > 0"):
        cache.solve(rho, np.ones(144))
    assert cache.factorizations == 0


@pytest.mark.parametrize("max_cached", [0, -3, 1.5])
def test_bad_max_cached(max_cached):
    with pytest.raises(ValueError, match="max_cached"):
        CachedFactorization(penalized, max_cached=max_cached)


@pytest.mark.parametrize("backend", BACKENDS)
def test_non_square_matrix(backend):
    with pytest.raises(ValueError, match="square"):
        factorize(sp.random(4, 5, density=0.5, format="csc"), backend)
    cache = CachedFactorization(lambda rho: sp.identity(4, format="csr")[:3], backend=backend)
    with pytest.raises(ValueError, match="square"):
        cache.solve(1.0, np.ones(3))


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("shape", [(143,), (145,), (144, 2, 1), (2, 144), ()])
def test_rhs_wrong_shape(backend, shape):
    solve = factorize(penalized(1.0), backend)
    with pytest.raises(ValueError, match=r"rhs must have shape \(144,\)"):
        solve(np.ones(shape))


def test_rhs_not_finite():
    solve = factorize(penalized(1.0))
    b = np.ones(144)
    b[3] = np.nan
    with pytest.raises(ValueError, match="rhs must be finite"):
        solve(b)


@pytest.mark.parametrize("backend", BACKENDS)
def test_singular_matrix(backend):
    A = sp.diags([1.0, 0.0, 2.0, 3.0]).tocsc()  # zero pivot
    with pytest.raises(np.linalg.LinAlgError, match=backend):
        factorize(A, backend)(np.ones(4))
    cache = CachedFactorization(lambda rho: A, backend=backend)
    with pytest.raises(np.linalg.LinAlgError):
        cache.solve(1.0, np.ones(4))


def test_in_place_refactorisation_is_the_new_factor():
    """in_place: one factorisation held; a new rho refactorises it numerically (qdldl), with the solutions of a
    fresh factorisation bit for bit; a changed pattern factorises anew."""
    if "qdldl" not in available_backends():
        pytest.skip("qdldl is not installed")
    fresh = CachedFactorization(penalized, backend="qdldl")
    kept = CachedFactorization(penalized, backend="qdldl", in_place=True)
    b = np.arange(1.0, penalized(1.0).shape[0] + 1)
    for rho in (1.0, 7.5, 0.3, 1.0):
        assert np.array_equal(kept.solve(rho, b), fresh.solve(rho, b))
        assert len(kept) == 1
    assert kept.factorizations == 4 and fresh.factorizations == 3      # 1.0 came back: a refactorisation
    solve = kept._cache[1.0]
    assert solve.refactor(sp.identity(b.size, format="csc")) is None     # another pattern: not in place

