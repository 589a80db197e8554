"""The approximate minimum degree ordering (AMD), compiled (numba): the order qdldl factorises in.

:func:`amd_order` is a line-by-line port of SuiteSparse AMD's ``amd_order``
with its default controls (dense rows: degree > 10 sqrt(n), at least 16;
aggressive absorption on), as bundled with qdldl-python 0.1.9 (AMD 2.x,
``amd_order -> amd_aat, amd_1 -> amd_2 -> amd_postorder, amd_post_tree``;
``amd_preprocess`` when the columns are unsorted or hold duplicates).  Given
the pattern of A it orders A + A' (the diagonal ignored), so a caller may
pass the upper triangle, the lower one or both; qdldl passes the *upper*
triangle of its matrix, and with that input the permutation is qdldl's own,
entry for entry (tests/admmkit/test_amd.py checks it on the KKT matrices of
the Maros-Meszaros problems and on random patterns).  Different inputs with
the same A + A' (the full matrix, say) can break ties differently: the order
is as good, not the same.

The method (Amestoy, Davis and Duff): eliminate, one supervariable at a time,
the one of least *approximate* external degree, an upper bound of the true
degree got from the quotient graph of elements and variables without forming
the fill; merge variables of equal pattern into supervariables (found by
hashing), absorb elements whose pattern the new one covers (aggressive
absorption), set rows denser than the threshold aside and order them last,
then postorder the assembly tree.

- P. R. Amestoy, T. A. Davis, I. S. Duff, "An approximate minimum degree
  ordering algorithm", SIAM J. Matrix Anal. Appl. 17(4):886-905, 1996.
- P. R. Amestoy, T. A. Davis, I. S. Duff, "Algorithm 837: AMD, an approximate
  minimum degree ordering algorithm", ACM Trans. Math. Softw. 30(3):381-388,
  2004.

License of the code ported here (SuiteSparse AMD, BSD 3-clause)::

    AMD, Copyright (c), 1996-2015, Timothy A. Davis,
    Patrick R. Amestoy, and Iain S. Duff.  All Rights Reserved.

    Redistribution and use in source and binary forms, with or without
    modification, are permitted provided that the following conditions are met:
        * Redistributions of source code must retain the above copyright
          notice, this list of conditions and the following disclaimer.
        * Redistributions in binary form must reproduce the above copyright
          notice, this list of conditions and the following disclaimer in the
          documentation and/or other materials provided with the distribution.
        * Neither the name of the organizations to which the authors are
          affiliated, nor the names of its contributors may be used to endorse
          or promote products derived from this software without specific prior
          written permission.

    THIS SOFTWARE IS PROVIDED BY THE COPYRIGHT HOLDERS AND CONTRIBUTORS "AS IS"
    AND ANY EXPRESS OR IMPLIED WARRANTIES, INCLUDING, BUT NOT LIMITED TO, THE
    IMPLIED WARRANTIES OF MERCHANTABILITY AND FITNESS FOR A PARTICULAR PURPOSE
    ARE DISCLAIMED. IN NO EVENT SHALL THE COPYRIGHT HOLDERS BE LIABLE FOR ANY
    DIRECT, INDIRECT, INCIDENTAL, SPECIAL, EXEMPLARY, OR CONSEQUENTIAL DAMAGES
    (INCLUDING, BUT NOT LIMITED TO, PROCUREMENT OF SUBSTITUTE GOODS OR
    SERVICES; LOSS OF USE, DATA, OR PROFITS; OR BUSINESS INTERRUPTION) HOWEVER
    CAUSED AND ON ANY THEORY OF LIABILITY, WHETHER IN CONTRACT, STRICT
    LIABILITY, OR TORT (INCLUDING NEGLIGENCE OR OTHERWISE) ARISING IN ANY WAY
    OUT OF THE USE OF THIS SOFTWARE, EVEN IF ADVISED OF THE POSSIBILITY OF SUCH
    DAMAGE.

The names of the C code are kept (Pe, Iw, Len, Nv, Elen, Degree, W, Head,
Next, Last, wflg, ...) so that the port can be read against it; EMPTY is -1
and FLIP(i) = -i - 2 as there.  The subscripts of the minimum degree loop
are cast to unsigned (``_u``): numba then skips its negative-index test,
which made the loop 1.5x faster (PRIMAL3's KKT matrix, one run: 13.5 -> 8.5
ms, where SuiteSparse's C compiled with gcc -O3 took 8.5 ms).

Why this port: qdldl's wheel builds AMD without optimisation (its setup.py
passes -O3 to the Python wrapper only), so its ordering costs more than its
factorisation.  Measured (one run, OMP_NUM_THREADS=1, best of 7, the 2-core
machine under load from other jobs, so +-20%) on the upper-triangle KKT
matrices [[P + sigma I, A'], [A, -I/rho]] of the 78 Maros-Meszaros problems
with n + m <= 3000: ``qdldl.Solver(U, upper=True)`` against this module's
:func:`amd_order` followed by :func:`admmkit.linalg.ldl.ldl_factor` in that
order (the same permutation; ldl_factor divides by D where qdldl multiplies by
1 / D, so its factor differs in the last bits; the QP's held KKT factor,
``admmkit.problems.qp.kkt_factor``, redoes qdldl's own phases and its bits).  qdldl's time over
ours: median 1.23, maximum 2.87 (PRIMAL3: 46.0 ms against 16.1 ms; also
PRIMAL4, n + m = 3053: 36.7 against 12.7; QSCSD6 3.2 against 2.0); about 1
(0.84-1.3 from run to run) where the factorisation dominates (CVXQP3_M:
11.6 against 13.3 ms in that run; the numeric factorisations alone, in
another run: qdldl's update 10.5 ms, ldl's 9.6 ms); 0.13-0.4 on the 16 problems qdldl does in under 0.1 ms (HS118:
0.04 against 0.11 ms: the Python-side checks of the two calls); 208 ms
against 123 ms over all 78.  The same AMD C source compiled with gcc -O3
orders PRIMAL3 in 13.4 ms in that run (this port: 12.7 ms; this port's time
over the C's, median 1.3 over the 78).  The kernels' first compilation, in
a fresh install, takes about 18 s on that machine (numba's cache keeps them;
a later process loads them in about 0.02 s each).
"""
from __future__ import annotations

import math

import numpy as np

from admmkit.kernels import AVAILABLE, _u, njit

EMPTY = -1
#: AMD's default controls, as qdldl's (rows of degree above DENSE * sqrt(n), at least 16, are dense; aggressive
#: absorption on)
DENSE = 10.0
AGGRESSIVE = True


def amd_order(indptr, indices, n: int) -> np.ndarray:
    """The AMD permutation of the pattern of A + A' (A given in CSC: ``indptr``, ``indices``; n x n).

    Returns ``perm`` (int64, length n): row/column ``perm[k]`` of A is the k-th
    pivot, i.e. factorise ``A[perm][:, perm]``.  Pass the upper triangle (with
    or without the diagonal) to get qdldl's order exactly (qdldl hands AMD its
    upper triangle).  Unsorted columns and duplicate entries are accepted (AMD
    then orders the sorted pattern of A', as ``amd_preprocess`` does).
    """
    if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)) or n < 0:
        raise ValueError(f"n must be an integer >= 0, got {n!r}")
    n = int(n)
    indptr, indices = np.asarray(indptr), np.asarray(indices)
    for name, a in (("indptr", indptr), ("indices", indices)):
        if a.ndim != 1 or not (a.size == 0 or np.issubdtype(a.dtype, np.integer)):
            raise ValueError(f"{name} must be a 1-d integer array, got dtype {a.dtype} and shape {a.shape}")
    if indptr.shape != (n + 1,):
        raise ValueError(f"indptr must have length n + 1 = {n + 1}, got {indptr.size}")
    if n == 0:
        return np.empty(0, np.int64)
    if not AVAILABLE:   # pragma: no cover - numba is a dependency
        raise RuntimeError("admmkit.linalg.amd needs numba")
    Ap = np.ascontiguousarray(indptr, dtype=np.int64)
    Ai = np.ascontiguousarray(indices, dtype=np.int64)
    status = _valid(n, Ap, Ai)
    if status == INVALID_POINTERS:
        raise ValueError(f"indptr must start at 0, not decrease and end at most at len(indices) = {Ai.size}")
    if status == INVALID_INDICES:
        raise ValueError(f"indices must lie in 0..n-1 = {n - 1}")
    return _amd_order(n, Ap, Ai, status == JUMBLED)[0]


#: what _valid answers, as amd_valid's AMD_OK and AMD_OK_BUT_JUMBLED, and its AMD_INVALID told apart
OK, JUMBLED, INVALID_POINTERS, INVALID_INDICES = 0, 1, -1, -2


@njit(cache=True)
def _valid(n, Ap, Ai):
    """amd_valid: OK, JUMBLED (a column with unsorted or repeated row indices), or what makes (Ap, Ai) invalid."""
    if Ap[0] != 0 or Ap[n] > Ai.shape[0]:
        return INVALID_POINTERS
    for j in range(n):
        if Ap[j] > Ap[j + 1]:
            return INVALID_POINTERS
    status = OK
    for j in range(n):
        ilast = EMPTY
        for p in range(Ap[j], Ap[j + 1]):
            i = Ai[p]
            if i < 0 or i >= n:
                return INVALID_INDICES
            if i <= ilast:
                status = JUMBLED
            ilast = i
    return status


def _amd_order(n, Ap, Ai, jumbled):
    """amd_order on a valid pattern: sort (amd_preprocess) if ``jumbled``, count A + A' (amd_aat), allocate and
    build A + A' (amd_1), order (amd_2).

    Returns the permutation and the number of garbage collections of AMD's workspace (Info[AMD_NCMPA]).  The
    steps are called from here, not from one kernel: numba optimises a kernel again inside every kernel that
    calls it, and the nesting tripled the first compilation (about 45 s on a loaded 2-core machine).
    """
    if jumbled:
        Ap, Ai = _preprocess(n, Ap, Ai)
    Len, nzaat = _aat(n, Ap, Ai)
    iwlen = int(nzaat) + int(nzaat) // 5 + n    # the matrix and elbow room (amd_order's slen less amd_1's 6n)
    Pe, Iw, pfree = _amd_1(n, Ap, Ai, Len, iwlen)
    dense = min(n, max(16, int(DENSE * math.sqrt(n))))
    return _amd_2(n, Pe, Iw, Len, iwlen, pfree, dense, AGGRESSIVE)


@njit(cache=True)
def _preprocess(n, Ap, Ai):
    """amd_preprocess: the pattern of A' with sorted columns and no duplicates (R = row form of A)."""
    W = np.zeros(n, np.int64)
    Flag = np.full(n, EMPTY, np.int64)
    for j in range(n):
        for p in range(Ap[j], Ap[j + 1]):
            i = Ai[p]
            if Flag[i] != j:
                W[i] += 1
                Flag[i] = j
    Rp = np.zeros(n + 1, np.int64)
    for i in range(n):
        Rp[i + 1] = Rp[i] + W[i]
    for i in range(n):
        W[i] = Rp[i]
        Flag[i] = EMPTY
    Ri = np.empty(Rp[n], np.int64)
    for j in range(n):
        for p in range(Ap[j], Ap[j + 1]):
            i = Ai[p]
            if Flag[i] != j:
                Ri[W[i]] = j
                W[i] += 1
                Flag[i] = j
    return Rp, Ri


@njit(cache=True)
def _aat(n, Ap, Ai):
    """amd_aat: Len[j], the off-diagonal nonzeros of column j of A + A', and their sum."""
    Len = np.zeros(n, np.int64)
    Tp = np.empty(n, np.int64)
    for k in range(n):
        p = Ap[k]
        p2 = Ap[k + 1]
        while p < p2:                            # the strictly upper part of column k
            j = Ai[p]
            if j < k:
                Len[j] += 1
                Len[k] += 1
                p += 1
            elif j == k:
                p += 1
                break
            else:
                break
            pj2 = Ap[j + 1]                      # column j's lower part, up to row k
            pj = Tp[j]
            while pj < pj2:
                i = Ai[pj]
                if i < k:
                    Len[i] += 1
                    Len[j] += 1
                    pj += 1
                elif i == k:
                    pj += 1
                    break
                else:
                    break
            Tp[j] = pj
        Tp[k] = p
    for j in range(n):                           # the lower entries left without a mirror
        for pj in range(Tp[j], Ap[j + 1]):
            i = Ai[pj]
            Len[i] += 1
            Len[j] += 1
    return Len, Len.sum()


@njit(cache=True)
def _amd_1(n, Ap, Ai, Len, iwlen):
    """amd_1: the adjacency lists of A + A' (Pe, Iw[:pfree]) in AMD's order of construction; returns Pe, Iw, pfree."""
    Pe = np.empty(n, np.int64)
    Sp = np.empty(n, np.int64)
    Tp = np.empty(n, np.int64)
    Iw = np.empty(iwlen, np.int64)
    pfree = 0
    for j in range(n):
        Pe[j] = pfree
        Sp[j] = pfree
        pfree += Len[j]
    for k in range(n):
        p = Ap[k]
        p2 = Ap[k + 1]
        while p < p2:
            j = Ai[p]
            if j < k:                            # A(j, k) strictly upper
                Iw[Sp[j]] = k
                Sp[j] += 1
                Iw[Sp[k]] = j
                Sp[k] += 1
                p += 1
            elif j == k:
                p += 1
                break
            else:
                break
            pj2 = Ap[j + 1]
            pj = Tp[j]
            while pj < pj2:
                i = Ai[pj]
                if i < k:                        # A(i, j) only in the lower part
                    Iw[Sp[i]] = j
                    Sp[i] += 1
                    Iw[Sp[j]] = i
                    Sp[j] += 1
                    pj += 1
                elif i == k:
                    pj += 1
                    break
                else:
                    break
            Tp[j] = pj
        Tp[k] = p
    for j in range(n):
        for pj in range(Tp[j], Ap[j + 1]):
            i = Ai[pj]
            Iw[Sp[i]] = j
            Sp[i] += 1
            Iw[Sp[j]] = i
            Sp[j] += 1
    return Pe, Iw, pfree


@njit(cache=True)
def _flip(i):
    """FLIP: negation about -1 (marks an index; FLIP(FLIP(i)) = i, FLIP(EMPTY) = EMPTY)."""
    return -i - 2


@njit(cache=True)
def _clear_flag(wflg, wbig, W, n):
    """clear_flag: reset W (keeping its zeros) when wflg would overflow; W[0..n-1] < wflg afterwards."""
    if wflg < 2 or wflg >= wbig:
        for x in range(n):
            if W[_u(x)] != 0:
                W[_u(x)] = 1
        wflg = 2
    return wflg


@njit(cache=True)
def _unlink(i, Head, Next, Last, Degree):
    """Remove variable i from its degree list."""
    ilast = Last[_u(i)]
    inext = Next[_u(i)]
    if inext != EMPTY:
        Last[_u(inext)] = ilast
    if ilast != EMPTY:
        Next[_u(ilast)] = inext
    else:
        Head[Degree[_u(i)]] = inext


@njit(cache=True)
def _compress(n, Pe, Iw, Len, pme1, pfree):
    """Garbage collection of Iw: pack every live list to the front, then the element under construction
    (Iw[pme1..pfree-1]); return its new start and the new pfree."""
    for j in range(n):                           # the first entry of each list saved in Pe, replaced by FLIP(j)
        pn = Pe[_u(j)]
        if pn >= 0:
            Pe[_u(j)] = Iw[_u(pn)]
            Iw[_u(pn)] = _flip(j)
    psrc = 0
    pdst = 0
    pend = pme1 - 1
    while psrc <= pend:
        j = _flip(Iw[_u(psrc)])
        psrc += 1
        if j >= 0:
            Iw[_u(pdst)] = Pe[_u(j)]
            Pe[_u(j)] = pdst
            pdst += 1
            for _ in range(Len[_u(j)] - 1):
                Iw[_u(pdst)] = Iw[_u(psrc)]
                pdst += 1
                psrc += 1
    p1 = pdst
    for psrc in range(pme1, pfree):
        Iw[_u(pdst)] = Iw[_u(psrc)]
        pdst += 1
    return p1, pdst


@njit(cache=True)
def _amd_2(n, Pe, Iw, Len, iwlen, pfree, dense, aggressive):
    """amd_2: the minimum degree loop on the quotient graph, then the postorder; returns the permutation and
    the number of garbage collections of Iw."""
    Nv = np.ones(n, np.int64)
    Next = np.full(n, EMPTY, np.int64)
    Last = np.full(n, EMPTY, np.int64)
    Head = np.full(n, EMPTY, np.int64)
    Elen = np.zeros(n, np.int64)
    Degree = Len.copy()
    W = np.ones(n, np.int64)
    wbig = np.iinfo(np.int64).max - n
    wflg = _clear_flag(0, wbig, W, n)
    mindeg = 0
    ncmpa = 0
    nel = 0
    lemax = 0
    me = EMPTY

    # degree lists; empty rows eliminated at once, dense ones set aside (ordered last)
    for i in range(n):
        deg = Degree[_u(i)]
        if deg == 0:
            Elen[_u(i)] = _flip(1)
            nel += 1
            Pe[_u(i)] = EMPTY
            W[_u(i)] = 0
        elif deg > dense:
            Nv[_u(i)] = 0
            Elen[_u(i)] = EMPTY
            nel += 1
            Pe[_u(i)] = EMPTY
        else:
            inext = Head[_u(deg)]
            if inext != EMPTY:
                Last[_u(inext)] = i
            Next[_u(i)] = inext
            Head[_u(deg)] = i

    while nel < n:
        # the pivot: a supervariable of minimum approximate degree
        deg = mindeg
        while deg < n:
            me = Head[_u(deg)]
            if me != EMPTY:
                break
            deg += 1
        mindeg = deg
        inext = Next[_u(me)]
        if inext != EMPTY:
            Last[_u(inext)] = EMPTY
        Head[_u(deg)] = inext
        elenme = Elen[_u(me)]
        nvpiv = Nv[_u(me)]
        nel += nvpiv

        # the new element Lme: the variables of me and of the elements adjacent to me
        Nv[_u(me)] = -nvpiv
        degme = 0
        if elenme == 0:                          # built in place
            pme1 = Pe[_u(me)]
            pme2 = pme1 - 1
            for p in range(pme1, pme1 + Len[_u(me)]):
                i = Iw[_u(p)]
                nvi = Nv[_u(i)]
                if nvi > 0:
                    degme += nvi
                    Nv[_u(i)] = -nvi
                    pme2 += 1
                    Iw[_u(pme2)] = i
                    _unlink(i, Head, Next, Last, Degree)
        else:                                    # built in the free space Iw[pfree...]
            p = Pe[_u(me)]
            pme1 = pfree
            slenme = Len[_u(me)] - elenme
            for knt1 in range(1, elenme + 2):
                if knt1 > elenme:
                    e = me
                    pj = p
                    ln = slenme
                else:
                    e = Iw[_u(p)]
                    p += 1
                    pj = Pe[_u(e)]
                    ln = Len[_u(e)]
                for knt2 in range(1, ln + 1):
                    i = Iw[_u(pj)]
                    pj += 1
                    nvi = Nv[_u(i)]
                    if nvi > 0:
                        if pfree >= iwlen:       # no room: compress Iw
                            Pe[_u(me)] = p
                            Len[_u(me)] -= knt1
                            if Len[_u(me)] == 0:
                                Pe[_u(me)] = EMPTY
                            Pe[_u(e)] = pj
                            Len[_u(e)] = ln - knt2
                            if Len[_u(e)] == 0:
                                Pe[_u(e)] = EMPTY
                            ncmpa += 1
                            pme1, pfree = _compress(n, Pe, Iw, Len, pme1, pfree)
                            pj = Pe[_u(e)]
                            p = Pe[_u(me)]
                        degme += nvi
                        Nv[_u(i)] = -nvi
                        Iw[_u(pfree)] = i
                        pfree += 1
                        _unlink(i, Head, Next, Last, Degree)
                if e != me:                      # e is absorbed into me
                    Pe[_u(e)] = _flip(me)
                    W[_u(e)] = 0
            pme2 = pfree - 1
        Degree[_u(me)] = degme
        Pe[_u(me)] = pme1
        Len[_u(me)] = pme2 - pme1 + 1
        Elen[_u(me)] = _flip(nvpiv + degme)
        wflg = _clear_flag(wflg, wbig, W, n)

        # scan 1: W[e] - wflg = |Le \ Lme| for every element e adjacent to a variable of Lme
        for pme in range(pme1, pme2 + 1):
            i = Iw[_u(pme)]
            eln = Elen[_u(i)]
            if eln > 0:
                nvi = -Nv[_u(i)]
                wnvi = wflg - nvi
                for p in range(Pe[_u(i)], Pe[_u(i)] + eln):
                    e = Iw[_u(p)]
                    we = W[_u(e)]
                    if we >= wflg:
                        we -= nvi
                    elif we != 0:
                        we = Degree[_u(e)] + wnvi
                    W[_u(e)] = we

        # scan 2: approximate degrees, element absorption, mass elimination, hash buckets
        for pme in range(pme1, pme2 + 1):
            i = Iw[_u(pme)]
            p1 = Pe[_u(i)]
            p2 = p1 + Elen[_u(i)] - 1
            pn = p1
            hash = 0
            deg = 0
            for p in range(p1, p2 + 1):
                e = Iw[_u(p)]
                we = W[_u(e)]
                if we != 0:
                    dext = we - wflg
                    if dext > 0 or not aggressive:
                        deg += dext
                        Iw[_u(pn)] = e
                        pn += 1
                        hash += e
                    else:                        # |Le \ Lme| = 0: absorb e into me
                        Pe[_u(e)] = _flip(me)
                        W[_u(e)] = 0
            Elen[_u(i)] = pn - p1 + 1
            p3 = pn
            p4 = p1 + Len[_u(i)]
            for p in range(p2 + 1, p4):
                j = Iw[_u(p)]
                nvj = Nv[_u(j)]
                if nvj > 0:
                    deg += nvj
                    Iw[_u(pn)] = j
                    pn += 1
                    hash += j
            if Elen[_u(i)] == 1 and p3 == pn:        # mass elimination: i only touches me
                Pe[_u(i)] = _flip(me)
                nvi = -Nv[_u(i)]
                degme -= nvi
                nvpiv += nvi
                nel += nvi
                Nv[_u(i)] = 0
                Elen[_u(i)] = EMPTY
            else:
                Degree[_u(i)] = min(Degree[_u(i)], deg)
                Iw[_u(pn)] = Iw[_u(p3)]                  # me goes first in i's list
                Iw[_u(p3)] = Iw[_u(p1)]
                Iw[_u(p1)] = me
                Len[_u(i)] = pn - p1 + 1
                hash = hash % n
                j = Head[_u(hash)]
                if j <= EMPTY:                   # degree list empty: the bucket's head is FLIP(Head)
                    Next[_u(i)] = _flip(j)
                    Head[_u(hash)] = _flip(i)
                else:                            # else Last[Head[hash]] is the bucket's head
                    Next[_u(i)] = Last[_u(j)]
                    Last[_u(j)] = i
                Last[_u(i)] = hash
        Degree[_u(me)] = degme
        lemax = max(lemax, degme)
        wflg += lemax
        wflg = _clear_flag(wflg, wbig, W, n)

        # supervariable detection: within each hash bucket, merge variables of identical pattern
        for pme in range(pme1, pme2 + 1):
            i = Iw[_u(pme)]
            if Nv[_u(i)] < 0:
                hash = Last[_u(i)]
                j = Head[_u(hash)]
                if j == EMPTY:
                    i = EMPTY
                elif j < EMPTY:
                    i = _flip(j)
                    Head[_u(hash)] = EMPTY
                else:
                    i = Last[_u(j)]
                    Last[_u(j)] = EMPTY
                while i != EMPTY and Next[_u(i)] != EMPTY:
                    ln = Len[_u(i)]
                    eln = Elen[_u(i)]
                    for p in range(Pe[_u(i)] + 1, Pe[_u(i)] + ln):
                        W[Iw[_u(p)]] = wflg
                    jlast = i
                    j = Next[_u(i)]
                    while j != EMPTY:
                        ok = Len[_u(j)] == ln and Elen[_u(j)] == eln
                        p = Pe[_u(j)] + 1
                        while ok and p <= Pe[_u(j)] + ln - 1:
                            if W[Iw[_u(p)]] != wflg:
                                ok = False
                            p += 1
                        if ok:                   # j is absorbed into i
                            Pe[_u(j)] = _flip(i)
                            Nv[_u(i)] += Nv[_u(j)]
                            Nv[_u(j)] = 0
                            Elen[_u(j)] = EMPTY
                            j = Next[_u(j)]
                            Next[_u(jlast)] = j
                        else:
                            jlast = j
                            j = Next[_u(j)]
                    wflg += 1
                    i = Next[_u(i)]

        # restore the degree lists; drop the non-principal variables from Lme
        p = pme1
        nleft = n - nel
        for pme in range(pme1, pme2 + 1):
            i = Iw[_u(pme)]
            nvi = -Nv[_u(i)]
            if nvi > 0:
                Nv[_u(i)] = nvi
                deg = min(Degree[_u(i)] + degme - nvi, nleft - nvi)
                inext = Head[_u(deg)]
                if inext != EMPTY:
                    Last[_u(inext)] = i
                Next[_u(i)] = inext
                Last[_u(i)] = EMPTY
                Head[_u(deg)] = i
                mindeg = min(mindeg, deg)
                Degree[_u(i)] = deg
                Iw[_u(p)] = i
                p += 1
        Nv[_u(me)] = nvpiv
        Len[_u(me)] = p - pme1
        if Len[_u(me)] == 0:                         # a root of the assembly tree
            Pe[_u(me)] = EMPTY
            W[_u(me)] = 0
        if elenme != 0:
            pfree = p

    return _permutation(n, Pe, Nv, Elen, W, Head, Next, Last), ncmpa


@njit(cache=True)
def _permutation(n, Pe, Nv, Elen, W, Head, Next, Last):
    """The end of amd_2: the assembly tree (paths of absorbed variables compressed), its postorder, then each
    element's pivots with its absorbed variables just before it and the dense rows last."""
    for i in range(n):
        Pe[i] = _flip(Pe[i])
        Elen[i] = _flip(Elen[i])
    for i in range(n):
        if Nv[i] == 0:
            j = Pe[i]
            if j == EMPTY:                       # a dense row: no parent
                continue
            while Nv[j] == 0:
                j = Pe[j]
            e = j
            j = i
            while Nv[j] == 0:
                jnext = Pe[j]
                Pe[j] = e
                j = jnext
    _postorder(n, Pe, Nv, Elen, W, Head, Next, Last)
    for k in range(n):
        Head[k] = EMPTY
        Next[k] = EMPTY
    for e in range(n):
        k = W[e]
        if k != EMPTY:
            Head[k] = e
    nel = 0
    for k in range(n):
        e = Head[k]
        if e == EMPTY:
            break
        Next[e] = nel
        nel += Nv[e]
    for i in range(n):
        if Nv[i] == 0:
            e = Pe[i]
            if e != EMPTY:                       # merged into e: just before it
                Next[i] = Next[e]
                Next[e] += 1
            else:                                # dense: last
                Next[i] = nel
                nel += 1
    for i in range(n):
        Last[Next[i]] = i
    return Last


@njit(cache=True)
def _postorder(nn, Parent, Nv, Fsize, Order, Child, Sibling, Stack):
    """amd_postorder: Order[e] = the rank of element e in a depth-first postorder of the assembly tree, the
    child of the largest front visited last."""
    for j in range(nn):
        Child[j] = EMPTY
        Sibling[j] = EMPTY
    for j in range(nn - 1, -1, -1):
        if Nv[j] > 0:
            parent = Parent[j]
            if parent != EMPTY:
                Sibling[j] = Child[parent]
                Child[parent] = j
    for i in range(nn):                          # the largest child last in each list
        if Nv[i] > 0 and Child[i] != EMPTY:
            fprev = EMPTY
            maxfrsize = EMPTY
            bigfprev = EMPTY
            bigf = EMPTY
            f = Child[i]
            while f != EMPTY:
                frsize = Fsize[f]
                if frsize >= maxfrsize:
                    maxfrsize = frsize
                    bigfprev = fprev
                    bigf = f
                fprev = f
                f = Sibling[f]
            fnext = Sibling[bigf]
            if fnext != EMPTY:
                if bigfprev == EMPTY:
                    Child[i] = fnext
                else:
                    Sibling[bigfprev] = fnext
                Sibling[bigf] = EMPTY
                Sibling[fprev] = bigf
    for i in range(nn):
        Order[i] = EMPTY
    k = 0
    for i in range(nn):
        if Parent[i] == EMPTY and Nv[i] > 0:
            k = _post_tree(i, k, Child, Sibling, Order, Stack)


@njit(cache=True)
def _post_tree(root, k, Child, Sibling, Order, Stack):
    """amd_post_tree: number the tree under root from k in postorder (an explicit stack); return the next k."""
    head = 0
    Stack[0] = root
    while head >= 0:
        i = Stack[head]
        if Child[i] != EMPTY:                    # push the children, the first on top
            f = Child[i]
            while f != EMPTY:
                head += 1
                f = Sibling[f]
            h = head
            f = Child[i]
            while f != EMPTY:
                Stack[h] = f
                h -= 1
                f = Sibling[f]
            Child[i] = EMPTY
        else:
            head -= 1
            Order[i] = k
            k += 1
    return k
