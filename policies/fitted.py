"""``rowwise`` with its exponents and thresholds as parameters, the constants fitted offline on a training split.

A family of :class:`admmkit.policies.rowwise.RowwiseRule` (OSQP's rule for
the global rho, a penalty per row moved by the row's own residuals).  Every
``interval`` iterations, with r_rel, s_rel the normalised primal and dual
residuals (OSQP's own where the plug-in passes ``residuals``), and for each
row r_i = ``|(A x - z)_i|``, s_i = rho w_i ``|z_i^{k+1} - z_i^k|``::

    rho_est = rho_k (r_rel / s_rel)^alpha,   adopted if it moves rho by more than the factor tolerance
    t_i     = (r_i + floor max_j r_j) / (s_i + floor max_j s_j)
    d_i    <- d_i t_i^beta,  normalised to geometric mean 1,  clamped to [1/spread, spread]
    w_i     = w0_i d_i                       (row i's penalty rho w_i)

and the rows change with rho, or alone when the root mean square of
log(d_new / d) exceeds log(tolerance) (one event, one factorisation, as in
``rowwise``).  alpha = beta = 1/2, interval 50, tolerance 5 is ``rowwise``
bit for bit (the square root taken as ``math.sqrt``).

The class defaults below were chosen by a grid over (alpha, beta, interval,
tolerance) on the training half of qpbenchmark's Maros-Meszaros class only
(43 problems; ``admmkit.benchmarks.qp.qp_rules_report.split``), in admmkit's
preset, scored by problems solved at eps 1e-3 and 1e-6 (qpbenchmark's
criteria) and then by the shifted geometric mean of iterations:
``python -m admmkit.benchmarks.qp.fit_rule``; the grid, the choice and its
check on the test half are in docs/results/qp_fitted/README.md.
"""
from __future__ import annotations

import math

from admmkit import IterationRecord
from admmkit.policies.rowwise import RowwiseRule


class FittedRowwise(RowwiseRule):
    """rho <- rho (r_rel / s_rel)^alpha and each row's factor d_i <- d_i t_i^beta, every ``interval`` iterations."""

    #: exponent of the global estimate: fitted by `python -m admmkit.benchmarks.qp.fit_rule --data
    #: /work/shared/data/maros_meszaros --out docs/results/qp_fitted`, 2026-11-29
    ALPHA = 0.5
    #: exponent of the rows' step: fitted by the same command, 2026-11-29 (rowwise's 1/2: 65 of 86 training runs
    #: solved; 1: 71, the grid's best; docs/results/qp_fitted/grid.md)
    BETA = 1.0
    #: iterations between two readings: fitted by the same command, 2026-11-29
    INTERVAL = 50
    #: factor a change must exceed (rho, and the rows' RMS log-change): fitted by the same command, 2026-11-29
    TOLERANCE = 5.0

    def __init__(self, alpha: float | None = None, beta: float | None = None, interval: int | None = None,
                 tolerance: float | None = None, spread: float = 100.0, floor: float = 1e-3, rho_min: float = 0.0,
                 rho_max: float = math.inf, residuals=None):
        super().__init__(interval=self.INTERVAL if interval is None else interval,
                         tolerance=self.TOLERANCE if tolerance is None else tolerance, spread=spread, floor=floor,
                         rho_min=rho_min, rho_max=rho_max, residuals=residuals)
        self.alpha = exponent("alpha", self.ALPHA if alpha is None else alpha, zero=False)
        self.beta = exponent("beta", self.BETA if beta is None else beta, zero=True)

    def estimate(self, rec: IterationRecord) -> float:
        """rho_est = rho_k (r_rel / s_rel)^alpha, the ratio taken as :meth:`OSQPRule.estimate` takes it."""
        return rec.rho * power(self.ratio(rec), self.alpha)


def exponent(name: str, value, zero: bool) -> float:
    """float(value) if it is in (0, 1] (``zero``: [0, 1]), else a ValueError naming ``name`` and the range."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if isinstance(value, bool) or not (0.0 <= v <= 1.0) or (v == 0.0 and not zero):
        raise ValueError(f"{name} must be a finite number in {'[' if zero else '('}0, 1], got {value!r}")
    return v


def power(x: float, a: float) -> float:
    """x^a, as ``math.sqrt`` for a = 1/2 (so that alpha = 1/2 is OSQP's estimate to the last bit)."""
    return math.sqrt(x) if a == 0.5 else x ** a
