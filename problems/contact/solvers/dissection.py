"""A fill-reducing ordering by geometric nested dissection, compiled (numba).

The boundary-condensed mode factorises K with the contact dofs last
(:mod:`admmkit.problems.contact.solvers.schur`); the inner dofs need a
fill-reducing order.  SuperLU's minimum degree gives one, but scipy exposes
it only through an incomplete LU that keeps no fill, which costs more than the
ordering (at Example 2, h = 1/200: 0.33 s, against 0.22 s for the ordering
inside ``splu``), and minimum degree does not know that the contact dofs stay
to the end: in that order the factorisation took 46 % more flops than an
unconstrained one (7.7e9 against 5.2e9).

Nested dissection with the dofs' coordinates: split a set of dofs at the
median of its longest side, take as separator the dofs of the upper half that
are coupled in K to the lower half, order the lower half, then the upper
half without the separator, each the same way, and the separator last;
sets of at most ``leaf`` dofs are ordered by their coordinates (the dofs of
one node together).  Any split is a valid ordering; the coordinates only make
it a good one.  On the paper's structured meshes, contact dofs last, it gave
6.4e9 flops at Example 2, h = 1/200 (minimum degree: 7.7e9) and the same as
minimum degree at h = 1/40, in under a millisecond there.
:func:`permute_symmetric` applies the order to K for the factorisation;
:func:`contact_last_order` is the whole order the Schur backends use, with
:func:`minimum_degree_ordering` (SuperLU's) where no coordinates are known.

Compiled only where it pays (issue #49): importing numba and loading these
kernels costs about 0.7 s in a fresh process, more than the whole condensed
set-up of a small body.  Each of :func:`nested_dissection` and
:func:`permute_symmetric` has a numpy twin that gives the same permutation
and the same matrix, array for array (``_dissect_numpy`` splits every set
of one level of the dissection at once; scipy's fancy indexing permutes);
``compiled="auto"`` runs the kernels when numba is imported in the process
already or K has at least :data:`COMPILED_MIN_DOFS` rows, the twins
otherwise.  At Example 1 (CPU seconds at load 9 on 2 cores) the twin ordered
in 16 ms at h = 1/40 (the kernel 2 ms) and 0.6 s at h = 1/200 (0.09 s).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from admmkit.kernels import AVAILABLE, compiled_now, njit

#: sets of at most this many dofs are not split (16 was the fastest factorisation of 8, 16, 32 at
#: Examples 1 and 2, h = 1/40 and 1/100)
LEAF = 16
#: from this many rows of K, ``compiled="auto"`` runs the kernels even in a process without numba
#: (at Example 1, h = 1/200, 160,800 rows, the twin's extra 0.5 s is about what importing numba costs)
COMPILED_MIN_DOFS = 150_000


def use_kernels(n: int, compiled="auto") -> bool:
    """Whether the kernels run for a matrix of ``n`` rows: ``compiled`` True or False, or "auto" (the module
    docstring); False where numba is not installed."""
    if compiled not in ("auto", True, False):
        raise ValueError(f"compiled must be 'auto', True or False, got {compiled!r}")
    if compiled == "auto":
        compiled = compiled_now() or n >= COMPILED_MIN_DOFS
    return bool(compiled) and AVAILABLE


def nested_dissection(K, dofs: np.ndarray, coordinates: np.ndarray, leaf: int = LEAF,
                       compiled="auto") -> np.ndarray:
    """An order of ``dofs`` by geometric nested dissection of K's graph restricted to them.

    K: sparse (CSR or CSC; only its pattern is read, which must be
    symmetric); ``dofs``: the indices to order; ``coordinates``: (n, d), the
    position of every dof of K.  Returns ``dofs`` permuted: eliminating them
    in that order (the others after) makes little fill.  ``compiled``: the
    kernel (True), its numpy twin (False) or "auto" (module docstring); the
    same order.
    """
    kernels = use_kernels(K.shape[0], compiled)
    dofs = np.ascontiguousarray(dofs, dtype=np.int64)
    X = np.ascontiguousarray(coordinates, dtype=np.float64)
    if X.ndim != 2 or X.shape[0] != K.shape[0]:
        raise ValueError(f"coordinates must have shape ({K.shape[0]}, d), got {X.shape}")
    if leaf < 1:
        raise ValueError(f"leaf must be >= 1, got {leaf}")
    if kernels:
        return _dissect(K.indptr, K.indices, X, dofs, int(leaf))
    return _dissect_numpy(np.asarray(K.indptr), np.asarray(K.indices), X, dofs, int(leaf))


def permute_symmetric(K: sp.csc_matrix, order: np.ndarray, compiled="auto") -> sp.csc_matrix:
    """P K P' for a structurally symmetric CSC matrix K: ``K[order][:, order]``, row indices sorted.

    Column j of the result is column ``order[j]`` of K with its rows renamed
    and sorted, in one compiled pass: at Example 1, h = 1/40, 0.2 ms where
    scipy's two fancy-index steps took 0.7 ms.  ``compiled``: that pass
    (True), scipy's fancy indexing (False) or "auto" (module docstring); the
    same arrays.
    """
    order = np.ascontiguousarray(order, dtype=np.int64)
    n = K.shape[0]
    if order.shape != (n,):
        raise ValueError(f"order must have shape ({n},), got {order.shape}")
    if n and (order.min() < 0 or order.max() >= n or np.bincount(order, minlength=n).max() > 1):
        raise ValueError("order must be a permutation of 0..n-1")
    if use_kernels(n, compiled):
        position = np.empty(n, np.int64)
        position[order] = np.arange(n)
        indptr, indices, data = _permute(K.indptr, K.indices, K.data, order, position)
    else:
        P = sp.csc_matrix(K)[:, order][order, :].sorted_indices()
        indptr, indices, data = P.indptr.astype(np.int64), P.indices.astype(np.int32), P.data
    out = sp.csc_matrix((data, indices, indptr.astype(np.int32) if indptr[-1] < 2**31 else indptr), shape=K.shape)
    out.has_canonical_format = True   # sorted, and no duplicates since K has none: splu need not check
    return out


def minimum_degree_ordering(A: sp.spmatrix) -> np.ndarray:
    """SuperLU's multiple minimum degree ordering of A' + A, as a permutation.

    scipy does not expose SuperLU's ordering alone, but an incomplete LU
    that drops every entry (``spilu`` with ``drop_tol=1``) computes it, plus
    the elimination-tree postorder, at the cost of the ordering: at Example
    1, h = 1/40, it took 6 ms where METIS nested dissection took 12 ms, and
    the factorisation in either order took 15-17 ms.  Returns ``order`` with
    ``A[order][:, order]`` the reordered matrix.
    """
    import scipy.sparse.linalg as spla    # here only: the nested dissection path imports no scipy.linalg (lapack.py)
    ilu = spla.spilu(sp.csc_matrix(A), drop_tol=1.0, fill_factor=1.0, permc_spec="MMD_AT_PLUS_A",
                     diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
    return np.argsort(ilu.perm_c)   # perm_c[j] is the new position of column j


def contact_last_order(K: sp.csc_matrix, inner: np.ndarray, contact: np.ndarray, coordinates,
                       compiled="auto") -> np.ndarray:
    """The order of a factorisation that gives the Schur complement on ``contact``: the ``inner`` dofs in nested
    dissection order (given the dofs' ``coordinates``) or minimum degree order (None), then ``contact``."""
    first = (nested_dissection(K, inner, coordinates, compiled=compiled) if coordinates is not None else
             inner[minimum_degree_ordering(K[inner][:, inner])])
    return np.concatenate([first, contact])


@njit(cache=True)
def _permute(indptr, indices, data, order, position):
    """The CSC arrays of K[order][:, order]: columns taken in order, rows renamed by position and sorted."""
    n = order.shape[0]
    out_ptr = np.empty(n + 1, np.int64)
    out_ptr[0] = 0
    for j in range(n):
        out_ptr[j + 1] = out_ptr[j] + indptr[order[j] + 1] - indptr[order[j]]
    out_idx = np.empty(out_ptr[n], np.int32)
    out_val = np.empty(out_ptr[n], data.dtype)
    for j in range(n):
        start, q = out_ptr[j], out_ptr[j]
        for p in range(indptr[order[j]], indptr[order[j] + 1]):
            r, v = position[indices[p]], data[p]
            k = q
            while k > start and out_idx[k - 1] > r:   # insertion: columns hold a few dozen entries
                out_idx[k] = out_idx[k - 1]
                out_val[k] = out_val[k - 1]
                k -= 1
            out_idx[k] = r
            out_val[k] = v
            q += 1
    return out_ptr, out_idx, out_val


@njit(cache=True)
def _less(X, a, b):
    """Whether dof a comes before dof b in a leaf: by coordinates, then index."""
    for k in range(X.shape[1]):
        if X[a, k] != X[b, k]:
            return X[a, k] < X[b, k]
    return a < b


@njit(cache=True)
def _sort_leaf(X, perm, lo, hi):
    """Insertion sort of perm[lo:hi] by _less (leaves are small)."""
    for i in range(lo + 1, hi):
        v = perm[i]
        j = i - 1
        while j >= lo and _less(X, v, perm[j]):
            perm[j + 1] = perm[j]
            j -= 1
        perm[j + 1] = v


@njit(cache=True)
def _split(indptr, indices, X, perm, lo, hi, stamp, mark, buf, sep, upper):
    """Reorder perm[lo:hi] as [lower, upper without separator, separator]; return (n_lower, n_upper) or (-1, -1)
    when the set cannot be split (all coordinates equal)."""
    d = X.shape[1]
    best, axis = -1.0, 0
    for k in range(d):
        lo_k, hi_k = np.inf, -np.inf
        for i in range(lo, hi):
            x = X[perm[i], k]
            lo_k = min(lo_k, x)
            hi_k = max(hi_k, x)
        if hi_k - lo_k > best:
            best, axis = hi_k - lo_k, k
    if best <= 0.0:
        return -1, -1
    size = hi - lo
    for i in range(size):
        buf[i] = X[perm[lo + i], axis]
    med = np.median(buf[:size])
    lower_mark, upper_mark = 2 * stamp, 2 * stamp + 1
    n_lower = 0
    for i in range(lo, hi):
        if X[perm[i], axis] < med:
            mark[perm[i]] = lower_mark
            n_lower += 1
        else:
            mark[perm[i]] = upper_mark
    if n_lower == 0:   # at least half the set sits at the minimum: split there instead
        for i in range(lo, hi):
            if X[perm[i], axis] <= med:
                mark[perm[i]] = lower_mark
                n_lower += 1
        if n_lower == size:
            return -1, -1
    # stable partition into buf: lower, upper inner, separator (upper dofs coupled to a lower one)
    a, b, s = 0, 0, 0
    for i in range(lo, hi):
        v = perm[i]
        if mark[v] == lower_mark:
            perm[lo + a] = v
            a += 1
            continue
        touches = False
        for p in range(indptr[v], indptr[v + 1]):
            if mark[indices[p]] == lower_mark:
                touches = True
                break
        if touches:
            sep[s] = v
            s += 1
        else:
            upper[b] = v
            b += 1
    for i in range(b):
        perm[lo + a + i] = upper[i]
    for i in range(s):
        perm[lo + a + b + i] = sep[i]
    return a, b


@njit(cache=True)
def _dissect(indptr, indices, X, dofs, leaf):
    """Nested dissection of dofs (an explicit stack, depth first, upper half first: the order is filled from
    its end, each separator after the two halves it divides)."""
    n = dofs.shape[0]
    perm = dofs.copy()
    out = np.empty(n, np.int64)
    mark = np.full(X.shape[0], -1, np.int64)
    buf = np.empty(n, np.float64)
    sep, upper = np.empty(n, np.int64), np.empty(n, np.int64)
    stack_lo = np.empty(n + 1, np.int64)
    stack_hi = np.empty(n + 1, np.int64)
    top, stamp = n, 0
    stack_lo[0], stack_hi[0] = 0, n
    depth = 1
    while depth > 0:
        depth -= 1
        lo, hi = stack_lo[depth], stack_hi[depth]
        if hi - lo == 0:
            continue
        n_lower, n_upper = -1, -1
        if hi - lo > leaf:
            n_lower, n_upper = _split(indptr, indices, X, perm, lo, hi, stamp, mark, buf, sep, upper)
            stamp += 1
        if n_lower < 0:   # a leaf (or a set that cannot be split): in coordinate order
            _sort_leaf(X, perm, lo, hi)
            for i in range(hi - lo):
                out[top - (hi - lo) + i] = perm[lo + i]
            top -= hi - lo
            continue
        n_sep = hi - lo - n_lower - n_upper
        for i in range(n_sep):
            out[top - n_sep + i] = perm[lo + n_lower + n_upper + i]
        top -= n_sep
        stack_lo[depth], stack_hi[depth] = lo, lo + n_lower               # the lower half: done last
        stack_lo[depth + 1], stack_hi[depth + 1] = lo + n_lower, lo + n_lower + n_upper
        depth += 2
    return out


def _dissect_numpy(indptr, indices, X, dofs, leaf):
    """:func:`_dissect` with numpy, level by level: every set of a level is split at once, the same split.

    Each dof gets one digit per level, 0 (lower half), 1 (upper half) or 2 (separator), and the order is the
    lexicographic order of the digits: the layout [lower, upper, separator] that the kernel writes. Ties are
    the dofs of one leaf, ordered by coordinates then index (the kernel's insertion sort), or of one
    separator, in their order in ``dofs`` (the kernel's partitions are stable).
    """
    n, d = dofs.shape[0], X.shape[1]
    digits = []                                     # one array of n digits per level
    tie_x = np.zeros((n, d))                        # a leaf's dofs: their coordinates, then their index
    tie_i = np.arange(n)                            # a separator's dofs: their place in ``dofs``
    pos = np.arange(n)                              # the dofs still to split, by set, each set in dofs' order
    label = np.zeros(n, dtype=np.int64)             # their set
    in_set = np.full(X.shape[0], -1, dtype=np.int64)
    while pos.size:
        starts = np.flatnonzero(np.r_[True, label[1:] != label[:-1]])
        sizes = np.diff(np.r_[starts, pos.size])
        set_of = np.repeat(np.arange(starts.size), sizes)
        v = dofs[pos]
        Xv = X[v]
        extent = np.column_stack([np.maximum.reduceat(Xv[:, k], starts) - np.minimum.reduceat(Xv[:, k], starts)
                                  for k in range(d)])
        axis = np.argmax(extent, axis=1)            # the first longest side, as the kernel's strict >
        splits = (sizes > leaf) & (extent[np.arange(starts.size), axis] > 0.0)
        value = Xv[np.arange(pos.size), axis[set_of]]
        ranked = np.lexsort((value, set_of))        # each set's values in ascending order
        sv = value[ranked]
        half = starts + sizes // 2
        odd = sizes % 2 == 1
        median = np.where(odd, sv[half], (sv[np.maximum(half - 1, starts)] + sv[half]) / 2)
        lower = value < median[set_of]
        none_below = np.bincount(set_of, weights=lower, minlength=starts.size) == 0
        lower |= none_below[set_of] & (value <= median[set_of])   # at least half at the minimum: split there
        n_lower = np.bincount(set_of, weights=lower, minlength=starts.size)
        splits &= n_lower < sizes
        split_dof = splits[set_of]
        # separator: an upper dof of a split set coupled in K to a lower dof of the same set
        in_set[v] = -1
        in_set[v[split_dof & lower]] = set_of[split_dof & lower]
        upper = np.flatnonzero(split_dof & ~lower)
        rows = v[upper]
        counts = indptr[rows + 1] - indptr[rows]
        entry = np.repeat(indptr[rows] - np.cumsum(np.r_[0, counts[:-1]]), counts) + np.arange(counts.sum())
        hit = in_set[indices[entry]] == np.repeat(set_of[upper], counts)
        touches = np.zeros(pos.size, dtype=bool)
        touches[upper] = np.bincount(np.repeat(np.arange(upper.size), counts), weights=hit,
                                     minlength=upper.size) > 0
        in_set[v] = -1
        digit = np.zeros(n, dtype=np.int8)
        digit[pos] = np.where(split_dof & ~lower, np.where(touches, 2, 1), 0)   # a leaf's dofs: 0, then the ties
        digits.append(digit)
        leaf_dof = ~split_dof
        tie_x[pos[leaf_dof]] = Xv[leaf_dof]
        tie_i[pos[leaf_dof]] = v[leaf_dof]
        go_on = split_dof & ~touches                # the halves, each set in dofs' order (a stable sort)
        pos, label = pos[go_on], 2 * set_of[go_on] + (~lower[go_on])
        keep = np.argsort(label, kind="stable")
        pos, label = pos[keep], label[keep]
    keys = [tie_i] + [tie_x[:, k] for k in reversed(range(d))] + digits[::-1]
    return dofs[np.lexsort(keys)]
