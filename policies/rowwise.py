"""A penalty per row, each moved by its own residuals (RLQP's shape, without learning), on top of OSQP's rule.

J. Ichnowski, P. Jain, B. Stellato, G. Banjac, M. Luo, F. Borrelli, J. E.
Gonzalez, I. Stoica, K. Goldberg, "Accelerating quadratic optimization with
reinforcement learning", NeurIPS 2021 (RLQP): a policy sets each constraint's
penalty rho_i from that row's own state, where OSQP sets one rho (and a fixed
1e3 x on equality rows).  Here the per-row policy is written, not learned.

Every ``interval`` iterations (iteration-based, deterministic, never timed):

- the global rho: OSQP's estimate and tolerance test
  (:class:`admmkit.policies.OSQPRule`, the same numbers);
- the rows: with r_i = ``|(A x - z)_i|`` row i's primal residual and
  s_i = rho w_i ``|z_i^{k+1} - z_i^k|`` its share of the dual residual
  A'M rho (z^{k+1} - z^k) (up to the row's norm ||a_i||, about 1 once the QP is
  Ruiz-equilibrated), each row's factor d_i on the weights w0 the run started
  with moves as OSQP's rho does, by the square root of the ratio::

      t_i = (r_i + floor max_j r_j) / (s_i + floor max_j s_j)
      d_i <- d_i sqrt(t_i),  normalised to geometric mean 1,  clamped to [1/spread, spread]
      w_i = w0_i d_i         (row i's penalty rho w_i)

  The normalisation leaves the level to the global rho; the floors keep a
  row with no residual of either kind at the common ratio.

The rows' weights change with the global rho (that change refactorises the
x-step anyway), or alone when they would move by more than the factor
``tolerance`` in the root mean square of log(d_new / d): a change is one
event and one factorisation (:class:`admmkit.RowPenalties`).  With
``spread = 1`` the rows never move and the run is OSQP's rule's, bit for bit.  The problem must take a
penalty per row (the QP plug-in does); the rule reads r as A x - z (c = 0,
as in a QP).

Written for issue #50 (item 2).  Not done: a restart to the last good point
(a rule sets penalties, not the iterate).
"""
from __future__ import annotations

import math

import numpy as np

from admmkit import IterationRecord, RowPenalties
from admmkit.policies._checks import check_number
from admmkit.policies.osqp_rule import OSQPRule


class RowwiseRule(OSQPRule):
    """OSQP's rule for rho, and each row's weight moved by sqrt(its primal residual / its dual residual share)."""

    per_row = True
    #: the exponent of a row's step d_i <- d_i t_i^beta (the square root; ``fitted`` makes it a parameter)
    beta = 0.5

    def __init__(self, interval: int = 50, tolerance: float = 5.0, spread: float = 100.0, floor: float = 1e-3,
                 rho_min: float = 0.0, rho_max: float = math.inf, residuals=None):
        super().__init__(interval=interval, tolerance=tolerance, rho_min=rho_min, rho_max=rho_max,
                         residuals=residuals)
        self.spread = check_number("spread", spread, low=1.0, low_open=False)
        self.floor = check_number("floor", floor, low=0.0, high=1.0)
        self.base = self.factors = None

    def reset(self, rho0: float) -> None:
        """Start a new run: the rows' factors are 1 on the weights of the first record read."""
        super().reset(rho0)
        self.base = self.factors = None

    def row_factors(self, rec: IterationRecord) -> np.ndarray | None:
        """The rows' new factors d (geometric mean 1, within [1/spread, spread]), or None where the record gives
        no residual to balance (every r_i or every s_i zero, or not finite)."""
        w = rec.row_weights
        if self.base is None:
            self.base, self.factors = w, np.ones_like(w)
        r = np.abs(rec.Ax - rec.z)
        s = rec.rho * w * np.abs(rec.z - rec.z_prev)
        r_top, s_top = float(np.max(r, initial=0.0)), float(np.max(s, initial=0.0))
        if not (0 < r_top < math.inf and 0 < s_top < math.inf):
            return None
        t = (r + self.floor * r_top) / (s + self.floor * s_top)
        log_d = np.log(self.factors) + self.beta * np.log(t)
        log_d -= log_d.mean()
        return np.exp(np.clip(log_d, -math.log(self.spread), math.log(self.spread)))

    def update(self, rec: IterationRecord):
        """At iterations interval, 2 interval, ...: OSQP's rho, and the rows' weights with it or when they moved
        by more than ``tolerance`` (RowPenalties); else rho_k."""
        if (rec.k + 1) % self.interval:
            return rec.rho
        rho = self.adopted(rec, self.clamped_estimate(rec))
        d = self.row_factors(rec)
        if d is None:
            return rho
        moved = math.sqrt(float(np.mean(np.log(d / self.factors) ** 2)))
        if rho == rec.rho and moved <= math.log(self.tolerance):
            return rho
        self.factors = d
        return RowPenalties(rho, self.base * d)
