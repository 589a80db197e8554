"""The building blocks' compiled segment: which :class:`admmkit.SplitProblem` blocks have a kernel, and the call.

:meth:`admmkit.SplitProblem.segment` (the protocol of :mod:`admmkit.loop.segments`)
runs ``count`` iterations in one call of :func:`admmkit.blocks.split_kernels.iterations`
when every block has a kernel that repeats its numpy bit for bit:

- the x-step (:class:`admmkit.QuadraticXStep`): ``solver="direct"`` with the
  qdldl backend (qdldl's own factors, :meth:`admmkit.QuadraticXStep.kernel_form`), or
  ``solver="diagonal"`` (a division);
- A (:class:`admmkit.LinearMap`): the identity or a sparse matrix (scipy's
  CSR product, repeated), with any diagonal M;
- g: :class:`admmkit.blocks.prox.Zero`, ``Box``, ``NonNegative``, ``UpperBound``,
  ``L1`` and ``Consensus`` (blocks of two or more entries), exactly these
  classes (a subclass may compute otherwise);
- both orders, any alpha, c = 0, a number or a vector.

Everything else gives None and runs in Python: another backend (SuperLU's
or CHOLMOD's solve is not repeatable outside their library), CG or AMG, a
dense A or a LinearOperator (BLAS sums a product in its own order),
``GroupL1`` and ``L2Ball`` (their norms are BLAS dot products),
``PyProximal``, a prox of your own.
"""
from __future__ import annotations

import numpy as np

from . import prox as proxes
from ..loop.segments import AVAILABLE

_EMPTY = np.empty(0)
_EMPTY_INDEX = np.empty(0, dtype=np.int32)
#: the qdldl factors' stand-in for the diagonal solver (same types: one compiled kernel)
_NO_FACTORS = (np.zeros(1, dtype=np.int32), _EMPTY_INDEX, _EMPTY, _EMPTY, np.empty(0, dtype=np.int64))


def _vector(value, p: int) -> np.ndarray:
    """``value`` (a number or an array) broadcast to a contiguous float vector of length p (the same values)."""
    return np.ascontiguousarray(np.broadcast_to(np.asarray(value, dtype=np.float64), (p,)))


def prox_form(g, rho: float, m, p: int):
    """(g_kind, lo, up, thr, blocks, W, wsum) for the kernel's ``prox``, or None when g has no kernel.

    The arrays are those numpy's prox computes with, for t = 1/rho: the
    bounds, the L1 thresholds t w (/ m), Consensus' weights and their sums.
    """
    from . import split_kernels as kern
    kind = type(g)
    lo = up = thr = W = wsum = _EMPTY
    blocks = 1
    try:
        if kind is proxes.Zero:
            code = kern.ZERO
        elif kind is proxes.Box:
            code, lo, up = kern.BOX, _vector(g.lower, p), _vector(g.upper, p)
        elif kind is proxes.NonNegative:
            code, lo = kern.LOWER, _vector(0.0, p)
        elif kind is proxes.UpperBound:
            code, up = kern.UPPER, _vector(g.upper, p)
        elif kind is proxes.L1:
            t = 1.0 / rho                                           # the z-step's t, as SplitProblem.z_step passes it
            code, thr = kern.L1, _vector(t * g.weight if m is None else t * g.weight / m, p)
        elif kind is proxes.Consensus:
            blocks = g.blocks
            if p % blocks or p // blocks < 2:   # a block of one entry: numpy sums the column pairwise
                return None
            code = kern.CONSENSUS
            if m is not None:
                code, W = kern.CONSENSUS_M, np.ascontiguousarray(m, dtype=np.float64)
                wsum = np.reshape(m, (blocks, -1)).sum(axis=0)    # as Consensus.prox sums them
        else:
            return None
    except ValueError:          # bounds that do not broadcast: the Python prox raises its own error
        return None
    return code, lo, up, thr, blocks, W, wsum


def map_form(A):
    """(Ap, Ai, Ad, Tp, Ti, Td, m) of a LinearMap: CSR arrays of A and A' (empty: the identity), the weights
    (empty: M = I); None for a dense A or a LinearOperator."""
    m = _EMPTY if A.m is None else A.m
    if A.kind == "identity":
        return _EMPTY_INDEX, _EMPTY_INDEX, _EMPTY, _EMPTY_INDEX, _EMPTY_INDEX, _EMPTY, m
    if A.kind == "sparse":
        At = A._At
        return A.A.indptr, A.A.indices, A.A.data, At.indptr, At.indices, At.data, m
    return None


def run_segment(problem, x, z, lam, Ax, rho: float, alpha: float, order: str, count: int):
    """``count`` iterations of the SplitProblem ``problem`` in one compiled call: (x, z, lam, Ax, done) in new
    arrays, or None where a block has no kernel (see the module docstring) or numba is missing."""
    if not AVAILABLE:
        return None
    f, A = problem.f, problem.map
    amap = map_form(A)
    if amap is None:
        return None
    p = A.p
    gform = prox_form(problem.g, rho, A.m, p)
    if gform is None:
        return None
    xform = f.kernel_form(rho)
    if xform is None:
        return None
    from .split_kernels import iterations
    direct = xform[0] == "direct"
    factors, denom = (xform[1], _EMPTY) if direct else (_NO_FACTORS, xform[1])
    c = problem.c
    c_zero = np.isscalar(c) and c == 0
    cvec = _EMPTY if c_zero else _vector(c, p)
    x, z, lam, Ax = (np.array(v, dtype=np.float64) for v in (x, z, lam, Ax))
    done, x, z, lam, Ax = iterations(int(count), order == "zx", float(rho), float(alpha), c_zero, cvec, *amap,
                                     f.q, f.sigma, direct, factors, denom, *gform, x, z, lam, Ax)
    f.count_solves(rho, done)
    return x, z, lam, Ax, done
