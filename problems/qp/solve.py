"""``solve_qp``: the QP plug-in with OSQP's machinery around :func:`admmkit.solve`.

It builds the QP in the form the settings ask for (Ruiz scaling, penalty per
row), runs the loop with over-relaxation, the termination test every
``check_every`` iterations (:class:`admmkit.problems.qp.termination.QPTermination`:
residuals, duality gap, infeasibility) and a penalty rule (default OSQP's,
fed OSQP 1.x's normalised residuals of the scaled problem), then, as OSQP:

- at the iteration cap, the test once more at 10x the tolerances
  ("solved inaccurate", "primal/dual infeasible inaccurate");
- polishing if asked (:mod:`admmkit.problems.qp.polish`);
- every number in the user's problem: x, z, the multiplier y (in ``lam``),
  the objective, the residuals.

The result says which test fired (``termination``) and carries the
infeasibility certificate.  ``warm_start=`` a previous result starts from its
x, y and rho (OSQP's warm start: z = A x).  As OSQP's setup, the x-step matrix
for rho_0 is factorised before the loop: ``timings["setup"]`` holds that time
(``timings["total"]`` is the loop's), ``counters["factorizations"]`` counts it.
"""
from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np

import admmkit
from admmkit import Result, Status
from admmkit.loop.checks import number
from admmkit.kernels import AVAILABLE, compiled_code

from .polish import polish as polish_solution
from .problem import QP
from .segment import choose_compiled
from .validate import check_options
from .residuals import neutral_residuals
from .settings import QPSettings, osqp_settings
from .termination import (DUAL_INFEASIBLE, PRIMAL_INFEASIBLE, SOLVED, QPTermination, _iterate, osqp_relative_residuals,
                          residuals_of_iterate)
from .termination import ScaleWarning  # noqa: F401  (re-exported: what the cvxpy interface warns with)

#: OSQP_RHO_MIN, OSQP_RHO_MAX
RHO_MIN, RHO_MAX = 1e-6, 1e6
#: OSQP's "inaccurate" tests use 10x the tolerances
INACCURATE_FACTOR = 10.0


#: the fields of an admmkit Result, which a QPResult copies
_RESULT_FIELDS = tuple(f.name for f in dataclasses.fields(Result))

#: the QP's statuses are admmkit's (``admmkit.Status`` has the infeasibility verdicts a stopping rule can give)
QPStatus = Status


@dataclass(repr=False)
class QPResult(Result):
    """An :class:`admmkit.Result` in the user's problem: ``x``, ``z``, ``lam`` (= the QP's multiplier y).

    Extra fields: ``termination`` (the test that ended the run: "solved",
    "primal_infeasible", "dual_infeasible", their "_inaccurate" forms at the
    iteration cap, or None), ``certificate`` (a field of every admmkit result: the
    normalised dy or dx of an infeasibility stop), ``residuals (OSQP's primal, dual and gap with their
    scales at the last iterate), ``neutral`` (the neutral criteria at the
    returned x, y), ``polish`` (None if not asked; else a dict whose
    ``status`` is "succeeded" or "failed"), ``settings``, ``warnings`` (sentences naming the rows or
    columns whose scale makes a tolerance vacuous, ``admmkit.problems.qp.termination.ScaleCheck``;
    empty when there are none).
    """

    termination: str | None = None
    residuals: dict | None = None
    neutral: dict | None = None
    polish: dict | None = None
    settings: QPSettings | None = None
    warnings: list[str] = field(default_factory=list)

    @property
    def y(self) -> np.ndarray:
        """The QP's multiplier (the same array as ``lam``)."""
        return self.lam

    @property
    def solved(self) -> bool:
        """True when the residual (and gap) test held at the requested accuracy and nothing downgraded the run
        (a test blind on some rows or columns makes it ``converged_inaccurate``: see ``warnings``)."""
        return self.termination == SOLVED and self.status is Status.CONVERGED


def qp_for(qp: QP, settings: QPSettings) -> QP:
    """``qp`` itself if it is built with the settings' sigma, scaling, row weights, x relaxation and x-step form, else
    a copy that is (the copy keeps the QP's backend).  x is relaxed only in order "xz" (OSQP's order; in
    order "zx" the loop relaxes z and the x-step comes last)."""
    want = qp_options(settings)
    if all(qp.options.get(k) == v for k, v in want.items()):
        return qp
    return qp.with_checked_options(want)


#: (settings, their QP options checked) of the last settings :func:`qp_options` was asked about
_held_options: tuple = (None, None)


def qp_options(settings: QPSettings) -> dict:
    """The QP options ``settings`` ask for (sigma, scaling, row_weights, x_relaxation, xstep), checked with the QP's
    own messages (``validate.check_options``: a bad ``row_weights`` is refused here).  Settings are frozen, so the
    check of the last settings object asked about is kept: a solve with the shared preset checks them once, not
    at every copy of a QP."""
    global _held_options
    held, options = _held_options
    if held is not settings:
        x_relaxation = float(settings.alpha) if settings.relax_x and settings.order == "xz" else 1.0
        checked = check_options(sigma=settings.sigma, backend="auto", xstep=settings.xstep, scaling=settings.scaling,
                                row_weights=settings.row_weights, x_relaxation=x_relaxation, allow_nonconvex=False)
        options = {k: checked[k] for k in ("sigma", "scaling", "row_weights", "x_relaxation", "xstep")}
        _held_options = (settings, options)
    return options


#: the rules ``solve_qp`` names and runs as OSQP runs its own (OSQP 1.x's residuals of the scaled problem, rho clamped
#: to [RHO_MIN, RHO_MAX]): ``default_policy``
OSQP_NORMALISED = ("osqp", "rowwise")


def default_policy(qp: QP, settings: QPSettings, name: str = "osqp"):
    """OSQP's rule as OSQP 1.x runs it: every ``adaptive_rho_interval`` iterations, on the scaled problem's residuals
    (``adaptive_rho="kkt_error"``: OSQP 1.x's KKT-error mode, ``policies.OSQPKKTRule``); ``name="rowwise"``: the
    same with a penalty per row (``policies.rowwise.RowwiseRule``), as is "osqp" with ``adaptive_rho="rowwise"``
    (admmkit's preset)."""
    if name == "rowwise" or settings.adaptive_rho == "rowwise":
        from admmkit.policies.rowwise import RowwiseRule
        return RowwiseRule(interval=settings.adaptive_rho_interval, tolerance=settings.adaptive_rho_tolerance,
                           rho_min=RHO_MIN, rho_max=RHO_MAX, residuals=osqp_relative_residuals(qp))
    from admmkit.policies import OSQPKKTRule, OSQPRule
    if settings.adaptive_rho == "kkt_error":
        return OSQPKKTRule(interval=settings.adaptive_rho_interval, tolerance=settings.adaptive_rho_tolerance,
                           fraction=settings.adaptive_rho_fraction, rho_min=RHO_MIN, rho_max=RHO_MAX,
                           residuals=osqp_relative_residuals(qp))
    return OSQPRule(interval=settings.adaptive_rho_interval, tolerance=settings.adaptive_rho_tolerance,
                    rho_min=RHO_MIN, rho_max=RHO_MAX, residuals=osqp_relative_residuals(qp))


def solve_qp(qp: QP, settings: QPSettings | None = None, *, policy="osqp", warm_start: Result | None = None,
             rho: float | None = None, callback=None, acceleration=None, **changes) -> QPResult:
    """Solve ``qp`` with ``settings`` (default :func:`osqp_settings`; keyword ``changes`` override single settings).

    ``policy``: "osqp" (default: OSQP's rule with OSQP's normalisation, see
    ``admmkit.problems.qp.solve.default_policy``), "rowwise" (the same with a penalty per row, on the same
    normalisation), None for a fixed rho, or any policy or registered
    name :func:`admmkit.solve` accepts.  ``warm_start``: a previous result of
    this QP (its x, y and rho; finite).  ``rho`` overrides rho_0: a number in (0, inf),
    clamped to OSQP's [1e-6, 1e6] as OSQP does.  ``acceleration``:
    None, "anderson", "fast" or an accelerator, as :func:`admmkit.solve` takes it.
    """
    if not isinstance(qp, QP):
        raise TypeError(f"qp must be a admmkit.problems.qp.QP, got {type(qp).__name__}")
    if settings is None:
        settings = osqp_settings(**changes)
    elif isinstance(settings, QPSettings):
        settings = settings.replace(**changes)
    else:
        raise TypeError(f"settings must be a QPSettings (e.g. osqp_settings()), got {type(settings).__name__}")
    segment, helpers = compiled_for(settings.compiled, qp)
    with compiled_code(helpers):          # the helper kernels compiled, or run as Python (the same bits)
        run_qp = qp_for(qp, settings)
        named = isinstance(policy, str) and policy in OSQP_NORMALISED
        rule = default_policy(run_qp, settings, policy) if named else policy
        x0 = z0 = lam0 = None
        if warm_start is not None:
            if not isinstance(warm_start, Result):
                raise TypeError(f"warm_start must be a result of solve_qp, got {type(warm_start).__name__}")
            if np.shape(warm_start.x) != (qp.n,) or np.shape(warm_start.lam) != (qp.m,):
                raise ValueError(f"warm_start has x of shape {np.shape(warm_start.x)} and y of shape "
                                 f"{np.shape(warm_start.lam)}; this QP needs ({qp.n},) and ({qp.m},): give a result "
                                 f"of a QP of the same size")
            for name, v in (("x", warm_start.x), ("y", warm_start.lam)):
                if not np.all(np.isfinite(v)):
                    raise ValueError(f"warm_start.{name} must be finite, got {np.size(v) - np.count_nonzero(np.isfinite(v))} "
                                     f"NaN or infinite entries: give a result that did not diverge")
            x0, z0, lam0 = run_qp.iterate_from(warm_start.x, warm_start.lam)
            rho = warm_start.rho if rho is None else rho
        rho0 = min(max(settings.rho if rho is None else check_rho(rho), RHO_MIN), RHO_MAX)
        stop = termination_for(run_qp, settings)
        start = time.perf_counter()
        setup_factorizations = run_qp.setup(rho0)                               # OSQP factorises in its setup too
        setup_time = time.perf_counter() - start
        res = admmkit.solve(run_qp, rho=rho0, policy=rule, order=settings.order, stop=stop, max_iter=settings.max_iter,
                            alpha=settings.alpha, check_every=settings.check_every, x0=x0, z0=z0, lam0=lam0,
                            time_limit=settings.time_limit, callback=callback, acceleration=acceleration,
                            compiled=segment)
        res.timings["setup"] = setup_time
        res.counters["factorizations"] = res.counters.get("factorizations", 0) + setup_factorizations
        return _qp_result(run_qp, settings, res, stop, res.last_record)


def compiled_for(setting, qp: QP) -> tuple[bool, bool]:
    """:func:`admmkit.problems.qp.segment.choose_compiled`'s (segment, helpers) for the setting ``compiled``; for
    True, (numba installed, numba installed) without asking whether compiled code pays (which walks the loaded
    kernels: ~6 us of a small QP's solve)."""
    if setting is True:
        return AVAILABLE, AVAILABLE
    return choose_compiled(setting, qp)


def termination_for(qp: QP, settings: QPSettings) -> QPTermination:
    """OSQP's test at the settings' tolerances; with ``early_polish``, the test that also polishes near the solution
    (:class:`admmkit.problems.qp.polish_stop.PolishingTermination`)."""
    options = dict(gap=settings.gap, infeasibility=settings.infeasibility, eps_prim_inf=settings.eps_prim_inf,
                   eps_dual_inf=settings.eps_dual_inf)
    if settings.early_polish:
        from .polish_stop import PolishingTermination
        return PolishingTermination(qp, settings.eps_abs, settings.eps_rel, gate=settings.polish_gate,
                                    every=settings.polish_interval, backoff=settings.polish_backoff,
                                    delta=settings.delta,
                                    refine=settings.polish_refine_iter, **options)
    return QPTermination(qp, settings.eps_abs, settings.eps_rel, **options)


def check_rho(rho) -> float:
    """``rho`` (solve_qp's keyword, or a warm start's) as a float in (0, inf): TypeError unless a number, ValueError
    outside the range.  (A valid rho is then clamped to OSQP's [RHO_MIN, RHO_MAX], as OSQP does.)"""
    value = number("rho", rho, "in (0, inf)")
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"rho must be a number in (0, inf), got {rho!r} (a rho in range is clamped to OSQP's "
                         f"[{RHO_MIN:g}, {RHO_MAX:g}])")
    return value


def _same(view: np.ndarray, array: np.ndarray) -> bool:
    """``view`` is ``array`` or a view of it (a record's read-only view of the loop's iterate)."""
    return view is array or view.base is array


#: the same names as a set, to compare with a result's attributes
_RESULT_FIELD_SET = frozenset(_RESULT_FIELDS)


def _fields_of(res: Result) -> dict:
    """{field: value} of an admmkit Result: a copy of its attributes when they are exactly its fields (a dataclass
    sets nothing else: one copy, not 22 lookups), else read field by field."""
    attributes = res.__dict__
    if attributes.keys() == _RESULT_FIELD_SET:
        return attributes.copy()
    return {name: getattr(res, name) for name in _RESULT_FIELDS}


def _qp_result(qp: QP, settings: QPSettings, res: Result, stop: QPTermination, rec) -> QPResult:
    status, termination, message = res.status, None, res.message
    if res.status in (Status.CONVERGED, Status.PRIMAL_INFEASIBLE, Status.DUAL_INFEASIBLE) and stop.outcome is not None:
        termination = stop.outcome                                         # the test that ended the loop
    elif res.status is Status.MAX_ITER and rec is not None:                 # OSQP: one more test at 10x
        loose = QPTermination(qp, INACCURATE_FACTOR * settings.eps_abs, INACCURATE_FACTOR * settings.eps_rel,
                              gap=settings.gap, infeasibility=settings.infeasibility,
                              eps_prim_inf=INACCURATE_FACTOR * settings.eps_prim_inf,
                              eps_dual_inf=INACCURATE_FACTOR * settings.eps_dual_inf)
        if loose.fired(rec):
            termination = loose.outcome + "_inaccurate"
            stop = loose
            message += f"; {loose.outcome} at 10x the tolerances"
    if termination in (PRIMAL_INFEASIBLE, PRIMAL_INFEASIBLE + "_inaccurate",
                       DUAL_INFEASIBLE, DUAL_INFEASIBLE + "_inaccurate"):
        status = QPStatus(termination)
    elif termination == SOLVED + "_inaccurate":
        status = Status.CONVERGED_INACCURATE
    if status is Status.CONVERGED and (stop.scale.span_columns.size or stop.scale.void_rows.size):
        status = Status.CONVERGED_INACCURATE        # the dual test was blind on some columns, or no x meets a row
        message += "; but the test cannot see some rows or columns (see warnings)"
    lam_z = rec.lam_z if rec is not None else res.lam
    zb = rec.z if rec is not None else res.z
    xb = qp.relaxed_x(res.x_iterate)                                       # OSQP's x under (Q4)
    x, z, y = qp.unscaled(xb, zb, lam_z)
    finite = bool(np.isfinite(xb).all() and np.isfinite(lam_z).all())
    residuals = None
    if finite:                  # the last test's residuals when they are of this iterate (OSQP's numbers, unscaled)
        same = rec is not None and xb is qp.relaxed_x(rec.x)
        residuals = _iterate(qp, rec) if same else residuals_of_iterate()(qp, xb, zb, lam_z)
        residuals = {k: v for k, v in residuals.items() if not k.startswith("scaled_")}
    objective = res.objective
    if not finite:
        kkt = None
    elif res.kkt is not None and _same(zb, res.z) and _same(lam_z, res.lam):
        kkt = res.kkt                       # the loop's result measured this very point: x = D xb, z, lam
    else:
        kkt = qp.kkt(x, zb, lam_z)
    if status is Status.PRIMAL_INFEASIBLE or status is Status.PRIMAL_INFEASIBLE_INACCURATE:
        objective = math.inf
    elif status is Status.DUAL_INFEASIBLE or status is Status.DUAL_INFEASIBLE_INACCURATE:
        objective = -math.inf
    polish_info = None
    polished = getattr(stop, "polished", None)
    if polished is not None:                    # the run ended on a polished point that passed the test
        x, z, y, polish_info = polished
        objective = qp.objective(x, z)
        residuals = dict(stop.last)
        kkt = qp.kkt(x, qp.scaling.E * z if qp.scaled else z, qp.iterate_from(x, y)[2])
    elif settings.polish:
        if termination in (SOLVED, SOLVED + "_inaccurate"):
            yb = lam_z if qp.w is None else qp.w * lam_z
            xp, yp, polish_info = polish_solution(qp, xb, zb, yb, delta=settings.delta,
                                                  refine=settings.polish_refine_iter)
            if xp is not None:
                x, y = xp, yp
                z = np.clip(qp.A @ x, qp.l, qp.u)
                objective = qp.objective(x, z)
        else:
            polish_info = {"status": "failed", "reason": f"not run: the run ended {termination or res.status.value}"}
    neutral = neutral_residuals(qp, x, y) if finite else None
    warnings = stop.scale.warnings(x, stop.eps_abs, stop.eps_rel, stop.row_test) if finite else []
    fields = _fields_of(res)
    fields.update(x=x, z=z, lam=y, status=status, message=message, objective=objective, kkt=kkt,
                  certificate=stop.certificate if termination else None)
    return QPResult(**fields, termination=termination, residuals=residuals, neutral=neutral, polish=polish_info,
                    settings=settings, warnings=warnings)
