"""The QP's data checked once, at construction: real, finite where it must be, shapes that agree, l <= u."""
from __future__ import annotations

import math
import warnings

import numpy as np
import scipy.sparse as sp

from admmkit.loop.segments import AVAILABLE as NUMBA      # numba installed (asked once, without importing it)

from .convexity import check_convex
from .rows import ROW_WEIGHTS
from .scaling import _csc
from .segment import compiled_pays
from .sparse_kernels import p_checks, symmetry_defect
from .validate_kernel import bound_facts
from .xstep_forms import XSTEPS

#: the index dtype of the QP's matrices, whatever route they come by (the MAT loader and qpsolvers give int32,
#: cvxpy int64): scipy builds every new CSC matrix (the scaled P and A, the KKT matrix) with int32 indices when
#: they fit, and qdldl's factors are int32, so with int32 at the entry one compiled kernel serves every route
INDEX = np.int32

def _inf(v) -> float:
    return float(np.max(np.abs(v), initial=0.0))


def _real(name: str, value, sparse_ok: bool = False):
    """``value`` as a real float array, or a sparse matrix of any scipy format as a float CSC matrix (``value``
    itself when it is one); ValueError naming ``name`` for text or complex values."""
    if type(value) is np.ndarray and value.dtype == np.float64:     # already what it would become: no checks
        return value
    if sparse_ok and sp.issparse(value):
        if np.iscomplexobj(value):
            raise ValueError(f"{name} must be real, got complex entries")
        if value.dtype.kind not in "biuf":
            raise ValueError(f"{name} must be a matrix of numbers, got a sparse matrix of dtype {value.dtype}")
        return _csc(value)
    if np.iscomplexobj(value):
        raise ValueError(f"{name} must be real, got complex values")
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an array of numbers, got {value!r:.60}") from None


def _canonical(M: sp.csc_matrix) -> sp.csc_matrix:
    """``M`` in canonical CSC form (sorted row indices, no duplicates) with :data:`INDEX` indices (int64 only
    where int32 cannot hold them, as scipy): ``M`` itself when it is, else a copy (the user's matrix is never
    changed).  The compiled kernels read canonical arrays."""
    if (M.indices.dtype != INDEX or M.indptr.dtype != INDEX) and max(M.nnz, *M.shape) <= np.iinfo(INDEX).max:
        M = sp.csc_matrix((M.data.copy(), M.indices.astype(INDEX), M.indptr.astype(INDEX)), shape=M.shape)
    if M.has_canonical_format:
        return M
    M = M.copy()
    M.sum_duplicates()
    return M


def _symmetry_defect(P: sp.csc_matrix) -> tuple[float, float]:
    """(max |P - P'|, max |P|) of canonical CSC ``P``: one compiled pass where numba is installed and P is large
    enough to pay for it (:func:`admmkit.problems.qp.segment.compiled_pays`), else scipy (the same values)."""
    if P.nnz == 0:
        return 0.0, 0.0
    if NUMBA and compiled_pays(P.shape[0], 0, P.nnz):
        defect, scale = symmetry_defect(P.indptr, P.indices, P.data)
        return float(defect), float(scale)
    return float(abs(P - P.T).max()), float(np.max(np.abs(P.data)))


def _p_facts(P: sp.csc_matrix, compiled: bool | None = None) -> tuple[bool, float, float, bool | None]:
    """(finite, max |P - P'|, max |P|, diagonal or None: not asked) of canonical CSC ``P``: one compiled call
    where compiled code pays (``compiled``; None: :func:`admmkit.problems.qp.segment.compiled_pays` says) with
    ``sparse_kernels.p_checks``, else numpy and :func:`_symmetry_defect`."""
    if compiled is None:
        compiled = NUMBA and compiled_pays(P.shape[0], 0, P.nnz)
    if compiled and P.nnz:
        finite, defect, scale, diagonal = p_checks(P.indptr, P.indices, P.data)
        return bool(finite), float(defect), float(scale), bool(diagonal)
    if not np.all(np.isfinite(P.data)):
        return False, 0.0, 0.0, None
    defect, scale = _symmetry_defect(P)
    return True, defect, scale, None


def _validate(P, q, A, l, u, allow_nonconvex: bool = False):
    """Check types, shapes, symmetry, convexity, finiteness and l <= u; return (P, q, A, l, u) as csc/arrays.

    ``allow_nonconvex``: a P that is not positive semidefinite gives a warning instead of the error (as OSQP
    solves such a QP: a point ADMM returns is then at best stationary)."""
    P = _real("P", P, sparse_ok=True)
    if not sp.issparse(P) and P.ndim != 2:
        raise ValueError(f"P must be a square 2-D matrix of shape (n, n), got an array of shape {P.shape}")
    P = _csc(P)
    n = P.shape[0]
    if P.shape != (n, n):
        raise ValueError(f"P must be square (n x n), got shape {P.shape}")
    if n == 0:
        raise ValueError("the QP needs at least one variable: P, q and A must have n >= 1 columns, got n = 0")
    P = _canonical(P)                   # (raises nothing: the checks below come in the order they always did)
    compiled = NUMBA and compiled_pays(n, 0, P.nnz)          # asked once: the compiled passes of P and the bounds
    finite, asym, scale, diagonal = _p_facts(P, compiled)
    if not finite:
        raise ValueError("P must have finite entries")
    if asym > 1e-10 * max(1.0, scale):
        raise ValueError(f"P must be symmetric; max |P - P'| = {asym:.3g}")
    try:
        check_convex(P, scale=scale, diagonal=diagonal)
    except ValueError as err:
        if not allow_nonconvex:
            raise ValueError(f"{err}; allow_nonconvex=True solves it anyway, as OSQP does") from None
        warnings.warn(f"{err}; solving it anyway (allow_nonconvex=True): ADMM may not converge, and a point "
                      f"it returns is at best stationary", RuntimeWarning, stacklevel=3)
    q = _real("q", q).ravel()
    if q.shape != (n,):
        raise ValueError(f"q must have length n = {n} (from P), got shape {q.shape}")
    if not np.all(np.isfinite(q)):
        raise ValueError("q must be finite")
    A = _real("A", A, sparse_ok=True)
    if not sp.issparse(A) and A.ndim != 2:
        raise ValueError(f"A must be a 2-D matrix of shape (m, n) with n = {n} (from P), got an array of shape "
                         f"{A.shape}")
    A = _csc(A)
    if A.shape[1] != n:
        raise ValueError(f"A must have n = {n} columns (from P), got shape {A.shape}")
    if not np.all(np.isfinite(A.data)):
        raise ValueError("A must have finite entries")
    A = _canonical(A)
    m = A.shape[0]
    l = _real("l", l).ravel()
    u = _real("u", u).ravel()
    _check_bounds(l, u, m, compiled or compiled_pays(n, m, P.nnz + A.nnz))
    return P, q, A, l, u


def _kernel_ready(v: np.ndarray) -> bool:
    """Whether the compiled kernels' own signature takes ``v`` (contiguous and writeable, as the kernels were compiled
    for): another layout would compile a new copy of the kernel, seconds at a first call."""
    flags = v.flags
    return flags.c_contiguous and flags.writeable


def _check_bounds(l: np.ndarray, u: np.ndarray, m: int, compiled: bool) -> None:
    """ValueError unless l and u have length m, hold no NaN, no l_i = +inf nor u_i = -inf, and l <= u (the first
    failed check, in that order, l's before u's); ``compiled``: the facts of both in one compiled pass
    (``validate_kernel.bound_facts``, the same answers) once both lengths are right."""
    if compiled and l.shape == (m,) and u.shape == (m,) and _kernel_ready(l) and _kernel_ready(u):
        nan_l, nan_u, wrong_inf, crossed, first = bound_facts(l, u)
        facts = {"l": nan_l, "u": nan_u}
    else:
        facts = crossed = None
    for name, v in (("l", l), ("u", u)):
        if v.shape != (m,):
            raise ValueError(f"{name} must have length m = {m} (rows of A), got shape {v.shape}")
        if facts[name] if facts else np.any(np.isnan(v)):
            raise ValueError(f"{name} must not contain NaN")
    if wrong_inf if facts else (np.any(l == np.inf) or np.any(u == -np.inf)):
        raise ValueError("bounds must satisfy l < +inf and u > -inf")
    if facts is None:
        bad = np.flatnonzero(l > u)
        crossed, first = bad.size, (bad[0] if bad.size else -1)
    if crossed:
        i = first
        raise ValueError(f"l must be <= u; row {i} has l = {l[i]:g} > u = {u[i]:g} ({crossed} such rows)")


def check_options(*, sigma, backend, xstep, scaling, row_weights, x_relaxation, allow_nonconvex) -> dict:
    """The QP's options checked (a ValueError naming the option and its range), as a dict of plain values."""
    if isinstance(sigma, (bool, str, bytes)) or not isinstance(sigma, (int, float, np.integer, np.floating)) \
            or not (math.isfinite(sigma) and sigma >= 0):
        raise ValueError(f"sigma must be a finite number >= 0, got {sigma!r}")
    if xstep not in XSTEPS:
        raise ValueError(f"xstep must be one of {', '.join(XSTEPS)}, got {xstep!r}")
    if isinstance(scaling, bool) or not isinstance(scaling, (int, np.integer)) or scaling < 0:
        raise ValueError(f"scaling must be an integer >= 0 (Ruiz iterations; OSQP uses 10), got {scaling!r}")
    if row_weights not in ROW_WEIGHTS:
        raise ValueError(f"row_weights must be one of {', '.join(ROW_WEIGHTS)}, got {row_weights!r}")
    if not (isinstance(x_relaxation, (int, float)) and 0 < x_relaxation < 2):
        raise ValueError(f"x_relaxation must be a number in (0, 2), got {x_relaxation!r}")
    return dict(sigma=float(sigma), backend=backend, xstep=xstep, scaling=int(scaling), row_weights=row_weights,
                x_relaxation=float(x_relaxation), allow_nonconvex=bool(allow_nonconvex))
