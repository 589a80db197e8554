"""OSQP's penalty update (Stellato et al. 2020, section 5.2; osqp ``src/auxil.c``).

B. Stellato, G. Banjac, P. Goulart, A. Bemporad, S. Boyd, "OSQP: an operator
splitting solver for quadratic programs", Math. Prog. Comp. 12 (2020) 637-672,
eq. (34) and section 5.2; ``compute_rho_estimate`` and ``adapt_rho`` in OSQP.

Every ``interval`` iterations the rule computes

    rho_est = rho_k sqrt( (||r|| / max(||A x||, ||z||))
                        / (||P x + q + A'y|| / max(||P x||, ||A'y||, ||q||)) )

and adopts it only if it changes rho by more than the factor ``tolerance``:

    rho_{k+1} = rho_est   if rho_est > tolerance rho_k or rho_est < rho_k / tolerance
              = rho_k     otherwise,

then clamps rho_{k+1} to [rho_min, rho_max].  Defaults are OSQP 1.x's
deterministic mode (``adaptive_rho = 1``, iteration based): interval = 50,
tolerance = 5.  OSQP's default in versions before 1.0 set the interval from
the setup time; admmkit never steers rho by wall time.

In admmkit the two ratios are the record's normalised residuals
``primal_residual_rel`` and ``dual_residual_rel`` (2-norms in the problem's
norms, the dual residual Boyd's, normalised by ||A^T M lam|| for order "xz"
or ||lam||_M for "zx").  OSQP's are infinity norms of the QP's KKT
residuals; for a QP, P x + q + A'y is Boyd's dual residual up to the proximal
term, and ||P x + q|| = ||A'y|| at a solution, so the estimate has the same
scale.  Differences from OSQP: a normalised residual is floored at 1e-10
(OSQP adds 1e-10 to the norms, so a zero residual gives a finite estimate);
and OSQP clamps to [1e-6, 1e6] on its scaled data, which admmkit does not
scale, so no clamp is applied unless ``rho_min``/``rho_max`` are given.

A plug-in that knows OSQP's exact normalisation can pass it as
``residuals``, a function of the record returning (r_rel, s_rel); the QP
plug-in has one (``admmkit.problems.qp.termination.osqp_relative_residuals``: OSQP
1.x's ``compute_rho_estimate``, inf-norms in the scaled problem with the
multiplier y = M lam).  With it, ``rho_min=1e-6, rho_max=1e6`` (OSQP's
clamp, applied before the tolerance test as in ``adapt_rho``), interval 50
and tolerance 5, the rule is OSQP 1.x's (``admmkit.problems.qp.solve_qp`` sets it up).  The
difference matters where lam = 0 (no constraint active yet): then
||A^T M lam|| = 0 and the record's dual ratio is infinite, while OSQP's
still has ||P x|| and ||q|| in its denominator.
"""
from __future__ import annotations

import math

from admmkit import IterationRecord, Policy

from ._checks import check_int, check_number

#: floor of a normalised residual in the estimate (OSQP_DIVISION_TOL)
DIVISION_TOL = 1e-10


class OSQPRule(Policy):
    """rho <- rho sqrt(r_rel / s_rel) every ``interval`` iterations, if that changes rho by more than ``tolerance``."""

    requires = ("dual_residual",)

    def __init__(self, interval: int = 50, tolerance: float = 5.0, rho_min: float = 0.0, rho_max: float = math.inf,
                 residuals=None):
        self.interval = check_int("interval", interval, low=1)
        self.tolerance = check_number("tolerance", tolerance, low=1.0, low_open=False)
        self.rho_min = check_number("rho_min", rho_min, low=0.0, low_open=False)
        self.rho_max = float(rho_max) if rho_max == math.inf else check_number("rho_max", rho_max, low=0.0)
        if self.rho_min >= self.rho_max:
            raise ValueError(f"rho_min must be < rho_max, got rho_min={rho_min!r}, rho_max={rho_max!r}")
        if residuals is not None and not callable(residuals):
            raise ValueError(f"residuals must be None or a function record -> (r_rel, s_rel), got {residuals!r}")
        self.residuals = residuals

    def relative_residuals(self, rec: IterationRecord) -> tuple[float, float]:
        """(r_rel, s_rel): the record's normalised residuals, or those of ``residuals`` if given."""
        if self.residuals is not None:
            r, s = self.residuals(rec)
            return float(r), float(s)
        return rec.primal_residual_rel, rec.dual_residual_rel

    def estimate(self, rec: IterationRecord) -> float:
        """rho_est = rho_k sqrt(r_rel / s_rel).

        With the record's residuals each normalised residual is clamped to
        [DIVISION_TOL, 1/DIVISION_TOL]; with ``residuals`` (OSQP's own
        normalisation) the ratio is taken as OSQP 1.x takes it (s_rel = 0 gives
        an infinite estimate, clamped to ``rho_max`` by :meth:`update`).
        """
        return rec.rho * math.sqrt(self.ratio(rec))

    def ratio(self, rec: IterationRecord) -> float:
        """r_rel / s_rel as :meth:`estimate` takes it (each clamped, or OSQP 1.x's quotient with ``residuals``)."""
        r, s = self.relative_residuals(rec)
        if self.residuals is not None:
            return r / s if s > 0 else (math.inf if r > 0 else math.nan)
        r = min(max(r, DIVISION_TOL), 1 / DIVISION_TOL)
        s = min(max(s, DIVISION_TOL), 1 / DIVISION_TOL)
        return r / s

    def unchanged_until(self, k: int) -> int:
        """The next iteration j >= k with (j + 1) a multiple of ``interval``: the rule reads no other record."""
        return k + (-(k + 1)) % self.interval

    def update(self, rec: IterationRecord) -> float:
        """Adopt rho_est at iterations interval, 2 interval, ... when it differs by more than ``tolerance``."""
        if (rec.k + 1) % self.interval:
            return rec.rho
        return self.adopted(rec, self.clamped_estimate(rec))

    def clamped_estimate(self, rec: IterationRecord) -> float:
        """rho_est of :meth:`estimate` clipped to [rho_min, rho_max], or NaN where it cannot be computed."""
        est = self.estimate(rec)
        return est if math.isnan(est) else min(max(est, self.rho_min), self.rho_max)

    def adopted(self, rec: IterationRecord, est: float) -> float:
        """``est`` if it differs from rho by more than the factor ``tolerance`` (OSQP's test), else rho."""
        if est > self.tolerance * rec.rho or est < rec.rho / self.tolerance:
            return est
        return rec.rho
