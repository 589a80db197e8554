"""The contact-boundary Schur complement of K, from one sparse factorisation.

Order the dofs that B touches (the contact dofs, index set c) last and the
others (i) first by a fill-reducing ordering.  A factorisation of K in that
order, without pivoting (K is SPD), has trailing blocks whose product is the
Schur complement

    S = K_cc - K_ci K_ii^{-1} K_ic = L_cc L_cc'   (Cholesky, K = L L')
                                   = L_cc U_cc    (LU, K = L U),

and (K^{-1})_cc = S^{-1}.  So the compliance on Gamma_C,

    C = B K^{-1} B' = B_c S^{-1} B_c',

costs one factorisation instead of n_c solves.

Three backends:

* ``"cholmod"`` (scikit-sparse, when installed): AMD on K_ii, then CHOLMOD's
  L L' in that order; S from the last n_c columns of L.
* ``"ldl"`` (:mod:`admmkit.linalg.ldl`, compiled with numba): P K P' = (I + L) D
  (I + L)' in our order; the last n_c columns of L hold only their trailing
  block, so S = L_cc D_c L_cc' and R = D_c^{1/2} L_cc' are read without
  touching the rest of the factor.  Not supernodal: fastest on small bodies.
* ``"superlu"`` (scipy): LU in our order without pivoting; S from the last
  n_c rows and columns of U, which scipy gives only as a copy of all of U
  (made with a copy of all of L, at the first access to either: at Example 1,
  h = 1/40, 7.7 MB into fresh memory, 1.1 ms warm and 6-7.5 ms in the set-up,
  where 1,500-1,800 pages are first written; the rest of the "schur" phase,
  U's trailing block, S, R and the half solves' checks, 0.8 ms).
  With that copy, K = U' D^{-1} U (D = diag U) gives the load's u0 = K^{-1} f
  and the final u each as one substitution, with U' and with U (SuperLU's
  ``gstrs``, ``lapack.upper_solve``), where two whole solves ran (issue #49:
  2.1 + 2.4 ms against 0.6 + 1.5 ms at Example 1, h = 1/40, load 4).

The order of the inner dofs (``ldl`` and ``superlu``): with the dofs'
coordinates, geometric nested dissection
(:mod:`admmkit.problems.contact.solvers.dissection`), else SuperLU's multiple
minimum degree ordering of K_ii (the one ``splu`` uses for a plain solve,
read off a factorisation that keeps no fill).  At Example 2, h = 1/200,
nested dissection took 0.06 s and its order 1.59 s to factorise, minimum
degree 0.33 s and 1.99 s.

``"auto"`` takes CHOLMOD when installed, else ``superlu``, whose set-up runs
without numba on a small body (``compiled="auto"``: the ordering's kernels run
only where they pay, :mod:`admmkit.problems.contact.solvers.dissection`; the
same order either way).  Importing numba and loading the ``ldl`` kernels
costs about 0.7 s in a fresh process, where ``ldl`` saves 5-15 ms over
SuperLU at h = 1/40 (issue #49: the whole ``solve contact`` process).

With ``compiled=True``, ``"auto"`` without CHOLMOD chooses as before issue
#49: up to ``LDL_MAX_DOFS`` dofs, it orders, computes the elimination tree and
L's column counts c_j (:func:`admmkit.linalg.ldl.ldl_analyse`, 1-4 % of a
factorisation), and takes ``ldl`` when the mean column length sum c_j^2 /
sum c_j is at most ``LDL_MAX_COLUMN_LENGTH``, else ``superlu``: the longer the
columns, the more SuperLU's dense supernodal blocks gain over the compiled
scalar loop.  On the paper's 2D meshes that is ``ldl`` up to about h = 1/90
(3.3e4 unknowns), on the 3D block up to about h = 1/5 (2e3 unknowns); larger
bodies get ``superlu`` without the analysis.  That is the choice for a process
that solves many small bodies (numba's cost paid once).
"""
from __future__ import annotations

import functools

import time

import numpy as np
import scipy.sparse as sp

from admmkit.loop.blas import limit_blas

from admmkit.problems.contact.solvers import lapack
from admmkit.problems.contact.solvers.dissection import (contact_last_order, minimum_degree_ordering,  # noqa: F401
                                                         permute_symmetric)

SCHUR_BACKENDS = ("cholmod", "ldl", "superlu")
#: with compiled=True and without CHOLMOD, "auto" takes "ldl" when the mean length of L's columns (sum c_j^2 / sum c_j, known from the
#: elimination tree before the factorisation) is at most this, else "superlu" (supernodal: dense blocks by BLAS).
#: Measured (ordering + factorisation + S, one thread, Examples 1-2 and example2_3d): ldl / superlu 0.67-0.78 at
#: 83-129 (2D h = 1/40-1/70, 3D 1/4), 0.89-1.04 at 142-188 (2D 1/70-1/100), 1.09-1.80 at 214-682 (3D 1/6-1/12)
LDL_MAX_COLUMN_LENGTH = 170.0
#: with compiled=True and without CHOLMOD, "auto" computes the mean column length up to this many dofs only, and takes "superlu" above
#: it: the analysis costs 2-4 percent of a factorisation, 58-104 ms at h = 1/200, where the mean column length
#: was 296-325 (2D: 172-188 at 4e4-6e4 dofs)
LDL_MAX_DOFS = 50_000


@functools.lru_cache(maxsize=1)
def available_schur_backends() -> tuple[str, ...]:
    """The Schur backends installed here, fastest first (asked once: a failed import costs ~0.4 ms each time)."""
    out = []
    try:
        from sksparse import cholmod  # noqa: F401
        out.append("cholmod")
    except ImportError:
        pass
    from admmkit.kernels import AVAILABLE
    return tuple(out + (["ldl"] if AVAILABLE else []) + ["superlu"])


class _CholmodSchur:
    """K = L L' by CHOLMOD, inner dofs in AMD order, contact dofs last."""

    def __init__(self, K: sp.csc_matrix, inner: np.ndarray, contact: np.ndarray, timings: dict):
        from sksparse import cholmod
        t0 = time.perf_counter()
        analysis = cholmod.analyze(K[inner][:, inner].tocsc(), ordering_method="amd")
        self.order = np.concatenate([inner[analysis.P()], contact])
        Kp = K[self.order][:, self.order].tocsc()
        t1 = time.perf_counter()
        self._factor = cholmod.cholesky(Kp, ordering_method="natural")
        t2 = time.perf_counter()
        m = contact.size
        L_c = sp.csc_matrix(self._factor.L()[:, -m:])   # the last m columns: [0; L_cc]
        L_cc = L_c[-m:, :].toarray()
        self.S = L_cc @ L_cc.T                          # S = L_cc L_cc'
        self.R = L_cc.T                                 # S = R'R, R upper triangular
        timings.update(ordering=t1 - t0, factorisation=t2 - t1, schur=time.perf_counter() - t2)

    def solve_permuted(self, b: np.ndarray) -> np.ndarray:
        return self._factor(b)


class _SuperLUSchur:
    """K = L U by SuperLU in the given order (contact dofs last), without pivoting."""

    def __init__(self, K: sp.csc_matrix, order: np.ndarray, m: int, timings: dict, analysis=None, compiled="auto"):
        t1 = time.perf_counter()
        self.order = order
        Kp = permute_symmetric(K, order, compiled)
        try:
            self._lu = lapack.splu_natural(Kp, factor_arrays=True)   # without scipy.sparse.linalg
        except RuntimeError as err:
            raise np.linalg.LinAlgError(f"K is singular (is the body clamped?): {err}") from None
        t2 = time.perf_counter()
        # no pivoting and K symmetric: L = U' D^{-1} with D = diag(U), so S = L_cc U_cc = U_cc' D_c^{-1} U_cc
        # (scipy copies L and U both at the first access to either; only U is read here)
        data, indices, indptr = lapack.factor_csc_arrays(self._lu.U)
        U_cc = trailing_block(data, indices, indptr, m)
        d = np.diag(U_cc)[:, None]
        self.S = U_cc.T @ (U_cc / d)
        self.R = U_cc / np.sqrt(d)                      # S = R'R, R upper triangular (D > 0: K is SPD)
        self.U_cc = U_cc
        self._halves = _half_solves(self._lu, data, indices, indptr, m)
        timings.update(factorisation=t2 - t1, schur=time.perf_counter() - t2)

    def solve_permuted(self, b: np.ndarray) -> np.ndarray:
        return self._lu.solve(b)

    def load(self, fp: np.ndarray):
        """For P f (None when the factor does not allow half solves, :func:`_half_solves`): t = U'^{-1} P f,
        f'K^{-1}f = t'D t and the contact part of K^{-1} f = U^{-1} D t, which needs only the trailing block of
        U: U_cc x_c = (D t)_c.  One substitution with U' instead of a whole solve (K = U' D^{-1} U)."""
        if self._halves is None:
            return None
        d, U, position = self._halves
        t = lapack.upper_solve(d, *U, _scatter(fp, position), trans=True)
        dt = d * t
        m = self.U_cc.shape[0]
        x_c = lapack.solve_triangular(self.U_cc, dt[-m:], lower=False)
        return float(t @ dt), x_c, t

    def solve_load(self, t: np.ndarray, s: float, v: np.ndarray) -> np.ndarray:
        """(P K P')^{-1} (s P f + [0; v]) from t = U'^{-1} P f: U'^{-1} [0; v] is U_cc'^{-1} v on the trailing
        block alone, then one substitution with U."""
        d, U, position = self._halves
        m = v.shape[0]
        w = s * t
        w[-m:] += lapack.solve_triangular(self.U_cc, v, trans="T", lower=False)
        x = lapack.upper_solve(d, *U, d * w)
        return x if position is None else x[position]


def _scatter(b: np.ndarray, position: np.ndarray | None) -> np.ndarray:
    """b in SuperLU's numbering: out[position[k]] = b[k] (b itself when the numbering is the identity)."""
    if position is None:
        return b
    out = np.empty_like(b)
    out[position] = b
    return out


def _half_solves(lu, data: np.ndarray, indices: np.ndarray, indptr: np.ndarray, m: int):
    """(D, U above its diagonal, SuperLU's column permutation or None) for :meth:`_SuperLUSchur.load`'s half
    solves with U alone, or None where they do not apply: rows and columns renumbered differently, the last m
    moved, or a column of U that does not end at its diagonal (then two whole solves, as before).

    SuperLU factorises Pr K Pc = L U; here Pr = Pc (no pivoting, symmetric mode), and scipy reports Pc as the
    identity in our orders; any other Pc that keeps the contact dofs last is undone by the solves.  ``data`` is
    SuperLU's copy of U, ours: its diagonal is set to zero in place (the substitution takes D apart,
    ``lapack.upper_solve``)."""
    n = indptr.shape[0] - 1
    perm_c, perm_r = np.asarray(lu.perm_c), np.asarray(lu.perm_r)
    ends = indptr[1:] - 1
    if (n == 0 or not np.array_equal(perm_c, perm_r) or not np.array_equal(perm_c[n - m:], np.arange(n - m, n))
            or np.any(indptr[1:] == indptr[:-1]) or not np.array_equal(indices[ends], np.arange(n))):
        return None
    d = data[ends]
    data[ends] = 0.0
    position = None if np.array_equal(perm_c, np.arange(n)) else perm_c
    return d, (data, indices, indptr), position


def trailing_block(data: np.ndarray, indices: np.ndarray, indptr: np.ndarray, m: int) -> np.ndarray:
    """The dense trailing m x m block of a square CSC matrix U given by its arrays (the same values as
    ``U[:, -m:][-m:, :].toarray()``, without scipy's two indexing steps)."""
    n = indptr.shape[0] - 1
    start, stop = indptr[n - m], indptr[n]
    rows, values = indices[start:stop], data[start:stop]
    columns = np.repeat(np.arange(m), np.diff(indptr[n - m:]))
    keep = rows >= n - m
    block = np.zeros((m, m))
    block[rows[keep] - (n - m), columns[keep]] = values[keep]
    return block


class _LDLSchur:
    """P K P' = (I + L) D (I + L)' by :func:`admmkit.linalg.ldl.ldl_factor` in the given order (contact dofs last)."""

    def __init__(self, K: sp.csc_matrix, order: np.ndarray, m: int, timings: dict, analysis=None, compiled=True):
        from admmkit.linalg.ldl import ldl_factor
        t1 = time.perf_counter()
        self.order = order
        try:
            self._factor = ldl_factor(K, order, analysis)
        except np.linalg.LinAlgError as err:
            raise np.linalg.LinAlgError(f"K is singular (is the body clamped?): {err}") from None
        if self._factor.d.min() <= 0.0:
            raise np.linalg.LinAlgError(f"K is not positive definite: pivot {self._factor.d.min():.3g} <= 0")
        t2 = time.perf_counter()
        # the last m columns of I + L hold only their trailing block: S = L_cc D_c L_cc', read without a copy
        self.L_cc, d_c = self._factor.trailing_block(m), self._factor.d[-m:]
        self.S = (self.L_cc * d_c) @ self.L_cc.T
        self.R = np.sqrt(d_c)[:, None] * self.L_cc.T     # S = R'R, R upper triangular
        timings.update(factorisation=t2 - t1, schur=time.perf_counter() - t2)

    def solve_permuted(self, b: np.ndarray) -> np.ndarray:
        return self._factor.solve_permuted(b)

    def load(self, fp: np.ndarray):
        """For P f: y = (I + L)^{-1} P f, f'K^{-1}f = y'D^{-1}y and the contact part of K^{-1} f, which needs
        only the trailing block of the backward substitution: (I + L_cc)' x_c = (D^{-1} y)_c."""
        y = self._factor.forward(fp)
        z = y / self._factor.d
        m = self.L_cc.shape[0]
        x_c = lapack.solve_triangular(self.L_cc, z[-m:], trans="T", lower=True, unit_diagonal=True)
        return float(y @ z), x_c, y

    def solve_load(self, y: np.ndarray, s: float, v: np.ndarray) -> np.ndarray:
        """(P K P')^{-1} (s P f + [0; v]) from y = (I + L)^{-1} P f: the forward substitution of [0; v] is
        (I + L_cc)^{-1} v on the trailing block alone, then one backward substitution."""
        m = v.shape[0]
        w = s * y
        w[-m:] += lapack.solve_triangular(self.L_cc, v, lower=True, unit_diagonal=True)
        return self._factor.backward(w / self._factor.d)


_ORDERED = {"ldl": _LDLSchur, "superlu": _SuperLUSchur}   # the backends that take our order


def _ordered_factorisation(K, inner, contact, timings, coordinates, backend, compiled="auto", order=None):
    """Order the dofs (contact_last_order, unless ``order`` gives it), pick "ldl" or "superlu" for "auto",
    factorise."""
    t0 = time.perf_counter()
    if order is None:
        order = contact_last_order(K, inner, contact, coordinates, compiled)
    analysis = None
    if backend == "auto" and (compiled is not True or K.shape[0] > LDL_MAX_DOFS):
        backend = "superlu"
    elif backend == "auto":   # the elimination tree and L's column counts tell how long the updates run
        from admmkit.linalg.ldl import ldl_analyse
        analysis = ldl_analyse(K, order)
        backend = "ldl" if analysis.mean_column_length <= LDL_MAX_COLUMN_LENGTH else "superlu"
    timings["ordering"] = time.perf_counter() - t0
    return _ORDERED[backend](K, order, contact.size, timings, analysis, compiled), backend


def _csc(K: sp.spmatrix) -> sp.csc_matrix:
    """K in CSC: K is symmetric, so its CSR arrays are those of K' = K in CSC (no copy)."""
    if getattr(K, "format", None) == "csr":
        return sp.csc_matrix((K.data, K.indices, K.indptr), shape=K.shape)
    return sp.csc_matrix(K)


def _split_dofs(K: sp.csc_matrix, B: sp.spmatrix) -> tuple[np.ndarray, np.ndarray]:
    """(contact, inner): the dofs B touches, sorted, and the others (a mask, where ``np.unique`` would load numpy.ma,
    30-50 ms of a fresh ``solve contact`` process: admmkit/cli/deferred_modules.py)."""
    touched = np.zeros(K.shape[0], dtype=bool)
    touched[sp.csr_matrix(B).indices] = True
    return np.flatnonzero(touched), np.flatnonzero(~touched)


def _fits(order: np.ndarray, n: int, contact: np.ndarray) -> bool:
    """Whether ``order`` is an order of n dofs that ends with ``contact``."""
    order = np.asarray(order)
    if order.shape != (n,) or order.dtype.kind not in "iu" or not np.array_equal(order[n - contact.size:], contact):
        return False
    seen = np.zeros(n, dtype=bool)
    if order.size and (order.min() < 0 or order.max() >= n):
        return False
    seen[order] = True
    return bool(seen.all())


def contact_last(K: sp.spmatrix, B: sp.spmatrix, coordinates: np.ndarray | None = None,
                 compiled="auto") -> np.ndarray:
    """The order in which :class:`BoundarySchur` factorises K with ``ldl`` or ``superlu``: the inner dofs by
    nested dissection (with ``coordinates``) or minimum degree, the dofs B touches last."""
    K = _csc(K)
    contact, inner = _split_dofs(K, B)
    return contact_last_order(K, inner, contact, coordinates, compiled)


class BoundarySchur:
    """One factorisation of K, ordered contact-last, giving S and solves with K.

    Attributes: ``contact_dofs`` (the dofs B touches), ``S`` (dense Schur
    complement on them), ``backend`` (the one used: "cholmod", "ldl" or
    "superlu"), ``timings`` (seconds of ordering, factorisation and Schur
    extraction; "auto"'s elimination tree counts as ordering).

    BLAS runs with ``blas_threads`` threads during the factorisation (None:
    leave it alone).  One thread is the default, as in :func:`admmkit.solve`:
    on this 2-core machine, loaded by another process, CHOLMOD with two
    OpenBLAS threads took 0.45 s instead of 0.02 s at Example 2, h = 1/40.

    ``coordinates`` ((n, d), the position of each dof, or None): with them
    the order of the inner dofs (``ldl``, ``superlu``) is nested dissection,
    else minimum degree (CHOLMOD always takes AMD).

    ``compiled``: "auto" (the ordering's numba kernels where they pay, the
    same order as without them), True (the kernels, and "auto" may take
    ``ldl``: see the module docstring) or False (no numba unless ``backend``
    is "ldl").

    ``order``: the order :func:`contact_last` gives for these K, B and
    coordinates, computed before (the operator cache stores it: a warm
    ``solve contact`` process does not order again); used by ``ldl`` and
    ``superlu`` when it is a permutation of K's dofs that ends with the dofs
    B touches, else ignored.
    """

    def __init__(self, K: sp.spmatrix, B: sp.spmatrix, backend: str = "auto", blas_threads: int | None = 1,
                 coordinates: np.ndarray | None = None, compiled="auto", order: np.ndarray | None = None):
        if backend not in ("auto",) + SCHUR_BACKENDS:
            raise ValueError(f"schur backend must be 'auto' or one of {', '.join(SCHUR_BACKENDS)}, got {backend!r}")
        if compiled not in ("auto", True, False):
            raise ValueError(f"compiled must be 'auto', True or False, got {compiled!r}")
        installed = available_schur_backends()
        if backend == "auto" and installed[0] == "cholmod":
            backend = "cholmod"
        elif backend != "auto" and backend not in installed:
            raise ValueError(f"schur backend {backend!r} is not installed here (installed: {', '.join(installed)})")
        K = _csc(K)
        self.contact_dofs, inner = _split_dofs(K, B)
        if order is not None and not _fits(order, K.shape[0], self.contact_dofs):
            order = None
        self.timings: dict[str, float] = {}
        if backend != "cholmod":
            lapack.load_extensions()        # before the pin below: one BLAS controller for the set-up and the solve
        try:
            with limit_blas(blas_threads):
                if backend == "cholmod":
                    self._impl = _CholmodSchur(K, inner, self.contact_dofs, self.timings)
                else:
                    self._impl, backend = _ordered_factorisation(K, inner, self.contact_dofs, self.timings,
                                                                 coordinates, backend, compiled, order)
        except np.linalg.LinAlgError:
            raise
        except Exception as err:  # CHOLMOD reports a non-positive-definite K as CholmodNotPositiveDefiniteError
            if "positive definite" in str(err).lower() or "singular" in str(err).lower():
                raise np.linalg.LinAlgError(f"K is singular (is the body clamped?): {err}") from None
            raise
        self.backend = backend
        self.order = self._impl.order
        self.S = 0.5 * (self._impl.S + self._impl.S.T)

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """K^{-1} rhs (rhs in the original dof order)."""
        x = self._impl.solve_permuted(np.asarray(rhs, dtype=float)[self.order])
        out = np.empty_like(x)
        out[self.order] = x
        return out

    def load(self, f: np.ndarray) -> tuple[float, np.ndarray]:
        """f'K^{-1}f and K^{-1}f on the contact dofs, for a load f that :meth:`solve_load` adds to later.

        With ``ldl`` this costs a forward substitution: the backward one is
        left to :meth:`solve_load`, which does it once for the load and the
        contact forces together (one solve in all, where two solves took 2.6
        ms at Example 2, h = 1/40).  The other backends solve with K here.
        """
        f = np.asarray(f, dtype=float)
        half = self._impl.load(f[self.order]) if hasattr(self._impl, "load") else None
        if half is not None:
            e, x_c, y = half
            self._load = ("forward", y)
            return e, x_c
        u = self.solve(f)
        self._load = ("solution", u)
        return float(f @ u), u[self.contact_dofs]

    def solve_load(self, s: float, v: np.ndarray) -> np.ndarray:
        """K^{-1}(s f + E_c v): f the load given to :meth:`load`, v on the contact dofs (E_c: zero elsewhere)."""
        kind, data = self._load
        v = np.asarray(v, dtype=float)
        if kind == "forward":
            x = self._impl.solve_load(data, s, v)
            out = np.empty_like(x)
            out[self.order] = x
            return out
        rhs = np.zeros(data.shape[0])
        rhs[self.contact_dofs] = v
        return s * data + self.solve(rhs)

    def contact_columns(self, B: sp.spmatrix) -> sp.csr_matrix:
        """B's columns of the contact dofs, B[:, contact_dofs]: where B touches no other dof, B's own entries with
        their columns renumbered (the matrix scipy's column indexing gives, which took 0.3-1.9 ms at Example 1,
        h = 1/40), else scipy's indexing."""
        B = sp.csr_matrix(B)
        m = self.contact_dofs.size
        columns = np.searchsorted(self.contact_dofs, B.indices)
        if m == 0 or not np.array_equal(self.contact_dofs[np.minimum(columns, m - 1)], B.indices):
            return B[:, self.contact_dofs]
        return sp.csr_matrix((B.data.copy(), columns.astype(B.indices.dtype), B.indptr.copy()),
                             shape=(B.shape[0], self.contact_dofs.size))

    def compliance(self, B: sp.spmatrix, B_c: sp.spmatrix | None = None) -> np.ndarray:
        """C = B K^{-1} B' = B_c S^{-1} B_c' = W'W with W = R^{-T} B_c' (dense, n_c x n_c, SPD).

        R is S's Cholesky factor, read off the factorisation of K (S = R'R):
        one triangular solve and one symmetric product, 2 n_c^3 flops where
        factorising S, solving and multiplying took 4.3 n_c^3.  ``B_c``: B's
        columns of the contact dofs when the caller has them already.
        """
        Bc = (self.contact_columns(B) if B_c is None else B_c).toarray()
        W = lapack.solve_triangular(self._impl.R, Bc.T, trans="T", lower=False)
        return W.T @ W
