"""OSQP's termination test and OSQP's rho rule inside the compiled segment: Python runs only when the segment ends.

Under OSQP's settings the loop tests every 25 iterations and OSQP's rule reads
a record every 50; each such iteration in Python (its record, the residuals,
the test, the rule, the history) costs some 100-200 us on a small QP, where
OSQP's 25 iterations and its check cost about 40 us.  A segment given
``check=`` (:mod:`admmkit.loop.segments`) runs up to ``count`` iterations and
makes, at every tested iteration, the decision the loop would make there
*when it is "go on"*:

- OSQP's residuals of the iterate (``residual_kernel._residuals``,
  the very kernel the Python test calls, so the same bits) and the test of
  :class:`admmkit.problems.qp.termination.QPTermination` on them: primal,
  dual and gap tests at eps_abs, eps_rel; when they fail, the candidates
  (I1), (I2) of the infeasibility tests (the kernels of ``infeasibility_kernel``
  on the same dy and dx);
- for ``polish_stop.PolishingTermination``, also its
  gate (the test at ``gate`` x the tolerances, from the iteration of its next try on);
- the loop's divergence and stall tests, conservatively: every entry of
  r = A x - z finite and below 1e100 in size, and one above 1e-100 (so a QP
  without constraint rows is tested in Python);
- at an iteration OSQP's rule reads (:class:`admmkit.policies.OSQPRule` with
  OSQP's normalisation, ``osqp_relative_residuals`` of this QP), its estimate,
  clamped, and its tolerance test, with Python's operations.

Only where all of these say "go on" does the kernel go on; anywhere else
(the test would pass, a candidate certificate, the gate, a new rho, a
number out of range) the segment ends with that iteration as the read one,
and the loop's Python runs its own test and rule on the same numbers, which
then decide exactly as before.  So the iterates, the iteration count, the
status, rho's path and the factorisations are those of the Python loop; the
history rows of the iterations tested in the kernel carry NaN norms (no
norm was computed there), as every unread row of a lean history does.
"""
from __future__ import annotations

import math

import numpy as np

from admmkit.kernels import compiled_now, kernel
from admmkit.linalg.compiled import csc_matvec

from .infeasibility_kernel import dual_candidate, dual_update_change, primal_candidate
from .residual_kernel import _residuals
from .segment import (NO_ACCELERATION, _xz_kkt, accelerator_arguments, accelerator_step, run_segment,
                      segment_state)
# (numba caches these kernels, which compile the segment's and the accelerators' in, by this file's stamp only:
# see the note in segment.py; 29 November: Anderson's kernels without reference counts, its Gram pass over padded
# columns)

#: ``False``: the segment makes no test and no rule update in its kernel (it ends at every iteration the loop reads,
#: as before this module): the switch the tests compare the two with
TESTS_IN_KERNEL = True
#: OSQPRule's floor in the ratio's denominators (``termination.osqp_relative_residuals``: DIVISION_TOL of OSQP)
RATIO_TOL = 1e-30
#: the size of an entry of r = A x - z from which the loop's own divergence test decides
DIVERGENCE_CEILING = 1e100
#: the size below which every entry of r must be for the loop's own stall test to decide
STALL_FLOOR = 1e-100


@kernel(cache=True)
def go_on(test, m, eps_abs, eps_rel, gap, infeasibility, eps_prim_inf, eps_dual_inf, gate, polish_from, k,
          interval, tolerance, rho_min, rho_max, rho, alpha,
          Pp, Pi, Pd, Ap, Ai, Ad, q, lo, up, w, E, D, c, cinv,
          Pu_p, Pu_i, Pu_d, qu, Au_p, Au_i, Au_d, lu, uu, scaled,
          x_rel, x_rel_prev, z, z_prev, lam, Ax, Axb, dy, dx, cert_m, cert_n, held):
    """Whether the loop would go on after the iteration ``k`` whose outputs are (x_rel, z, lam, Ax): True only
    when the test (if ``test``: k is a tested iteration) and OSQP's rule (if ``interval`` > 0 and k is one it reads) certainly leave the
    run and rho as they are (see the module docstring); False: the loop's Python must look.  ``held`` (12 numbers)
    keeps the residuals' 11 values computed here and, last, k (-1 when none were computed at k)."""
    held[11] = -1.0
    worst = 0.0
    for i in range(m):                                              # the loop's divergence and stall tests
        r = abs(Ax[i] - z[i])
        if not (r < DIVERGENCE_CEILING) or not np.isfinite(lam[i]):
            return False
        worst = max(worst, r)
    if not worst > STALL_FLOOR:                     # (no constraint row: the stall test reads x's change, Python's)
        return False
    for j in range(x_rel.shape[0]):
        if not np.isfinite(x_rel[j]):
            return False
    csc_matvec(Ap, Ai, Ad, x_rel, Axb)                                # A x of OSQP's x, as the Python test takes it
    (primal, primal_scale, dual, dual_scale, quad, lin, sup,
     s_primal, s_primal_scale, s_dual, s_dual_scale) = _residuals(Pp, Pi, Pd, Ap, Ai, Ad, q, lo, up, w, E, D,
                                                                   x_rel, z, lam, Axb)
    values = (primal, primal_scale, dual, dual_scale, quad, lin, sup, s_primal, s_primal_scale, s_dual,
              s_dual_scale)
    for v in values:
        if not np.isfinite(v):
            return False
    for i in range(11):                                 # for the Python test at this iteration, if it comes to look
        held[i] = values[i]
    held[11] = k
    if test:
        dual, dual_scale = cinv * dual, cinv * dual_scale
        gap_value, gap_scale = cinv * (quad + lin + sup), cinv * max(abs(quad), abs(lin), abs(sup))
        primal_ok = m == 0 or primal <= eps_abs + eps_rel * primal_scale
        dual_ok = dual <= eps_abs + eps_rel * dual_scale
        gap_ok = not gap or abs(gap_value) <= eps_abs + eps_rel * gap_scale
        if primal_ok and dual_ok and gap_ok:
            return False                                            # solved (or the row test): Python's to say
        if gate > 0.0 and k >= polish_from:                         # PolishingTermination's gate
            a, r = gate * eps_abs, gate * eps_rel
            if (primal <= a + r * primal_scale and dual <= a + r * dual_scale
                    and (not gap or abs(gap_value) <= a + r * gap_scale)):
                return False
        if infeasibility and not (primal_ok and dual_ok):
            dual_update_change(rho, alpha, Ax, z if alpha == 1.0 else z_prev, z, w, E, c, dy)
            if not primal_ok and primal_candidate(Au_p, Au_i, Au_d, lu, uu, dy, eps_prim_inf, cert_m):
                return False
            if not dual_ok:
                for j in range(x_rel.shape[0]):
                    dx[j] = x_rel[j] - x_rel_prev[j]
                    if scaled:
                        dx[j] = D[j] * dx[j]
                if dual_candidate(Pu_p, Pu_i, Pu_d, qu, Au_p, Au_i, Au_d, lu, uu, dx, eps_dual_inf, cert_n):
                    return False
    if interval > 0 and (k + 1) % interval == 0:                   # OSQPRule.update with OSQP's normalisation
        r_rel = s_primal / (s_primal_scale + RATIO_TOL)
        s_rel = s_dual / (s_dual_scale + RATIO_TOL)
        if s_rel > 0:
            est = rho * math.sqrt(r_rel / s_rel)
        elif r_rel > 0:
            return False                                            # an infinite estimate: rho_max, Python's
        else:
            return True                                             # NaN: rho kept
        est = min(max(est, rho_min), rho_max)
        if est > tolerance * rho or est < rho / tolerance:
            return False                                            # a new rho: the loop's event
    return True


@kernel(cache=True)
def segment_tested(count, first, every, knows_test, m, eps_abs, eps_rel, gap, infeasibility, eps_prim_inf, eps_dual_inf,
                   gate, polish_from, interval, tolerance, rho_min, rho_max, rho, alpha,
                   Pp, Pi, Pd, Ap, Ai, Ad, lo, up, w, E, D, c, cinv,
                   Pu_p, Pu_i, Pu_d, qu, Au_p, Au_i, Au_d, lu, uu, scaled, Axb, dy, dx, cert_m, cert_n,
                   a, sigma, Lp, Li, Lx, Dinv, perm, Rinv, q, free, w_free,
                   x, x_prev, x_rel, x_rel_prev, z, lam, Ax, rhs, sol, work, z_last, lam_last, Ax_last, hat,
                   accelerate, aw, safeguard, regularization, s_z, s_lam, ist, before, F_prev, G_prev, plain, dF, dG,
                   gram, g, acc, a_rhs, chol, gamma, held):
    """Up to ``count`` iterations from iteration ``first`` (``segment._xz_kkt``'s), each
    tested one ((k + 1) % every == 0) and each one OSQP's rule reads (``interval`` > 0) decided by :func:`go_on`;
    ``knows_test``: the run's test is one :func:`go_on` makes (else the segment ends at the first tested iteration);
    returns (done, kept): the segment ends after a "Python must look" iteration, at ``count``, or before a
    non-finite step (kept False: the last iteration's inputs are not kept).  With ``accelerate`` (a mode of
    ``segment.accelerator_step``), the accelerator's steps (``_xz_kkt``'s arguments from ``aw`` on) follow the
    iterations, a decided one's too where it goes on (rho unchanged: the loop would take that step next)."""
    done = 0
    while done < count:
        k = first + done
        chunk = every - k % every                                   # up to the next tested iteration ...
        if interval > 0:
            chunk = min(chunk, interval - k % interval)             # ... or the next one the rule reads
        chunk = min(chunk, count - done)
        got = _xz_kkt(chunk, rho, alpha, a, sigma, Lp, Li, Lx, Dinv, perm, Rinv, q, lo, up, free, w_free,
                      x, x_prev, x_rel, x_rel_prev, z, lam, Ax, rhs, sol, work, True, z_last, lam_last, Ax_last, hat,
                      accelerate, aw, safeguard, regularization, s_z, s_lam, ist, before, F_prev, G_prev, plain, dF,
                      dG, gram, g, acc, a_rhs, chol, gamma)
        done += got
        if got < chunk:
            return done, False
        if done == count:
            return done, True
        j = first + done - 1
        tested = (j + 1) % every == 0
        if tested and not knows_test:
            return done, True                                       # a test the kernel does not know: Python's
        if not go_on(tested, m, eps_abs, eps_rel, gap, infeasibility, eps_prim_inf, eps_dual_inf, gate,
                     polish_from, j, interval, tolerance, rho_min, rho_max, rho, alpha,
                     Pp, Pi, Pd, Ap, Ai, Ad, q, lo, up, w, E, D, c, cinv,
                     Pu_p, Pu_i, Pu_d, qu, Au_p, Au_i, Au_d, lu, uu, scaled,
                     x_rel, x_rel_prev, z, z_last, lam, Ax, Axb, dy, dx, cert_m, cert_n, held):
            return done, True
        if accelerate != NO_ACCELERATION:       # go on at this rho: the step from the state iteration j started from
            accelerator_step(accelerate, rho, aw, safeguard, regularization, z_last, lam_last, z, lam, ist, before,
                             F_prev, G_prev, plain, dF, dG, gram, g, acc, a_rhs, chol, gamma)
    return done, True


def test_parameters(qp, stop) -> tuple:
    """(knows_test, eps_abs, eps_rel, gap, infeasibility, eps_prim_inf, eps_dual_inf, gate, polish_from) of the
    run's stopping rule for :func:`segment_tested`: known when the rule says it is (``kernel_test``: this QP's
    ``QPTermination`` or ``PolishingTermination`` itself; a subclass may test more, and the segment then ends at a
    tested iteration)."""
    known = getattr(stop, "kernel_test", None)
    numbers = known(qp) if callable(known) and TESTS_IN_KERNEL else None
    if numbers is None:
        return False, 1.0, 1.0, True, True, 1.0, 1.0, 0.0, 0
    eps_abs, eps_rel, gap, infeasibility, eps_prim_inf, eps_dual_inf, gate, polish_from = numbers
    return (True, float(eps_abs), float(eps_rel), bool(gap), bool(infeasibility), float(eps_prim_inf),
            float(eps_dual_inf), float(gate), int(polish_from))


def rule_parameters(qp, policy) -> tuple | None:
    """(interval, tolerance, rho_min, rho_max) when ``policy`` is :class:`admmkit.policies.OSQPRule` itself with OSQP's
    normalisation of this QP (``termination.osqp_relative_residuals``; :func:`segment_tested` then makes its update),
    else None."""
    from admmkit.policies import OSQPRule
    residuals = getattr(policy, "residuals", None)
    if (TESTS_IN_KERNEL and type(policy) is OSQPRule and getattr(type(residuals), "osqp_ratios", False) is True
            and residuals.qp is qp):
        return policy.interval, policy.tolerance, policy.rho_min, policy.rho_max
    return None


def _data(qp) -> tuple:
    """The QP's arrays :func:`go_on` reads (the ones the Python test and rule read) and its work vectors, made once
    per QP."""
    held = qp.__dict__.get("_segment_checks")
    if held is None:
        ones_m, ones_n = qp._ones
        w = ones_m if qp.w is None else qp.w
        if qp.scaled:
            E, D, c, cinv = qp.scaling.E, qp.scaling.D, float(qp.scaling.c), 1.0 / qp.scaling.c
        else:
            E, D, c, cinv = ones_m, ones_n, 1.0, 1.0
        Ps, As, P, A = qp.Ps, qp.As, qp.P, qp.A
        held = qp._segment_checks = (
            Ps.indptr, Ps.indices, Ps.data, As.indptr, As.indices, As.data, qp.ls, qp.us, w, E, D, c, cinv,
            P.indptr, P.indices, P.data, qp.q, A.indptr, A.indices, A.data, qp.l, qp.u, bool(qp.scaled),
            np.empty(qp.m), np.empty(qp.m), np.empty(qp.n), np.empty(qp.m), np.empty(qp.n))
    return held


def checked_segment(qp, x, z, lam, Ax, rho: float, alpha: float, order: str, count: int, read: bool, accel, check):
    """``QP.segment`` given ``check`` (:class:`admmkit.loop.segments.SegmentChecks`): up to ``count`` iterations from
    iteration ``check.first``, the tests and OSQP's rule made in the kernel where they go on; (x, z, lam, Ax, done,
    last) as ``run_segment(..., read=True)`` returns them, ``last`` the read iteration's inputs (None when a
    non-finite step ended the segment early).  ``accel``: the accelerator's ``kernel_state()`` (Anderson's or
    restarted fast ADMM's), whose steps the kernel takes (:func:`segment_tested`).  Where the kernel does not apply
    (not order "xz" with the KKT form on qdldl, compiled code not chosen),
    :func:`admmkit.problems.qp.segment.run_segment` up to the next iteration the loop reads."""
    first = check.first
    factors = qp._solver.ldl(rho) if order == "xz" and qp.xstep == "kkt" and compiled_now() else None
    if factors is None or not read:
        upto = min(first + check.every - 1 - first % check.every, check.policy.unchanged_until(first))
        return run_segment(qp, x, z, lam, Ax, rho, alpha, order, min(count, upto - first + 1), read, accel)
    test = test_parameters(qp, check.stop)
    rule = rule_parameters(qp, check.policy)
    if rule is None:                    # another rule: the segment ends at the first iteration it reads
        count = min(count, check.policy.unchanged_until(first) - first + 1)
        rule = (0, 1.0, 0.0, math.inf)
    (x, z, lam, Ax, x_rel, x_prev, x_rel_prev), (rhs, sol, work) = segment_state(qp, x, z, lam, Ax)
    a = qp.x_relaxation
    m = z.shape[0]
    kept = (np.empty(m), np.empty(m), np.empty(m), np.empty(m))
    accelerator = accelerator_arguments(accel, m)
    held = np.full(12, -1.0)             # held[11] = -1: no residuals computed at the read iteration (yet)
    qp._kernel_residuals = None
    done, whole = segment_tested(count, first, check.every, *test[:1], m, *test[1:], *rule, float(rho),
                                 float(alpha), *_data(qp), a, qp.sigma, *factors, qp.inverse_penalty(rho), qp.qs,
                                 qp._free, qp._w_free_over_penalty, x, x_prev, x_rel, x_rel_prev, z, lam, Ax,
                                 rhs, sol, work, *kept, *accelerator, held)
    if done:
        qp.after_segment(x, x_prev, x_rel, x_rel_prev, done)
    data_w = _data(qp)[8]                   # the weights the kernel read are the QP's (a held copy: not asked)
    if whole and done and held[11] == first + done - 1 and data_w is (qp._ones[0] if qp.w is None else qp.w):
        qp._kernel_residuals = (x_rel, z, lam, held[:11].tolist())     # the read iteration's, made in the kernel
    last = (x_prev, *kept[:3], kept[3] if alpha != 1.0 else None) if whole and done else None
    return x, z, lam, Ax, done, last
