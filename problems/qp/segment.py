"""The QP's compiled segment: OSQP's iteration, ``count`` times in one call (:mod:`admmkit.loop.segments`).

Order "xz" with the KKT form of the x-step factorised by qdldl (OSQP's
machinery: :func:`admmkit.problems.qp.solve_qp`'s default), with
over-relaxation alpha and OSQP's relaxed x (Q4).  One iteration, as
:meth:`admmkit.problems.qp.QP.x_step`, ``apply_A``,
``z_step`` and :mod:`admmkit.loop.steps` compute it::

    [x~; v] = K(rho)^-1 b,  b = [sigma x^k - q; z^k - lam^k / rho]   (Q1), free rows: z - w lam / 1e-6 (Q5)
    x^{k+1} = a x~ + (1 - a) x^k                                 (Q4, a = x_relaxation)
    z~      = b_z + R^-1 v   (= A x~, read off the solve as OSQP does, no product)   (Q6)
    Ax_hat  = alpha z~ + (1 - alpha) z^k
    z^{k+1} = clip(Ax_hat + lam^k / rho, l, u)                   (Q2)
    lam^{k+1} = lam^k + rho (Ax_hat - z^{k+1})

with the same floating-point operations in the same order, so the iterates
are the Python loop's bit for bit (tests/problems/test_qp_segment.py).  The
kernel stops before an iteration whose right-hand side or solution is not
finite; the loop's Python iteration then meets the failure where it would
have anyway.
"""
from __future__ import annotations

import numpy as np

from admmkit.loop import anderson_kernel, fast_kernel
from admmkit.loop.anderson_kernel import CLOCK, anderson_reads_state, anderson_update
from admmkit.loop.fast_kernel import SKIP, fast_reads_state, fast_update
# numba compiles the accelerators' kernels into this file's and caches them by this file's stamp only: a change of
# theirs must touch this file too, or a warm cache runs their old code (fast ADMM's give_up, 29 November: new slots
# of its integer state that the old code does not read)
from admmkit.kernels import AVAILABLE, KERNELS, all_finite, compiled_now, kernel
from admmkit.linalg.compiled import ldl_solve

#: the size nnz(P) + nnz(A) + n + m from which a QP solve runs compiled code under ``compiled="auto"`` (the
#: default): below it, importing numba and loading (or, on a fresh install, compiling) the kernels costs more
#: than the whole solve, which then runs numpy/scipy and the kernels as Python, with the same iterates
#: (docs/qp.md, "First call", says how the threshold was measured)
COMPILED_MIN_SIZE = 1000


def compiled_pays(n: int, m: int, nnz: int) -> bool:
    """Whether compiled kernels pay for a QP of n variables, m constraints and nnz stored entries of P and A: numba
    is installed and either the QP is large enough to pay for numba's import and the kernels' load or compile, or
    this process has them already (a compiled solve ran: compiled code then costs nothing more)."""
    return AVAILABLE and (nnz + n + m >= COMPILED_MIN_SIZE or kernels_loaded())


def kernels_loaded() -> bool:
    """Whether this process has the QP's compiled segment (and with it numba and the other kernels) loaded: the
    plain segment ``_xz_kkt`` asked first (the segment that tests in its kernel, segment_checks', calls it)."""
    if _loaded(_xz_kkt):
        return True
    return any(_loaded(k) for k in KERNELS.get(_CHECKS_MODULE, ()))


#: the module of the segment that tests in its kernel (its kernels are listed in ``admmkit.kernels.KERNELS``)
_CHECKS_MODULE = __name__.rsplit(".", 1)[0] + ".segment_checks"


def _loaded(k) -> bool:
    """Whether kernel ``k`` has a compiled specialisation in this process."""
    return k._dispatcher is not None and bool(k._dispatcher.overloads)


def choose_compiled(setting, qp) -> tuple[bool, bool]:
    """(compiled segment, compiled helper passes) for the setting ``compiled`` of a solve of ``qp``: True both,
    "auto" both as :func:`compiled_pays` says, False no segment (every iteration in Python) and the helper passes
    (scaling, residuals, certificates) as :func:`compiled_pays` says."""
    pays = compiled_pays(qp.n, qp.m, qp.P.nnz + qp.A.nnz)
    if setting is True:
        return AVAILABLE, AVAILABLE
    return (pays if setting == "auto" else False), pays


#: the accelerator modes of the kernels' integer ``accelerate``: none, Anderson's steps, restarted fast ADMM's
NO_ACCELERATION, ANDERSON, FAST = 0, anderson_kernel.MODE, fast_kernel.MODE


@kernel(**anderson_kernel.OPTIONS)
def reads_state(mode, ist):
    """Whether the accelerator ``mode``'s next step reads the state the iteration starts from (fast ADMM's but in a
    back-off, :func:`admmkit.loop.fast_kernel.fast_reads_state`; Anderson's when
    :func:`admmkit.loop.anderson_kernel.anderson_reads_state` says so)."""
    return (mode == FAST and fast_reads_state(ist)) or (mode == ANDERSON and anderson_reads_state(ist))


@kernel(**anderson_kernel.OPTIONS)
def plain_step(mode, ist):
    """The count of an accelerator's step that does not read the state (the iterate itself goes on): Anderson's
    clock between its steps, fast ADMM's plain steps left in a back-off."""
    if mode == FAST:
        ist[SKIP] -= 1
    else:
        ist[CLOCK] += 1


@kernel(**anderson_kernel.OPTIONS)
def accelerator_step(mode, rho, w, safeguard, regularization, s_z, s_lam, z, lam, ist, before, F_prev, G_prev, plain,
                     dF, dG, gram, g, acc, a_rhs, chol, gamma):
    """The accelerator's step on (z, lam), in place, from the state (``s_z``, ``s_lam``) the iteration started from:
    Anderson's (``mode`` ANDERSON, the arguments of :func:`admmkit.loop.anderson_kernel.anderson_update`) or
    restarted fast ADMM's (FAST: ``safeguard`` is its eta, ``ist``, ``before``, ``F_prev`` its ist, ac, f_prev of
    :func:`admmkit.loop.fast_kernel.fast_update`; the other arrays are not read)."""
    if mode == ANDERSON:
        anderson_update(rho, w, safeguard, regularization, s_z, s_lam, z, lam, z, lam, ist, before, F_prev, G_prev,
                        plain, dF, dG, gram, g, acc, a_rhs, chol, gamma)
    elif mode == FAST:
        fast_update(rho, w, safeguard, s_z, s_lam, z, lam, z, lam, ist, before, F_prev)


@kernel(cache=True)
def _xz_kkt(count, rho, alpha, a, sigma, Lp, Li, Lx, Dinv, perm, Rinv, q, lo, up, free, w_free,
            x, x_prev, x_rel, x_rel_prev, z, lam, Ax, rhs, sol, work, keep_last, z_last, lam_last, Ax_last, hat,
            accelerate, w, safeguard, regularization, s_z, s_lam, ist, before, F_prev, G_prev, plain, dF, dG,
            gram, g, acc, a_rhs, chol, gamma):
    """``count`` iterations on the state arrays (x, x_prev, x_rel, x_rel_prev, z, lam, Ax), in place;
    returns the number done (fewer if a step would meet a non-finite number).  With ``keep_last``, the
    last iteration's z, lam, A x in (its x is then x_prev) and its relaxed vector (``hat``) are kept.
    With ``accelerate`` (a mode: ANDERSON, FAST; NO_ACCELERATION 0), the accelerator's step (that of
    :func:`accelerator_step`, its kernel called directly) follows every iteration but a kept last one (the loop
    takes that one's), on the state (z, lam), the one it started from kept in ``s_z``, ``s_lam`` where the step
    reads it; between the steps of Anderson's interval, and in fast ADMM's back-off, it only counts the
    iteration."""
    n, m = x.shape[0], z.shape[0]
    relax_x, relax = a != 1.0, alpha != 1.0
    for it in range(count):
        last = keep_last and it == count - 1
        step = accelerate != NO_ACCELERATION and not last
        reads = step and reads_state(accelerate, ist)
        if reads:                                                               # s = (z^k, lam^k)
            for i in range(m):
                s_z[i], s_lam[i] = z[i], lam[i]
        for i in range(n):
            rhs[i] = sigma * x_rel[i] - q[i]                                    # (Q1)
        for i in range(m):
            rhs[n + i] = z[i] - lam[i] / rho
        for f in range(free.shape[0]):                                          # (Q5)
            rhs[n + free[f]] = z[free[f]] - w_free[f] * lam[free[f]]
        if not all_finite(rhs, 0, n + m):
            return it
        ldl_solve(Lp, Li, Lx, Dinv, perm, rhs, work, sol)
        if not all_finite(sol, 0, n + m):
            return it
        if last:
            for i in range(m):
                z_last[i], lam_last[i], Ax_last[i] = z[i], lam[i], Ax[i]
        for i in range(n):
            x_prev[i] = x[i]
            x[i] = sol[i]
            if relax_x:                                                         # (Q4)
                x_rel_prev[i] = x_rel[i]
                x_rel[i] = a * sol[i] + (1.0 - a) * x_rel_prev[i]
            else:
                x_rel_prev[i] = x_rel[i]
                x_rel[i] = sol[i]
        for i in range(m):                                                      # z~ = rhs + R^-1 v (Q6)
            Ax[i] = rhs[n + i] + Rinv[i] * sol[n + i]
        for i in range(m):
            h = alpha * Ax[i] + (1.0 - alpha) * z[i] if relax else Ax[i]
            if last:
                hat[i] = h
            v = h + lam[i] / rho                                                # (Q2)
            if v < lo[i]:
                v = lo[i]
            if v > up[i]:
                v = up[i]
            lam[i] = lam[i] + rho * (h - v)
            z[i] = v
        if reads and accelerate == FAST:                                        # (A4)-(A6), its own arrays only
            fast_update(rho, w, safeguard, s_z, s_lam, z, lam, z, lam, ist, before, F_prev)
        elif reads:                                                 # (A2)-(A3), the kernel itself (no dispatch)
            anderson_update(rho, w, safeguard, regularization, s_z, s_lam, z, lam, z, lam, ist, before, F_prev,
                            G_prev, plain, dF, dG, gram, g, acc, a_rhs, chol, gamma)
        elif step:                                      # Anderson between steps, fast ADMM backing off: plain
            plain_step(accelerate, ist)
    return count


@kernel(cache=True)
def _kkt_solve(rho, sigma, Lp, Li, Lx, Dinv, perm, q, free, w_free, xp, z, lam, rhs, work, sol):
    """One x-step (Q1), (Q5) in the KKT form into ``sol``, as :meth:`QP.x_step` computes it; False (nothing
    to trust in ``sol``) if the right-hand side or the solution is not finite."""
    n, m = xp.shape[0], z.shape[0]
    for i in range(n):
        rhs[i] = sigma * xp[i] - q[i]
    for i in range(m):
        rhs[n + i] = z[i] - lam[i] / rho
    for f in range(free.shape[0]):
        rhs[n + free[f]] = z[free[f]] - w_free[f] * lam[free[f]]
    if not all_finite(rhs, 0, n + m):
        return False
    ldl_solve(Lp, Li, Lx, Dinv, perm, rhs, work, sol)
    return all_finite(sol, 0, n + m)


def kkt_x_step(qp, xp, z, lam, rho: float):
    """The KKT x-step's (solution [x~; v], right-hand side) in one compiled call with qdldl's factors (the same bits as qdldl's solve), or
    None where it does not apply (compiled code not chosen, :func:`admmkit.kernels.compiled_now`; another
    backend; a non-finite number: the Python path then meets it as it would anyway)."""
    if not compiled_now():
        return None
    factors = qp._solver.ldl(rho)
    if factors is None:
        return None
    size = qp.n + qp.m
    rhs, work, sol = np.empty(size), np.empty(size), np.empty(size)
    if not _kkt_solve(float(rho), qp.sigma, *factors, qp.qs, qp._free, qp._w_free_over_penalty,
                      np.asarray(xp, dtype=np.float64), np.asarray(z, dtype=np.float64),
                      np.asarray(lam, dtype=np.float64), rhs, work, sol):
        return None
    qp._solver.solves += 1
    return sol, rhs


def _scratch(qp):
    """The kernel's work vectors (rhs, sol, work) of length n + m, made once per QP (nothing reads them after)."""
    held = qp.__dict__.get("_segment_scratch")
    if held is None:
        size = qp.n + qp.m
        held = qp._segment_scratch = (np.empty(size), np.empty(size), np.empty(size))
    return held


def segment_state(qp, x, z, lam, Ax):
    """The arrays a segment iterates on, as new float64 arrays: (x, z, lam, Ax, x_rel, x_prev, x_rel_prev), x_rel
    the QP's relaxed x (Q4) where it keeps one, and its work vectors (rhs, sol, work), made once per QP."""
    x, z, lam, Ax = (np.array(v, dtype=np.float64) for v in (x, z, lam, Ax))
    a = qp.x_relaxation
    x_rel = np.array(qp._x_rel if a != 1.0 and qp._x_rel is not None else x, dtype=np.float64)
    return (x, z, lam, Ax, x_rel, np.empty_like(x), np.empty_like(x)), _scratch(qp)


#: placeholders for the kernel's accelerator arrays when it takes no steps (one compiled signature)
_NO_W, _NO_INTS, _NO_MATRIX = np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros((0, 0))
_NO_ACCELERATOR = (NO_ACCELERATION, _NO_W, 1.0, 0.0, _NO_W, _NO_W, _NO_INTS, _NO_W, _NO_W, _NO_W, _NO_W, _NO_MATRIX,
                   _NO_MATRIX, _NO_MATRIX, _NO_W, _NO_MATRIX, _NO_W, _NO_MATRIX, _NO_W)


def accelerator_arguments(accel, m: int) -> tuple:
    """The kernels' accelerator arguments (``accelerate`` to ``gamma``) for an accelerator's ``kernel_state()``
    (weights, a parameter, a second one, arrays with their ``mode``; None: no steps), with s_z, s_lam of length m."""
    if accel is None:
        return _NO_ACCELERATOR
    w, first, second, arrays = accel
    return (arrays.mode, w, first, second, np.empty(m), np.empty(m), *arrays.args())


def run_segment(qp, x, z, lam, Ax, rho: float, alpha: float, order: str, count: int, read: bool = False,
                accel=None):
    """``count`` iterations of ``qp`` from (x, z, lam, Ax) in one compiled call, or None where the kernel does
    not apply (order "zx", the reduced x-step, a backend other than qdldl, compiled code not chosen).

    Returns (x, z, lam, Ax, done) in new arrays; the QP's relaxed-x bookkeeping (Q4) follows, and its
    solve counter grows by ``done``.  ``read``: the last iteration is one the loop reads
    (:mod:`admmkit.loop.segments`); a sixth item, (x, z, lam, A x) it started from and its relaxed vector (None
    when alpha = 1), is returned, None unless all ``count`` iterations were done.  ``accel``: the accelerator's
    ``kernel_state()`` (Anderson's or restarted fast ADMM's; :mod:`admmkit.loop.segments`), whose steps follow the
    iterations (not a read last one's).
    (With the loop's tests and OSQP's rule in the kernel: :func:`admmkit.problems.qp.segment_checks.checked_segment`.)
    """
    if order != "xz" or qp.xstep != "kkt" or not compiled_now():
        return None
    factors = qp._solver.ldl(rho)
    if factors is None:
        return None
    (x, z, lam, Ax, x_rel, x_prev, x_rel_prev), (rhs, sol, work) = segment_state(qp, x, z, lam, Ax)
    a = qp.x_relaxation
    m = z.shape[0]
    kept = (np.empty(m), np.empty(m), np.empty(m), np.empty(m)) if read else (work[:0],) * 4
    accelerator = accelerator_arguments(accel, m)
    done = _xz_kkt(count, float(rho), float(alpha), a, qp.sigma, *factors, qp.inverse_penalty(rho),
                   qp.qs, qp.ls, qp.us, qp._free, qp._w_free_over_penalty,
                   x, x_prev, x_rel, x_rel_prev, z, lam, Ax, rhs, sol, work, read, *kept, *accelerator)
    if done:
        qp.after_segment(x, x_prev, x_rel, x_rel_prev, done)
    if not read:
        return x, z, lam, Ax, done
    last = (x_prev, *kept[:3], kept[3] if alpha != 1.0 else None) if done == count else None
    return x, z, lam, Ax, done, last
