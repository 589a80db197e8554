"""scipy's SuperLU and three LAPACK routines, called without importing scipy.linalg or scipy.sparse.linalg.

The condensed mode needs SuperLU (the factorisation of K in the contact-last
order, :mod:`admmkit.problems.contact.solvers.schur`, and its triangular
solve with U, :func:`upper_solve`) and LAPACK's potrf,
potrs and trtrs (the dense x-step, the compliance).  Importing
``scipy.sparse.linalg`` for them imports ``scipy.linalg`` too, whose import
parses the docstrings of its functions: at load 4 on 2 cores ``import numpy,
scipy.sparse.linalg`` took 1.11 s against 0.84 s for ``import numpy,
scipy.sparse``, for two compiled modules that load in a few milliseconds.
Without them a warm ``solve contact`` process took 0.73-0.84 of its time
before (wall, three runs at load 3-6; issue #49, docs/contact.md).

So the two compiled modules that hold the routines,
``scipy.sparse.linalg._dsolve._superlu`` and ``scipy.linalg._flapack``, are
loaded from their files (``importlib.machinery.ExtensionFileLoader``), without
running their packages' ``__init__``, and called with the arguments
``scipy.sparse.linalg.splu``, ``scipy.linalg.cho_factor``,
``scipy.linalg.lapack.dpotrs`` and ``scipy.linalg.solve_triangular`` give
them: the same routines on the same arrays, so the same bits.  Where a
package is imported already, its own module is used.

``DIRECT = False``, a scipy whose files are laid out otherwise, or an input
these shortcuts do not cover (not float64, empty, indices beyond 32 bits)
take the library functions: the plain path, compared with this one bit for bit
in tests/problems/test_contact_first_call.py.  The routines and their arguments
are scipy's private ones: where a direct call does not take them (TypeError or
AttributeError: a scipy that changed them), ``DIRECT`` turns False and that
call and every later one take the library functions.
"""
from __future__ import annotations

import importlib.machinery
import importlib.util
import sys
from pathlib import Path

import numpy as np
import scipy.sparse as sp

#: load the compiled modules from their files (False: import scipy.linalg and scipy.sparse.linalg as usual)
DIRECT = True

_loaded: dict[str, object] = {}


def _extension(package: str, name: str):
    """The compiled module ``package.name``: imported already, or loaded from its file without ``package``'s
    ``__init__`` (None when ``DIRECT`` is False or the file is not where scipy keeps it)."""
    if not DIRECT:
        return None
    full = f"{package}.{name}"
    if full in sys.modules:
        return sys.modules[full]
    if full not in _loaded:
        import scipy
        folder = Path(scipy.__file__).parent.joinpath(*package.split(".")[1:])
        module = None
        for suffix in importlib.machinery.EXTENSION_SUFFIXES:
            path = folder / f"{name}{suffix}"
            if path.is_file():
                loader = importlib.machinery.ExtensionFileLoader(full, str(path))
                spec = importlib.util.spec_from_loader(full, loader, origin=str(path))
                module = importlib.util.module_from_spec(spec)
                loader.exec_module(module)
                break
        _loaded[full] = module
    return _loaded[full]


def _library_from_now_on() -> None:
    """A direct call did not take scipy's private arguments: the library functions from now on."""
    global DIRECT
    DIRECT = False
    _loaded.clear()


def _flapack():
    """scipy.linalg._flapack (None: use scipy.linalg)."""
    return _extension("scipy.linalg", "_flapack")


def splu_natural(A: sp.csc_matrix, factor_arrays: bool = False, panel_size: int | None = None):
    """``scipy.sparse.linalg.splu(A, permc_spec="NATURAL", diag_pivot_thresh=0.0,
    options=dict(SymmetricMode=True))``: LU in A's own order, without pivoting (A CSC, canonical, float64).

    ``factor_arrays``: the factor's ``L`` and ``U`` are then SuperLU's CSC
    arrays as a tuple ``(data, indices, indptr)`` instead of ``csc_array``s,
    for a caller that reads them itself (:func:`factor_csc_arrays` reads
    either): SuperLU copies both factors at each access, and scipy's format
    check of the copies doubled the cost (1.6 of 2.8 ms at Example 1,
    h = 1/40).  ``panel_size``: SuperLU's panel size (splu's ``panel_size``; None: SuperLU's default).  A singular
    A raises RuntimeError, as splu does."""
    superlu = _extension("scipy.sparse.linalg._dsolve", "_superlu")
    if (superlu is None or A.format != "csc" or A.dtype != np.float64 or A.shape[0] != A.shape[1]
            or max(A.nnz, A.shape[0]) >= np.iinfo(np.intc).max):
        import scipy.sparse.linalg as spla
        return spla.splu(A, permc_spec="NATURAL", diag_pivot_thresh=0.0, panel_size=panel_size,
                         options=dict(SymmetricMode=True))
    A.sum_duplicates()                                   # as splu does (a no-op on a canonical matrix)
    options = dict(DiagPivotThresh=0.0, ColPerm="NATURAL", PanelSize=panel_size, Relax=None, SymmetricMode=True)
    try:
        return superlu.gstrf(A.shape[0], A.nnz, A.data, A.indices.astype(np.intc, copy=False),
                             A.indptr.astype(np.intc, copy=False),
                             csc_construct_func=_csc_arrays if factor_arrays else sp.csc_array, ilu=False,
                             options=options)
    except (TypeError, AttributeError):
        _library_from_now_on()
        return splu_natural(A, factor_arrays, panel_size)


def _csc_arrays(arrays: tuple, shape=None) -> tuple:
    """SuperLU's factor as the arrays it gives, (data, indices, indptr), without making a scipy matrix."""
    return arrays


def factor_csc_arrays(factor) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(data, indices, indptr) of a factor (``lu.U`` or ``lu.L``) that :func:`splu_natural` gave as a scipy CSC
    matrix or, with ``factor_arrays``, as the arrays themselves."""
    if isinstance(factor, tuple):
        return factor
    return factor.data, factor.indices, factor.indptr


def upper_solve(diagonal: np.ndarray, data: np.ndarray, indices: np.ndarray, indptr: np.ndarray, b: np.ndarray,
                trans: bool = False) -> np.ndarray:
    """x with U x = b (U' x = b when ``trans``), U upper triangular: its diagonal ``diagonal`` and its entries
    above the diagonal the CSC arrays (``data``, ``indices``, ``indptr``; an entry on the diagonal there must be
    zero).  One substitution in C, SuperLU's ``gstrs`` (what ``scipy.sparse.linalg.spsolve_triangular`` calls)
    given U as a factor with a unit L: no copy of U, where ``spsolve_triangular`` copies and rescales it.

    SuperLU keeps the diagonal of U in L's supernodes, so L is passed as the diagonal alone (n supernodes of one
    column, unit lower: L = I) and U as its part above the diagonal.  Where ``gstrs`` does not take these
    arguments (a scipy that changed them), ``spsolve_triangular`` on U assembled."""
    b1 = np.ascontiguousarray(b, dtype=np.float64)
    d = np.ascontiguousarray(diagonal, dtype=np.float64)
    n = d.shape[0]
    if b1.shape != (n,):
        raise ValueError(f"b must have shape ({n},), got {b1.shape}")
    superlu = _extension("scipy.sparse.linalg._dsolve", "_superlu")
    if superlu is None:
        from scipy.sparse.linalg._dsolve import _superlu as superlu
    unit = np.arange(n + 1, dtype=np.intc)      # L: column j holds its diagonal entry only
    try:
        x, info = superlu.gstrs("T" if trans else "N", n, n, d, unit[:n], unit, n, data.shape[0],
                                np.ascontiguousarray(data, dtype=np.float64), indices.astype(np.intc, copy=False),
                                indptr.astype(np.intc, copy=False), b1)
    except (TypeError, AttributeError):         # a scipy whose gstrs takes other arguments
        from scipy.sparse.linalg import spsolve_triangular
        U = (sp.csc_matrix((data, indices, indptr), shape=(n, n)) + sp.diags(d, format="csc")).tocsr()
        return spsolve_triangular(U.T.tocsr() if trans else U, b1, lower=bool(trans))
    if info:
        raise np.linalg.LinAlgError(f"SuperLU's triangular solve failed (info {info})")
    return x


def cho_factor(a: np.ndarray) -> tuple[np.ndarray, bool]:
    """``scipy.linalg.cho_factor(a)``: (c, False), c's upper triangle the Cholesky factor R of a = R'R.

    A non-finite entry raises ValueError, a matrix that is not positive definite LinAlgError, as there."""
    lapack = _flapack()
    a1 = np.asarray_chkfinite(a)
    if lapack is None or a1.dtype != np.float64 or a1.ndim != 2 or a1.shape[0] != a1.shape[1] or a1.size == 0:
        import scipy.linalg as sla
        return sla.cho_factor(a)
    # cho_factor overwrites a only when it made a1 a copy of it, never for a float64 array
    try:
        c, info = lapack.dpotrf(a1, lower=False, overwrite_a=False, clean=False)
    except (TypeError, AttributeError):
        _library_from_now_on()
        return cho_factor(a)
    if info > 0:
        raise np.linalg.LinAlgError(f"{info}-th leading minor of the array is not positive definite")
    if info < 0:
        raise ValueError(f'LAPACK reported an illegal value in {-info}-th argument on entry to "POTRF".')
    return c, False


def cho_solve(c: np.ndarray, lower: bool, rhs: np.ndarray) -> np.ndarray:
    """``scipy.linalg.lapack.dpotrs(c, rhs, lower=lower)[0]``: the solution of a x = rhs from cho_factor's c."""
    lapack = _flapack()
    if lapack is None:
        from scipy.linalg.lapack import dpotrs
        return dpotrs(c, rhs, lower=lower)[0]
    try:
        return lapack.dpotrs(c, rhs, lower=lower)[0]
    except (TypeError, AttributeError):
        _library_from_now_on()
        return cho_solve(c, lower, rhs)


def solve_triangular(a: np.ndarray, b: np.ndarray, trans: int | str = 0, lower: bool = False,
                     unit_diagonal: bool = False) -> np.ndarray:
    """``scipy.linalg.solve_triangular(a, b, trans, lower, unit_diagonal, check_finite=False)`` (trans 0 or "N",
    1 or "T")."""
    lapack = _flapack()
    trans = {"N": 0, "T": 1}.get(trans, trans)
    a1, b1 = np.asarray(a), np.asarray(b)
    if (lapack is None or trans not in (0, 1) or a1.dtype != np.float64 or b1.dtype != np.float64
            or a1.ndim != 2 or a1.shape[0] != a1.shape[1] or a1.shape[0] != b1.shape[0] or b1.size == 0):
        import scipy.linalg as sla
        return sla.solve_triangular(a, b, trans=trans, lower=lower, unit_diagonal=unit_diagonal, check_finite=False)
    try:
        if a1.flags.f_contiguous:
            x, info = lapack.dtrtrs(a1, b1, overwrite_b=False, lower=lower, trans=trans, unitdiag=unit_diagonal)
        else:   # the transposed system, as solve_triangular does: trtrs expects Fortran order
            x, info = lapack.dtrtrs(a1.T, b1, overwrite_b=False, lower=not lower, trans=not trans,
                                    unitdiag=unit_diagonal)
    except (TypeError, AttributeError):
        _library_from_now_on()
        return solve_triangular(a, b, trans, lower, unit_diagonal)
    if info > 0:
        raise np.linalg.LinAlgError(f"singular matrix: resolution failed at diagonal {info - 1}")
    if info < 0:
        raise ValueError(f"illegal value in {-info}-th argument of internal trtrs")
    return x


def load_extensions() -> None:
    """Load SuperLU's and LAPACK's compiled modules now (nothing if loaded or not ``DIRECT``): done before BLAS
    threads are pinned (:func:`admmkit.loop.blas.limit_blas`), the controller then sees scipy's OpenBLAS at once and
    is not built again at the solve's pin (10-25 ms in a fresh process)."""
    _extension("scipy.sparse.linalg._dsolve", "_superlu")
    _flapack()
