"""The two forms of the QP's x-step and how "auto" picks one (the module docstring of
:mod:`admmkit.problems.qp.problem` derives them): the reduced SPD matrix P + sigma I + rho A'MA,
or OSQP's quasi-definite KKT matrix when A'A could be dense."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from admmkit.linsolve import available_backends

XSTEPS = ("auto", "reduced", "kkt")
#: "auto" uses the KKT form when A'A could have more entries than this (bound: nnz(P) + sum_i nnz(row_i of A)^2)
REDUCED_MAX_NNZ = 2e7
#: sparse solvers that factorise the indefinite KKT matrix (CHOLMOD's L L' and PARDISO's SPD mode cannot)
KKT_BACKENDS = ("qdldl", "superlu")


def reduced_nnz_bound(P: sp.spmatrix, A: sp.spmatrix) -> float:
    """An upper bound on the entries of P + rho A'A: nnz(P) + sum over rows of A of nnz(row)^2."""
    rows = np.diff(sp.csr_matrix(A).indptr).astype(float)
    return float(sp.csc_matrix(P).nnz + (rows ** 2).sum())


def _kkt_backend(backend: str) -> str:
    """The solver for the KKT form: qdldl if installed, else SuperLU, unless one of them is asked for."""
    if backend == "auto":
        return next(b for b in KKT_BACKENDS if b in available_backends())
    if backend not in KKT_BACKENDS:
        raise ValueError(f"backend for xstep 'kkt' must be 'auto' or one of {', '.join(KKT_BACKENDS)} "
                         f"(the KKT matrix is indefinite), got {backend!r}")
    return backend
