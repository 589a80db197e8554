"""The constraint map A and the inner product M as one object, with the adjoint derived.

:class:`LinearMap` wraps a dense array, a scipy sparse matrix or a
:class:`scipy.sparse.linalg.LinearOperator` (or the identity) together with
the weights of the constraint space's inner product (a, b)_M = sum_i m_i a_i b_i
(M diagonal, as the lumped masses of finite elements; None is the identity).
It gives everything the loop and the x-step need:

- ``apply(x)``           A x                                   (``Problem.apply_A``)
- ``adjoint(y)``         A^T y
- ``adjoint_M(y)``       A^T M y
- ``adjoint_norm(y)``    ||A^T M y|| in the dual norm of the x space:
                         the Euclidean norm, or sqrt(sum_j v_j^2 / w_j) when the x
                         space has the weighted norm ||x||_W = sqrt(sum_j w_j x_j^2)
- ``inner``, ``norm``    (., .)_M and ||.||_M
- ``gram()``             A^T M A as a sparse matrix (matrices only)
"""
from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


def _weights(w, size: int | None, name: str):
    if w is None:
        return None
    arr = np.asarray(w, dtype=float)
    if arr.ndim == 0:
        arr = np.full(size, float(arr)) if size is not None else arr
    if size is not None and arr.shape != (size,):
        raise ValueError(f"{name} must be None, a number or an array of shape ({size},), got shape {arr.shape}")
    if not (np.all(np.isfinite(arr)) and np.all(arr > 0)):
        raise ValueError(f"{name} must be finite and > 0 (the diagonal of a positive definite inner product)")
    return arr


class LinearMap:
    """A (a matrix, sparse matrix, LinearOperator, or None for the identity of size ``n``) with the weights M of its range.

    ``M`` is None (the identity), a number or an array with the diagonal of the
    constraint space's inner product; ``x_weights`` is None (Euclidean) or the
    diagonal W of the x space's norm ||x||_W, whose dual norm ``adjoint_norm``
    uses; ``n`` is the size of x when ``A`` is None.
    """

    def __init__(self, A=None, *, M=None, x_weights=None, n: int | None = None):
        if A is None:
            if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
                raise ValueError(f"n must be an integer >= 1 when A is None (the identity), got {n!r}")
            self.kind, self.A, self.shape = "identity", None, (int(n), int(n))
        elif isinstance(A, spla.LinearOperator):
            self.kind, self.A, self.shape = "operator", A, tuple(A.shape)
        elif sp.issparse(A):
            self.kind, self.A = "sparse", sp.csr_matrix(A, dtype=float)
            self.shape = self.A.shape
            self._At = self.A.T.tocsr()
        else:
            arr = np.asarray(A, dtype=float)
            if arr.ndim != 2:
                raise ValueError(f"A must be a 2-D array, a sparse matrix, a LinearOperator or None, got shape {arr.shape}")
            self.kind, self.A, self.shape = "dense", arr, arr.shape
            self._At = np.ascontiguousarray(arr.T)
        self.p, self.n = self.shape
        self.m = _weights(M, self.p, "M")
        self.w = _weights(x_weights, self.n, "x_weights")

    @classmethod
    def of(cls, A, *, M=None, n: int | None = None) -> "LinearMap":
        """``A`` itself if it is a LinearMap (M must then be None), else ``LinearMap(A, M=M, n=n)``."""
        if isinstance(A, LinearMap):
            if M is not None:
                raise ValueError("give M either to the LinearMap or here, not both")
            return A
        return cls(A, M=M, n=n)

    # -- the maps
    def apply(self, x: np.ndarray) -> np.ndarray:
        """A x (a new array)."""
        if self.kind == "identity":
            return np.array(x, dtype=float)
        if self.kind == "operator":
            return np.asarray(self.A.matvec(x), dtype=float).ravel()
        return self.A @ x

    def adjoint(self, y: np.ndarray) -> np.ndarray:
        """A^T y."""
        if self.kind == "identity":
            return np.array(y, dtype=float)
        if self.kind == "operator":
            return np.asarray(self.A.rmatvec(y), dtype=float).ravel()
        return self._At @ y

    def weight(self, y: np.ndarray) -> np.ndarray:
        """M y."""
        return y if self.m is None else self.m * y

    def adjoint_M(self, y: np.ndarray) -> np.ndarray:
        """A^T M y."""
        return self.adjoint(self.weight(y))

    def adjoint_norm(self, y: np.ndarray) -> float:
        """||A^T M y|| in the dual norm of the x space (Euclidean, or weighted by 1/W)."""
        v = self.adjoint_M(y)
        if self.w is None:
            return math.sqrt(np.dot(v, v))
        return math.sqrt(np.dot(v, v / self.w))

    # -- the inner products
    def inner(self, a: np.ndarray, b: np.ndarray) -> float:
        """(a, b)_M."""
        return float(np.dot(a, b)) if self.m is None else float(np.dot(a, self.m * b))

    def norm(self, y: np.ndarray) -> float:
        """||y||_M."""
        return math.sqrt(max(self.inner(y, y), 0.0))

    def x_norm(self, x: np.ndarray) -> float:
        """||x||_W (Euclidean when no x_weights)."""
        return math.sqrt(np.dot(x, x)) if self.w is None else math.sqrt(np.dot(x, self.w * x))

    # -- matrices
    def is_matrix(self) -> bool:
        """True unless A is a LinearOperator."""
        return self.kind != "operator"

    def gram(self) -> sp.csr_matrix:
        """A^T M A as a sparse matrix (not for LinearOperators)."""
        if self.kind == "identity":
            return sp.diags(np.ones(self.n) if self.m is None else self.m, format="csr")
        if self.kind == "operator":
            raise TypeError("A^T M A of a LinearOperator is not formed; use QuadraticXStep(..., solver='cg')")
        A = sp.csr_matrix(self.A)
        AtM = A.T if self.m is None else A.T @ sp.diags(self.m)     # (A'M) A, as the plug-ins form it
        return sp.csr_matrix(AtM @ A)

    def gram_operator(self) -> spla.LinearOperator:
        """A^T M A as a LinearOperator (any kind of A)."""
        return spla.LinearOperator((self.n, self.n), matvec=lambda v: self.adjoint_M(self.apply(np.ravel(v))),
                                   dtype=float)

    def diagonal_gram(self) -> np.ndarray | None:
        """The diagonal of A^T M A if that matrix is diagonal (identity or diagonal A), else None."""
        if self.kind == "identity":
            return np.ones(self.n) if self.m is None else self.m.copy()
        if self.kind == "operator" or self.p != self.n:
            return None
        A = sp.csr_matrix(self.A)
        if A.nnz and not np.array_equal(*A.nonzero()):
            return None
        d = A.diagonal()
        return d * d if self.m is None else self.m * d * d

    def __repr__(self) -> str:
        return f"LinearMap({self.kind}, shape={self.shape}, M={'I' if self.m is None else 'diag'})"
