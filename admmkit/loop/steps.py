"""The steps of one ADMM iteration, with their equation numbers.

Order "zx" (the paper's ADMM2/SADMM, z-step first), with over-relaxation alpha::

    z^{k+1}   = argmin_z L_rho(x^k, z; lam^k)                       (11)/(14)  problem.z_step
    z_hat     = alpha z^{k+1} + (1 - alpha) (A x^k - c)               relax_z
    x^{k+1}   = argmin_x L_rho(x, z_hat; lam^k)                     (12)/(15)  problem.x_step
    lam^{k+1} = lam^k + rho (A x^{k+1} - z_hat - c)                 (13)/(16)  dual_update
    rho_{k+1} = policy.update(record of iteration k)                (17)       PolicyStep

Order "xz" (ADMM1, x-step first)::

    x^{k+1}   = argmin_x L_rho(x, z^k; lam^k)                                  problem.x_step
    Ax_hat    = alpha A x^{k+1} + (1 - alpha) (z^k + c)                        relax_Ax
    z^{k+1}   = argmin_z L_rho(Ax_hat, z; lam^k)  (z-step given "A x" = Ax_hat) problem.z_step
    lam^{k+1} = lam^k + rho (Ax_hat - z^{k+1} - c)                             dual_update

With alpha = 1 the relaxation steps are skipped and the iterates are those
of plain ADMM, bit for bit.  docs/math.md derives both relaxations.

:func:`order_zx` and :func:`order_xz` make the iteration of each order for a
run: a function whose docstring is the equations and whose body is the steps
in sequence; :class:`PolicyStep` is eq. (17).  ``admmkit.solve`` runs them.
"""
from __future__ import annotations

import math
import time

import numpy as np

from ..policy import RowPenalties
from .checks import RHO_RANGE, check_step, policy_answer, rho_in_range, row_weights_answer
from .result import Status

perf = time.perf_counter


def relax_z(alpha: float, z_new: np.ndarray, Ax: np.ndarray, c, c_is_zero: bool) -> np.ndarray:
    """Order zx: z_hat = alpha z^{k+1} + (1 - alpha)(A x^k - c)."""
    base = Ax if c_is_zero else Ax - c
    return alpha * z_new + (1.0 - alpha) * base


def relax_Ax(alpha: float, Ax_new: np.ndarray, z: np.ndarray, c, c_is_zero: bool) -> np.ndarray:
    """Order xz: Ax_hat = alpha A x^{k+1} + (1 - alpha)(z^k + c)."""
    base = z if c_is_zero else z + c
    return alpha * Ax_new + (1.0 - alpha) * base


def dual_update(lam: np.ndarray, rho: float, Ax: np.ndarray, z: np.ndarray, c, c_is_zero: bool) -> np.ndarray:
    """lam^{k+1} = lam + rho (Ax - z - c) (eq. (13)/(16)); numpy reuses the temporaries in place."""
    return lam + rho * (Ax - z) if c_is_zero else lam + rho * (Ax - z - c)


def dual_update_and_residual(lam: np.ndarray, rho: float, Ax: np.ndarray, z: np.ndarray, c, c_is_zero: bool,
                             norm) -> tuple[np.ndarray, float]:
    """(lam^{k+1}, ||r||) with r = Ax - z - c: the norm first, then lam + rho r in r's memory.

    The same numbers as :func:`dual_update` and ``norm(r)`` (rho r + lam is lam + rho r
    bit for bit), with one array fewer to allocate and write (float64 arrays; else a new one).
    """
    r = Ax - z if c_is_zero else Ax - z - c
    r_norm = norm(r)
    if type(r) is np.ndarray and r.dtype == np.float64 and lam.dtype == np.float64 and r.shape == lam.shape:
        r *= rho
        r += lam
        return r, r_norm
    return lam + rho * r, r_norm


def order_zx(problem, ctx):
    """One iteration of order zx (the paper's ADMM2, SADMM with its rule), as a function of the run::

        z^{k+1}   = argmin_z L_rho(x^k, z; lam^k)                   (11)
        z_hat     = alpha z^{k+1} + (1 - alpha) (A x^k - c)          (z^{k+1} if alpha = 1)
        x^{k+1}   = argmin_x L_rho(x, z_hat; lam^k)                 (12)
        lam^{k+1} = lam^k + rho (A x^{k+1} - z_hat - c)             (13)

    ``iterate(x, z, lam, Ax, rho, take_r)`` returns (x^{k+1}, z^{k+1}, lam^{k+1}, A x^{k+1}, hat,
    ||r||_M or None, t): ``hat`` the relaxed vector (None when alpha = 1), ||r||_M taken with
    the dual update when ``take_r`` and alpha = 1 (:func:`dual_update_and_residual`; with
    alpha != 1 the dual update's vector is not the record's r), ``t`` the perf_counter()
    after the two steps.  ``iterate.seconds()`` is (x-step, z-step) seconds so far.  The first
    call checks what each step returned as it returns it (``admmkit.loop.checks.check_step``: an array
    of the iterate's shape), before anything uses it.
    """
    alpha, c, c_zero, norm, relaxed = ctx.alpha, ctx.c, ctx.c_is_zero, ctx.norm, ctx.alpha != 1.0
    x_seconds = z_seconds = 0.0
    first = True

    def iterate(x, z, lam, Ax, rho, take_r):
        nonlocal x_seconds, z_seconds, first
        t0 = perf()
        z1 = problem.z_step(Ax, lam, rho, z)                                                # (11)
        if first:                       # a step of the wrong shape would broadcast silently: stop at once
            check_step(problem, "z_step", z1, z.shape, "z")
        t1 = perf()
        hat = relax_z(alpha, z1, Ax, c, c_zero) if relaxed else None
        z_hat = z1 if hat is None else hat
        x1 = problem.x_step(z_hat, lam, rho, x)                                             # (12)
        if first:
            check_step(problem, "x_step", x1, x.shape, "x")
        Ax1 = problem.apply_A(x1)
        if first:
            check_step(problem, "apply_A", Ax1, z.shape, "z")
            first = False
        t2 = perf()
        z_seconds += t1 - t0
        x_seconds += t2 - t1
        if take_r and not relaxed:                                                          # (13), ||r|| taken
            lam1, r_norm = dual_update_and_residual(lam, rho, Ax1, z_hat, c, c_zero, norm)
        else:
            lam1, r_norm = dual_update(lam, rho, Ax1, z_hat, c, c_zero), None                 # (13)
        return x1, z1, lam1, Ax1, hat, r_norm, t2

    iterate.seconds = lambda: (x_seconds, z_seconds)
    return iterate


def order_xz(problem, ctx):
    """One iteration of order xz (the paper's ADMM1: the x-step first), as a function of the run::

        x^{k+1}   = argmin_x L_rho(x, z^k; lam^k)
        Ax_hat    = alpha A x^{k+1} + (1 - alpha) (z^k + c)          (A x^{k+1} if alpha = 1)
        z^{k+1}   = argmin_z L_rho(Ax_hat, z; lam^k)   (the z-step given "A x" = Ax_hat)
        lam^{k+1} = lam^k + rho (Ax_hat - z^{k+1} - c)

    ``iterate`` is called and returns as in :func:`order_zx`.
    """
    alpha, c, c_zero, norm, relaxed = ctx.alpha, ctx.c, ctx.c_is_zero, ctx.norm, ctx.alpha != 1.0
    x_seconds = z_seconds = 0.0
    first = True

    def iterate(x, z, lam, Ax, rho, take_r):
        nonlocal x_seconds, z_seconds, first
        t0 = perf()
        x1 = problem.x_step(z, lam, rho, x)                                                 # x^{k+1}
        if first:                       # a step of the wrong shape would broadcast silently: stop at once
            check_step(problem, "x_step", x1, x.shape, "x")
        Ax1 = problem.apply_A(x1)
        if first:
            check_step(problem, "apply_A", Ax1, z.shape, "z")
        t1 = perf()
        hat = relax_Ax(alpha, Ax1, z, c, c_zero) if relaxed else None
        Ax_hat = Ax1 if hat is None else hat
        z1 = problem.z_step(Ax_hat, lam, rho, z)                                            # z^{k+1}
        if first:
            check_step(problem, "z_step", z1, z.shape, "z")
            first = False
        t2 = perf()
        x_seconds += t1 - t0
        z_seconds += t2 - t1
        if take_r and not relaxed:                                                          # lam^{k+1}, ||r||
            lam1, r_norm = dual_update_and_residual(lam, rho, Ax_hat, z1, c, c_zero, norm)
        else:
            lam1, r_norm = dual_update(lam, rho, Ax_hat, z1, c, c_zero), None                 # lam^{k+1}
        return x1, z1, lam1, Ax1, hat, r_norm, t2

    iterate.seconds = lambda: (x_seconds, z_seconds)
    return iterate


#: the function that makes the iteration of each order (``ITERATIONS[order](problem, ctx)`` is the run's ``iterate``)
ITERATIONS = {"zx": order_zx, "xz": order_xz}


class PolicyStep:
    """rho_{k+1} = policy.update(record of iteration k) (eq. (17) for SADMM), timed.

    :meth:`update` returns (rho_{k+1}, None), or (rho_{k+1}, (status, message))
    when the run ends there as diverged: the rule returned a number outside
    admmkit's range ``admmkit.loop.checks.RHO_RANGE``, or a non-finite one from a
    record with a non-finite norm.  Anything else that is not one number in
    (0, inf) is the rule's error: ``admmkit.loop.checks.policy_answer`` raises,
    naming its class and the value.  A rule with ``per_row = True`` may answer
    :class:`admmkit.RowPenalties`: its weights are checked
    (``admmkit.loop.checks.row_weights_answer``), and where they are the problem's
    current ones the answer is its rho alone.
    """

    __slots__ = ("policy", "seconds", "problem")

    def __init__(self, policy, problem=None) -> None:
        self.policy, self.seconds, self.problem = policy, 0.0, problem

    def update(self, rec, rho: float) -> tuple:
        """(rho_{k+1}, None or the end of the run) from the record of iteration k and rho_k."""
        t0 = perf()
        rho_next = self.policy.update(rec)                                                  # (17)
        self.seconds += perf() - t0
        if rho_next is rho or rho_in_range(rho_next):          # the same object: checked already
            return rho_next, None
        if type(rho_next) is RowPenalties:                     # a penalty per row (RowPenalties)
            return self._rows(rec, rho, rho_next)
        return self._scalar(rec, rho, rho_next)

    def _scalar(self, rec, rho: float, rho_next) -> tuple:
        """(rho_{k+1}, end) for an answer that is not a number in range: diverged, or the rule's error."""
        if _blown_up(rec):                                     # a rule fed inf or NaN: the iterates diverged
            return rho, (Status.DIVERGED, f"non-finite iterate at iteration {rec.k + 1} (policy "
                                          f"{self.policy!r} returned rho={rho_next!r})")
        value = policy_answer(self.policy, rho_next, rec.k)   # TypeError / ValueError unless a number in (0, inf)
        if rho_in_range(value):
            return value, None
        return value, (Status.DIVERGED, f"policy {self.policy!r} returned rho={rho_next!r} at iteration "
                                        f"{rec.k + 1}, outside admmkit's rho range [{RHO_RANGE[0]:g}, "
                                        f"{RHO_RANGE[1]:g}]")

    def _rows(self, rec, rho: float, answer: RowPenalties) -> tuple:
        """(rho_{k+1} or RowPenalties with new weights, end) for a per-row answer, checked."""
        weights = row_weights_answer(self.policy, answer.weights, rec.k, np.shape(rec.z))
        rho_next, final = (answer.rho, None) if rho_in_range(answer.rho) else self._scalar(rec, rho, answer.rho)
        if final is not None or np.array_equal(weights, self.problem.inner_weights()):
            return rho_next, final                             # the rows as they are: a scalar answer
        return RowPenalties(float(rho_next), weights), None


def _blown_up(rec) -> bool:
    """Whether the iterates of the record blew up: ||r||_M or ||x^{k+1}||_X is inf or NaN."""
    return not (math.isfinite(rec.primal_residual) and math.isfinite(rec.x_norm))


class RhoEvent:
    """A change of rho taking effect: the one event the loop raises where rho_{k+1} != rho_k (eq. (17)).

    As OSQP's ``update_rho``, one call chain: ``problem.update_rho(rho_{k+1})``
    redoes what depends on rho (a factorisation, a numeric refactorisation, a
    Galerkin refresh, or nothing: :meth:`admmkit.Problem.update_rho`), and an
    accelerator restarts (its history mixed two penalties).  The problem is
    told only when another iteration follows, so that no refresh is made for
    an iteration that will not run.  ``seconds`` is the time spent in the
    problem's refreshes (``result.timings["rho_update"]``).  A change of the
    penalties per row (:class:`admmkit.RowPenalties`) is the same one event,
    :meth:`change_rows`.
    """

    __slots__ = ("problem", "update_rho", "accel", "seconds")

    def __init__(self, problem, accel=None) -> None:
        # a plug-in written to the protocol without subclassing admmkit.Problem may lack the hook: nothing to redo
        self.problem = problem
        self.update_rho = getattr(problem, "update_rho", None)
        self.accel, self.seconds = accel, 0.0

    def change(self, rho_next, follows: bool = True) -> float:
        """Make rho_{k+1} the run's rho and return it as a float."""
        rho = float(rho_next)
        if follows and self.update_rho is not None:
            t0 = perf()
            self.update_rho(rho)
            self.seconds += perf() - t0
        if self.accel is not None:
            self.accel.reset()
        return rho

    def change_rows(self, penalties, lam: np.ndarray, follows: bool = True) -> tuple[float, np.ndarray]:
        """Make (rho, w) = ``penalties`` the run's penalties: (rho, lam) to go on with.

        ``problem.update_row_weights(rho, w)`` makes M = diag(w) (the problem
        may keep some rows' weights: what it took is ``inner_weights()`` after
        the call) and refreshes its x-step once; the multiplier it reports,
        M lam, is kept: lam_i <- lam_i w_i(before) / w_i(after).  As
        :meth:`change`, nothing is refreshed after the last iteration.
        """
        rho = float(penalties.rho)
        if follows:
            t0 = perf()
            before = np.array(self.problem.inner_weights(), dtype=float)
            self.problem.update_row_weights(rho, penalties.weights)
            lam = lam * (before / self.problem.inner_weights())           # M lam (the QP's y) unchanged
            self.seconds += perf() - t0
        if self.accel is not None:
            self.accel.reset()
        return rho, lam
