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
"""
from __future__ import annotations

import numpy as np

from .policy import Policy
from .record import IterationRecord


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


def policy_step(policy: Policy, rec: IterationRecord) -> float:
    """rho_{k+1} from the record of iteration k (eq. (17) for SADMM)."""
    return policy.update(rec)
