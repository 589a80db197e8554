"""Is P positive semidefinite?  Checked once when a QP is built, so a saddle point is never reported as a minimum.

With the diagonal kept as the pivot (SuperLU with ``diag_pivot_thresh=0``
and a symmetric fill-reducing ordering), the LU factors of the symmetric
matrix P + delta I are L D L' up to scaling, and by Sylvester's law of
inertia the number of negative pivots is the number of eigenvalues of P
below -delta: one sparse factorisation of P (smaller than the x-step's),
at every size (a dense eigenvalue solve cost more than the whole QP solve
below n = 500).  A diagonal P (an LP, a separable QP) is read off directly;
a small P (up to ``DENSE_ANY`` rows, or up to ``DENSE_MAX`` rows stored at least a quarter full) by a
dense Cholesky factorisation of P + delta I (LAPACK's, 10-50x faster than
SuperLU on such a matrix: DUAL2, n = 96, 600 us against 30 us; up to
``COMPILED_CHOLESKY_MAX`` rows, where compiled code runs, one kernel call on
P's arrays instead of LAPACK's call and the dense copy), whose
failure sends P to the eigenvalue test below, as a negative pivot does.
The shift delta = 1e-9 max|P| keeps a singular PSD P (an LP part, a
rank-deficient least-squares term) factorable.  For the message, the
smallest eigenvalue is estimated by Lanczos (``eigsh``), or exactly when P
is small.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from admmkit.kernels import compiled_now
from admmkit.loop.segments import AVAILABLE as NUMBA      # numba installed (asked once, without importing it)

from .sparse_kernels import shifted_cholesky_holds

#: relative shift of P + delta I, and the pivot below which P is indefinite
SHIFT = 1e-9
#: below this size the smallest eigenvalue is computed densely
DENSE_MAX = 500
#: up to this size P goes to the dense Cholesky factorisation however sparse it is: SuperLU's call and its U
#: cost more (CVXQP1_S, n = 100: 190 against 45 us; QAFIRO, n = 32: 150 against 20 us; one run, best of 300)
DENSE_ANY = 128
#: up to this size, where compiled code runs, the dense Cholesky factorisation is one kernel call on P's arrays
#: (``sparse_kernels.shifted_cholesky_holds``): LAPACK's call and the dense copy cost 14-22 us whatever n is, the
#: kernel 1-8 us up to n = 32 and about LAPACK's time at n = 64 (random dense P, best of 500, one run)
COMPILED_CHOLESKY_MAX = 64


def smallest_eigenvalue(P: sp.spmatrix) -> float:
    """The smallest eigenvalue of symmetric P (exact for n <= DENSE_MAX, a Lanczos estimate above)."""
    n = P.shape[0]
    if n <= DENSE_MAX:
        return float(np.linalg.eigvalsh(P.toarray())[0])
    try:
        return float(spla.eigsh(P.astype(float), k=1, which="SA", tol=1e-6, maxiter=20 * n,
                                return_eigenvectors=False)[0])
    except spla.ArpackNoConvergence as err:
        return float(err.eigenvalues[0]) if len(err.eigenvalues) else float("nan")


def shifted(P: sp.csc_matrix, delta: float) -> sp.csc_matrix:
    """P + delta I as scipy's sum ``(P + delta * sp.identity(n, format="csc")).tocsc()`` gives it (the same entries,
    exact zeros dropped, indices sorted), for canonical CSC ``P``: where compiled code runs, one pass of the KKT
    assembly's kernel with no rows of A (``sparse_kernels.kkt_arrays``; scipy's sum costs ~100 us in constructor
    checks on a small P), else scipy's sum."""
    n = P.shape[0]
    if NUMBA and compiled_now():
        from .csc import csc_of
        from .sparse_kernels import kkt_arrays
        indptr, indices, data, _ = kkt_arrays(n, 0, P.indptr, P.indices, P.data, delta,
                                              np.zeros(n + 1, P.indptr.dtype), np.empty(0, P.indices.dtype),
                                              np.empty(0), False)
        return csc_of(data, indices, indptr, (n, n))
    return (P + delta * sp.identity(n, format="csc")).tocsc()


def check_convex(P: sp.csc_matrix, *, scale: float | None = None, diagonal: bool | None = None) -> None:
    """Raise ValueError with the smallest eigenvalue found if the symmetric P is not positive semidefinite.

    ``scale`` (max |P_ij|) and ``diagonal`` (P has no entry off the diagonal), when the caller knows them already
    (the QP's construction: ``validate._p_facts``), are not computed again."""
    n = P.shape[0]
    if P.nnz == 0 or n == 0:
        return
    scale = float(np.max(np.abs(P.data))) if scale is None else scale
    delta = SHIFT * max(scale, 1e-300)
    if diagonal is None:
        diagonal = bool(np.all(P.indices == np.repeat(np.arange(n), np.diff(P.indptr))))
    if diagonal:                                                # diagonal: its entries are the eigenvalues
        indefinite = bool(np.any(P.data < -delta))
    elif n <= COMPILED_CHOLESKY_MAX and NUMBA and compiled_now():        # tiny: one kernel call
        indefinite = not shifted_cholesky_holds(P.indptr, P.indices, P.data, delta)
    elif n <= DENSE_MAX and (n <= DENSE_ANY or 4 * P.nnz >= n * n):     # small, or dense: LAPACK's Cholesky
        dense = P.toarray()
        dense[np.diag_indices(n)] += delta
        try:
            np.linalg.cholesky(dense)
            indefinite = False
        except np.linalg.LinAlgError:        # a pivot <= 0: P + delta I is not positive definite
            indefinite = True
    else:
        try:
            lu = spla.splu(shifted(P, delta), permc_spec="MMD_AT_PLUS_A",
                           diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
            indefinite = bool(np.any(lu.U.diagonal() < -delta))
        except RuntimeError:                  # an exactly singular pivot: P + delta I is not positive definite
            indefinite = True
    lowest = smallest_eigenvalue(P) if indefinite else 0.0
    if indefinite and not lowest >= -delta:    # a singular pivot of a PSD P is not a verdict; NaN: trust the pivots
        raise ValueError(f"P must be positive semidefinite (a convex QP); its smallest eigenvalue is about "
                         f"{lowest:.3g} (max |P| = {scale:.3g}), so the QP has no minimum to find")
