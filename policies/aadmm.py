"""Spectral penalty selection, AADMM (Xu, Figueiredo & Goldstein 2017).

Z. Xu, M. A. T. Figueiredo, T. Goldstein, "Adaptive ADMM with spectral
penalty parameter selection", AISTATS 2017, section 3 and Algorithm 1; the
authors' MATLAB code (``aadmm_estimate`` in github.com/nightldj/admm_release)
fixes the details used here.

The rule fits the dual functions of f and g by linear gradients, with
curvatures estimated Barzilai-Borwein style from the changes since the last
update (iteration k0):

    Dlam_x = lam_x^{k+1} - lam_x^{k0+1},  Dh = -A (x^{k+1} - x^{k0+1})
    Dlam_z = lam_z^{k+1} - lam_z^{k0+1},  Dg =    z^{k+1} - z^{k0+1}

lam_x and lam_z are the multipliers of the x-step's and z-step's optimality
conditions (``IterationRecord.lam_x``/``lam_z``): one of them is lam^{k+1},
the other the paper's "hat" multiplier of the block updated first.  With
(., .)_M the problem's inner product,

    alpha_SD = (Dlam_x, Dlam_x) / (Dh, Dlam_x),  alpha_MG = (Dh, Dlam_x) / (Dh, Dh)     eq. (26)
    alpha    = alpha_MG if 2 alpha_MG > alpha_SD else alpha_SD - alpha_MG / 2          eq. (27)
    alpha_cor = (Dh, Dlam_x) / (||Dh|| ||Dlam_x||)                                     eq. (28)

and beta, beta_cor likewise from (Dg, Dlam_z).  Then (eq. (29))

    rho_{k+1} = sqrt(alpha beta)  if alpha_cor > eps_cor and beta_cor > eps_cor
              = alpha             if only alpha_cor > eps_cor
              = beta              if only beta_cor > eps_cor
              = rho_k             otherwise.

The correlation test is the authors' (Dh, Dlam_x) > eps_cor ||Dh|| ||Dlam_x|| +
1e-20, which also rejects a zero change.  Literature defaults: eps_cor = 0.2,
an update every ``period`` = 2 iterations (at k = 1, 3, 5, ..., the first one
against the values after iteration 0), and no update from iteration
``freeze`` = 1000 on, which keeps He, Yang & Wang's convergence guarantee
(rho constant after finitely many changes).  ``freeze=None`` never stops
adapting (no guarantee; use :class:`policies.SummableSteps` for one).

Sign conventions: the paper writes the constraint as A u + B v = b with
lam multiplying b - A u - B v; admmkit's A x - z = c and unscaled lam give
the paper's lam = -lam_admmkit, A = A, B = -I, hence the minus sign in Dh.
"""
from __future__ import annotations

import math

import numpy as np

from admmkit import IterationRecord, Policy

from ._checks import check_int, check_number

#: the authors' smallest value considered (``minval``)
MINVAL = 1e-20


def hybrid_step(sd: float, mg: float) -> float:
    """Eq. (27): the minimum-gradient step if 2 mg > sd, else sd - mg/2 (Zhou et al. 2006's hybrid)."""
    return mg if 2.0 * mg > sd else sd - 0.5 * mg


def curvature(d_grad: np.ndarray, d_lam: np.ndarray, dot, eps_cor: float) -> float | None:
    """Spectral step 1/curvature from a gradient change and a multiplier change, or None.

    None when the correlation (d_grad, d_lam) / (||d_grad|| ||d_lam||) is not
    above eps_cor (the pair does not show a usable curvature, e.g. no change).
    """
    prod = dot(d_grad, d_lam)
    norm_grad = math.sqrt(max(dot(d_grad, d_grad), 0.0))
    norm_lam = math.sqrt(max(dot(d_lam, d_lam), 0.0))
    if not prod > eps_cor * norm_grad * norm_lam + MINVAL:
        return None
    return hybrid_step(norm_lam ** 2 / prod, prod / norm_grad ** 2)


class AADMM(Policy):
    """AADMM: rho = sqrt(alpha beta) from spectral (Barzilai-Borwein) curvature estimates of the dual."""

    def __init__(self, eps_cor: float = 0.2, period: int = 2, freeze: int | None = 1000):
        self.eps_cor = check_number("eps_cor", eps_cor, low=0.0, low_open=False, high=1.0)
        self.period = check_int("period", period, low=1)
        self.freeze = None if freeze is None else check_int("freeze", freeze, low=0)

    def reset(self, rho0: float) -> None:
        """Forget the reference point k0."""
        super().reset(rho0)
        self._ref = None          # (A x, z, lam_x, lam_z) at the last update
        self.updates = 0          # iterations where a new rho was computed
        self.last = None          # (alpha, beta) of the last estimate, None where not estimated

    def _snapshot(self, rec: IterationRecord):
        return (np.array(rec.Ax), np.array(rec.z), np.array(rec.lam_x), np.array(rec.lam_z))

    def estimate(self, rec: IterationRecord) -> tuple[float | None, float | None]:
        """(alpha, beta) against the reference point, each None where the correlation test fails."""
        Ax0, z0, lam_x0, lam_z0 = self._ref
        alpha = curvature(-(rec.Ax - Ax0), rec.lam_x - lam_x0, rec.dot, self.eps_cor)
        beta = curvature(rec.z - z0, rec.lam_z - lam_z0, rec.dot, self.eps_cor)
        return alpha, beta

    def update(self, rec: IterationRecord) -> float:
        """Eq. (29) every ``period`` iterations before ``freeze``; rho_k otherwise."""
        if self.freeze is not None and rec.k >= self.freeze:
            return rec.rho
        if self._ref is None:                     # the first iteration: only record
            self._ref = self._snapshot(rec)
            return rec.rho
        if (rec.k + 1) % self.period:
            return rec.rho
        alpha, beta = self.estimate(rec)
        self._ref = self._snapshot(rec)
        self.last = (alpha, beta)
        self.updates += 1
        if alpha is not None and beta is not None:
            rho = math.sqrt(alpha * beta)
        else:
            rho = alpha if alpha is not None else beta
        if rho is None or not (math.isfinite(rho) and rho > 0):   # no usable curvature (or overflow)
            return rec.rho
        return rho
