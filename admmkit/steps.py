"""The steps of one ADMM iteration, each a function with its equation number.

Order "zx" (the paper's ADMM2/SADMM, z-step first), with over-relaxation alpha::

    z^{k+1}   = argmin_z L_rho(x^k, z; lam^k)                       (11)/(14)  z_step
    z_hat     = alpha z^{k+1} + (1 - alpha) (A x^k - c)               relax_z
    x^{k+1}   = argmin_x L_rho(x, z_hat; lam^k)                     (12)/(15)  x_step
    lam^{k+1} = lam^k + rho (A x^{k+1} - z_hat - c)                 (13)/(16)  dual_update
    rho_{k+1} = policy.update(record of iteration k)                (17)       policy_step

Order "xz" (ADMM1, x-step first)::

    x^{k+1}   = argmin_x L_rho(x, z^k; lam^k)                                  x_step
    Ax_hat    = alpha A x^{k+1} + (1 - alpha) (z^k + c)                        relax_Ax
    z^{k+1}   = argmin_z L_rho(Ax_hat, z; lam^k)  (z-step given "A x" = Ax_hat) z_step
    lam^{k+1} = lam^k + rho (Ax_hat - z^{k+1} - c)                             dual_update

With alpha = 1 the relaxation steps are skipped and the iterates are those
of plain ADMM, bit for bit.  docs/math.md derives both relaxations.

:class:`OrderZX` and :class:`OrderXZ` are one iteration of each order, the
steps in sequence; :class:`PolicyStep` is eq. (17).  ``admmkit.solve`` runs them.
"""
from __future__ import annotations

import time

import numpy as np

from .checks import RHO_RANGE, check_steps, rho_in_range
from .result import Status

perf = time.perf_counter


def z_step(problem, Ax: np.ndarray, lam: np.ndarray, rho: float, z: np.ndarray) -> np.ndarray:
    """argmin_z L_rho(x, z; lam) given A x (eq. (11)/(14) in order zx)."""
    return problem.z_step(Ax, lam, rho, z)


def x_step(problem, z: np.ndarray, lam: np.ndarray, rho: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """argmin_x L_rho(x, z; lam) and A x of it (eq. (12)/(15) in order zx)."""
    x_new = problem.x_step(z, lam, rho, x)
    return x_new, problem.apply_A(x_new)


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


class Iteration:
    """One ADMM iteration of a run (the subclass fixes the order), timed step by step.

    Called with (x^k, z^k, lam^k, A x^k, rho_k, take_r), it returns
    (x^{k+1}, z^{k+1}, lam^{k+1}, A x^{k+1}, hat, ||r||_M or None, t): ``hat`` the
    relaxed vector (None when alpha = 1), ||r||_M taken with the dual update when
    ``take_r`` and alpha = 1 (see :func:`dual_update_and_residual`; with alpha != 1 the
    dual update's vector is not the record's r), and ``t`` the perf_counter() after the two steps.
    The first call checks the shapes the steps returned (``admmkit.checks.check_steps``).
    """

    __slots__ = ("problem", "alpha", "relaxed", "c", "c_zero", "norm", "first", "x_seconds", "z_seconds")

    def __init__(self, problem, ctx) -> None:
        self.problem, self.alpha, self.c, self.c_zero, self.norm = problem, ctx.alpha, ctx.c, ctx.c_is_zero, ctx.norm
        self.relaxed, self.first = ctx.alpha != 1.0, True      # take ||r|| only if not relaxed
        self.x_seconds = self.z_seconds = 0.0


class OrderZX(Iteration):
    """Order "zx" (the paper's ADMM2, and SADMM with its rule)."""

    __slots__ = ()

    def __call__(self, x, z, lam, Ax, rho, take_r):
        """One iteration of order zx::

            z^{k+1}   = argmin_z L_rho(x^k, z; lam^k)                   (11)
            z_hat     = alpha z^{k+1} + (1 - alpha) (A x^k - c)          (z^{k+1} if alpha = 1)
            x^{k+1}   = argmin_x L_rho(x, z_hat; lam^k)                 (12)
            lam^{k+1} = lam^k + rho (A x^{k+1} - z_hat - c)             (13)
        """
        problem, c, c_zero = self.problem, self.c, self.c_zero
        t0 = perf()
        z1 = z_step(problem, Ax, lam, rho, z)                                               # (11)
        t1 = perf()
        hat = relax_z(self.alpha, z1, Ax, c, c_zero) if self.relaxed else None
        x1, Ax1 = x_step(problem, z1 if hat is None else hat, lam, rho, x)                  # (12)
        t2 = perf()
        self.z_seconds += t1 - t0
        self.x_seconds += t2 - t1
        if self.first:                  # a step of the wrong shape would broadcast silently: stop at once
            check_steps(problem, x, z, x1, z1, Ax1)
            self.first = False
        z_dual = z1 if hat is None else hat
        if take_r and not self.relaxed:                                                     # (13), ||r|| taken
            lam1, r_norm = dual_update_and_residual(lam, rho, Ax1, z_dual, c, c_zero, self.norm)
        else:
            lam1, r_norm = dual_update(lam, rho, Ax1, z_dual, c, c_zero), None                # (13)
        return x1, z1, lam1, Ax1, hat, r_norm, t2


class OrderXZ(Iteration):
    """Order "xz" (the paper's ADMM1): the x-step first."""

    __slots__ = ()

    def __call__(self, x, z, lam, Ax, rho, take_r):
        """One iteration of order xz::

            x^{k+1}   = argmin_x L_rho(x, z^k; lam^k)
            Ax_hat    = alpha A x^{k+1} + (1 - alpha) (z^k + c)          (A x^{k+1} if alpha = 1)
            z^{k+1}   = argmin_z L_rho(Ax_hat, z; lam^k)   (the z-step given "A x" = Ax_hat)
            lam^{k+1} = lam^k + rho (Ax_hat - z^{k+1} - c)
        """
        problem, c, c_zero = self.problem, self.c, self.c_zero
        t0 = perf()
        x1, Ax1 = x_step(problem, z, lam, rho, x)                                           # x^{k+1}
        t1 = perf()
        hat = relax_Ax(self.alpha, Ax1, z, c, c_zero) if self.relaxed else None
        Ax_dual = Ax1 if hat is None else hat
        z1 = z_step(problem, Ax_dual, lam, rho, z)                                          # z^{k+1}
        t2 = perf()
        self.x_seconds += t1 - t0
        self.z_seconds += t2 - t1
        if self.first:                  # a step of the wrong shape would broadcast silently: stop at once
            check_steps(problem, x, z, x1, z1, Ax1)
            self.first = False
        if take_r and not self.relaxed:                                                     # lam^{k+1}, ||r||
            lam1, r_norm = dual_update_and_residual(lam, rho, Ax_dual, z1, c, c_zero, self.norm)
        else:
            lam1, r_norm = dual_update(lam, rho, Ax_dual, z1, c, c_zero), None                # lam^{k+1}
        return x1, z1, lam1, Ax1, hat, r_norm, t2


ORDER_STEPS = {"zx": OrderZX, "xz": OrderXZ}


class PolicyStep:
    """rho_{k+1} = policy.update(record of iteration k) (eq. (17) for SADMM), timed.

    Called with the record, it returns (rho_{k+1}, None), or (rho_{k+1}, (status, message))
    when the rule returned a rho outside admmkit's range ``admmkit.checks.RHO_RANGE``
    (the run then ends as diverged).
    """

    __slots__ = ("policy", "seconds")

    def __init__(self, policy) -> None:
        self.policy, self.seconds = policy, 0.0

    def __call__(self, rec) -> tuple:
        """(rho_{k+1}, None or the end of the run)."""
        t0 = perf()
        rho_next = self.policy.update(rec)                                                  # (17)
        self.seconds += perf() - t0
        if rho_next is rec.rho or rho_in_range(rho_next):      # the same object: checked already
            return rho_next, None
        return rho_next, (Status.DIVERGED, f"policy {self.policy!r} returned rho={rho_next!r} at iteration "
                                           f"{rec.k + 1}, outside admmkit's rho range [{RHO_RANGE[0]:g}, "
                                           f"{RHO_RANGE[1]:g}]")
