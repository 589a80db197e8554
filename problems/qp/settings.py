"""Settings of a QP solve, with OSQP 1.x's defaults as one preset (``osqp_settings()``) and admmkit's textbook loop.

OSQP's defaults (``osqp.OSQP().settings`` of osqp 1.1: rho 0.1, sigma 1e-6,
alpha 1.6, scaling 10, rho per row, eps_abs = eps_rel = 1e-3,
eps_prim_inf = eps_dual_inf = 1e-4, check_termination 25, check_dualgap on,
adaptive_rho 1 = every adaptive_rho_interval = 50 iterations with
adaptive_rho_tolerance 5, max_iter 4000, polishing off, delta 1e-6,
polish_refine_iter 3).  OSQP's rho rule (``policies.OSQPRule``) steers
rho at a fixed iteration interval, so a run is deterministic.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from admmkit.loop.checks import number          # float(value), or a TypeError naming the setting


@dataclass(frozen=True)
class QPSettings:
    """Everything :func:`admmkit.problems.qp.solve_qp` needs besides the QP and the penalty rule (defaults: OSQP 1.x's).

    ``sigma``, ``scaling``, ``row_weights``, ``xstep`` and ``relax_x`` shape the
    QP object (``solve_qp`` builds a copy of the QP with them if needed); the
    others the run.
    """

    rho: float = 0.1                   # rho_0 in (0, inf) (clamped to [1e-6, 1e6] as OSQP does)
    sigma: float = 1e-6                # proximal weight of the x-step
    alpha: float = 1.6                 # over-relaxation
    relax_x: bool = True               # relax x too, as OSQP (it enters the proximal term sigma and the residuals)
    scaling: int = 10                  # Ruiz iterations (0: none)
    row_weights: str = "osqp"          # "osqp": rho x 1e3 on equality rows, a floor on free rows; "uniform"
    order: str = "xz"                  # OSQP's order: x-step first
    xstep: str = "kkt"                 # OSQP's quasi-definite KKT system (qdldl if installed); "reduced", "auto"
    eps_abs: float = 1e-3
    eps_rel: float = 1e-3
    gap: bool = True                   # OSQP 1.x's check_dualgap
    infeasibility: bool = True         # detect primal / dual infeasibility
    eps_prim_inf: float = 1e-4
    eps_dual_inf: float = 1e-4
    check_every: int = 25              # OSQP's check_termination
    adaptive_rho_interval: int = 50    # OSQP's rule: every this many iterations
    adaptive_rho_tolerance: float = 5.0
    # when solve_qp's policy is "osqp": "interval", OSQP's rule every adaptive_rho_interval iterations (OSQP 1.x's
    # adaptive_rho 1); "kkt_error", once the KKT error fell to adaptive_rho_fraction x its value at the last update
    # (adaptive_rho 3, policies.OSQPKKTRule, read every adaptive_rho_interval iterations); "rowwise", OSQP's rule
    # every interval with a penalty per row moved by each row's own residuals (policies.rowwise.RowwiseRule)
    adaptive_rho: str = "interval"
    adaptive_rho_fraction: float = 0.4
    max_iter: int = 4000
    polish: bool = False
    polish_refine_iter: int = 3
    delta: float = 1e-6                # regularisation of the polishing system
    # polishing during the run (problems.qp.polish_stop): at a check where the test holds at polish_gate x the
    # tolerances, polish; the next try waits polish_interval iterations, that wait multiplied by polish_backoff after
    # each failed try; a polished point that passes the test ends the run
    early_polish: bool = False
    polish_gate: float = 1e3
    polish_interval: int = 100
    polish_backoff: float = 2.0
    time_limit: float | None = None    # seconds (benchmarks only)
    # compiled code (numba): "auto" where the QP is large enough to pay for numba's import and its kernels' load
    # or compile (problems.qp.segment.compiled_pays), True always, False every iteration in Python (the helper
    # passes as "auto" decides); the iterates are the same bits every way (docs/qp.md, "First call")
    compiled: bool | str = "auto"

    def __post_init__(self):
        for name in ("rho", "alpha", "eps_prim_inf", "eps_dual_inf", "adaptive_rho_tolerance", "delta", "polish_gate"):
            v = number(name, getattr(self, name), "finite, > 0")
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {getattr(self, name)!r}")
        if not 0 < self.alpha < 2:
            raise ValueError(f"alpha must be in (0, 2), got {self.alpha!r}")
        if self.adaptive_rho not in ADAPTIVE_RHO:
            raise ValueError(f"adaptive_rho must be one of {', '.join(map(repr, ADAPTIVE_RHO))}, got {self.adaptive_rho!r}")
        if not 0 < number("adaptive_rho_fraction", self.adaptive_rho_fraction, "in (0, 1)") < 1:
            raise ValueError(f"adaptive_rho_fraction must be a number in (0, 1), got {self.adaptive_rho_fraction!r}")
        if self.polish_gate < 1:
            raise ValueError(f"polish_gate must be >= 1, got {self.polish_gate!r}")
        backoff = number("polish_backoff", self.polish_backoff, "finite, >= 1")
        if not (math.isfinite(backoff) and backoff >= 1):
            raise ValueError(f"polish_backoff must be a finite number >= 1, got {self.polish_backoff!r}")
        if self.adaptive_rho_tolerance < 1:
            raise ValueError(f"adaptive_rho_tolerance must be >= 1, got {self.adaptive_rho_tolerance!r}")
        for name in ("sigma", "eps_abs", "eps_rel"):
            v = number(name, getattr(self, name), "finite, >= 0")
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {getattr(self, name)!r}")
        for name, low in (("scaling", 0), ("check_every", 1), ("adaptive_rho_interval", 1), ("max_iter", 1),
                          ("polish_refine_iter", 0), ("polish_interval", 1)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < low:
                raise ValueError(f"{name} must be an integer >= {low}, got {v!r}")
        if not isinstance(self.early_polish, bool):
            raise ValueError(f"early_polish must be True or False, got {self.early_polish!r}")
        if not (isinstance(self.compiled, bool) or self.compiled == "auto"):
            raise ValueError(f"compiled must be 'auto', True or False, got {self.compiled!r}")
        if self.xstep not in ("auto", "reduced", "kkt"):
            raise ValueError(f"xstep must be one of auto, reduced, kkt, got {self.xstep!r}")
        if self.order not in ("xz", "zx"):
            raise ValueError(f"order must be 'xz' or 'zx', got {self.order!r}")
        if self.time_limit is not None:
            v = number("time_limit", self.time_limit, "seconds, finite, > 0, or None")
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"time_limit must be a finite number > 0 or None, got {self.time_limit!r}")

    def replace(self, **changes) -> "QPSettings":
        """A copy with some settings changed (unknown names raise TypeError); no change: this object itself."""
        if not changes:
            return self
        _check_names(changes)
        return dataclasses.replace(self, **changes)


def _check_names(changes: dict) -> None:
    """TypeError naming the unknown settings among ``changes`` and listing the known ones."""
    known = _KNOWN
    if known.keys() >= changes.keys():
        return
    unknown = sorted(set(changes) - set(known))
    if unknown:
        raise TypeError(f"unknown QP setting(s) {', '.join(unknown)}; known: {', '.join(known)}")


#: the settings' names, in their order
_KNOWN = {f.name: None for f in dataclasses.fields(QPSettings)}


def osqp_settings(**changes) -> QPSettings:
    """OSQP 1.x's defaults (the preset), with ``changes`` applied."""
    _check_names(changes)
    return _checked_once(changes)


#: the settings :func:`osqp_settings` has built and checked, by their changes (see :func:`_checked_once`)
_BUILT: dict = {}
#: how many of them it keeps (a long session of varied settings does not grow it without end)
_BUILT_MAX = 256


def _checked_once(changes: dict) -> QPSettings:
    """``QPSettings(**changes)``, built and checked once per process for the same changes: the settings are frozen,
    so the object is shared (its checks cost ~25 us of a small QP's ~1 ms solve).  The key holds each value's
    type (1 and 1.0, True and 1 stay apart); a zero (whose sign a key cannot tell: -0.0 == 0.0) or a change that
    cannot be a key (an array) builds the settings anew."""
    values = changes.values()
    try:
        if 0 in values:
            return QPSettings(**changes)
        key = (tuple(changes.items()), tuple(map(type, values)))
        held = _BUILT.get(key)
    except (TypeError, ValueError):         # an unhashable value, or one that is no number (an array): no key
        return QPSettings(**changes)
    if held is None:
        held = QPSettings(**changes)        # a bad value raises here, and nothing is kept
        if len(_BUILT) >= _BUILT_MAX:
            _BUILT.clear()
        _BUILT[key] = held
    return held


def admmkit_settings(eps_abs: float = 1e-3, eps_rel: float = 1e-3, **changes) -> QPSettings:
    """admmkit's own preset (docs/qp.md, "admmkit's preset"): OSQP's machinery with what ``admmkit bench rules``
    found best on the training half of the Maros-Meszaros problems (docs/results/qp_rules), ``changes`` applied.

    Beside OSQP's defaults: polishing during the run (``early_polish``: near the solution the iterate is
    polished, and a polished point that passes OSQP's test ends the run), the iteration cap raised to
    ADMMKIT_MAX_ITER (a ``time_limit`` is the budget that matters) and a penalty per row
    (``adaptive_rho="rowwise"``: OSQP's rule for rho, each row's weight moved by its own residuals,
    ``policies.rowwise.RowwiseRule``).
    """
    _check_names(changes)
    return QPSettings(eps_abs=eps_abs, eps_rel=eps_rel, **(ADMMKIT_PRESET | changes))


#: when solve_qp's rule "osqp" updates rho, and how (QPSettings.adaptive_rho)
ADAPTIVE_RHO = ("interval", "kkt_error", "rowwise")
#: the iteration cap of admmkit's preset
ADMMKIT_MAX_ITER = 100_000
#: what admmkit's preset changes in OSQP's defaults (chosen on the training split, docs/results/qp_rules)
ADMMKIT_PRESET = {"max_iter": ADMMKIT_MAX_ITER, "early_polish": True, "adaptive_rho": "rowwise"}


def textbook_settings(**changes) -> QPSettings:
    """admmkit's textbook QP loop: no scaling, M = I, alpha = 1, the test at every iteration, rho_0 = 0.1."""
    return QPSettings(scaling=0, row_weights="uniform", alpha=1.0, relax_x=False, check_every=1,
                      xstep="auto").replace(**changes)
