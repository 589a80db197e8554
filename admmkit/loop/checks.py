"""Checks made once at the start of a run: arguments, starting point, and what the rules need.

:func:`prepare` makes them all for ``admmkit.solve`` and returns the :class:`Run`:
the checked arguments, the starting point and the constants every record shares.
"""
from __future__ import annotations

import contextlib
import math
import numbers
import sys
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .blas import limit_blas
from .history import History
from .norms import RunContext
from ..policy import Policy, make_policy
from ..problem import Problem
from .result import Result
from .stopping import StoppingRule, default_stop

ORDERS = {"xz": "xz", "zx": "zx", "admm1": "xz", "admm2": "zx"}
#: record fields that order "xz" can only give with ``Problem.adjoint_norm``
NEEDS_ADJOINT = ("dual_residual", "dual_scale", "dual_residual_rel")


class Fixed(Policy):
    """Keeps rho constant (used when no policy is given)."""

    def update(self, rec) -> float:
        """Return rho_k."""
        return rec.rho

    def unchanged_until(self, k: int) -> int:
        """Never reads a record (so the iterations between checks may run in a compiled segment)."""
        return sys.maxsize


#: the penalties admmkit accepts, from the user (rho_0) and from a policy (a rho outside ends the run as
#: diverged): 60 decades, wide enough for any unit system, narrow enough that rho * ||r|| cannot under- or
#: overflow silently (a rule returning 1e-300 or 1e300 has failed, whatever the iterates say)
RHO_RANGE = (1e-30, 1e30)


def rho_in_range(rho) -> bool:
    """Whether ``rho`` is a number in :data:`RHO_RANGE`."""
    return (isinstance(rho, (float, int, np.floating, np.integer)) and not isinstance(rho, bool)
            and RHO_RANGE[0] <= rho <= RHO_RANGE[1])


def is_number(value) -> bool:
    """Whether ``value`` is one real number: an int, a float, a numpy scalar or a 0-d array of one
    (not a bool, not text: ``"1"`` is not taken for 1)."""
    if type(value) is float or type(value) is int:       # the common case, without the ABC check (a bool's type
        return True                                       # is bool, not int)
    if isinstance(value, (bool, np.bool_)):
        return False
    if isinstance(value, np.ndarray):
        return value.ndim == 0 and value.dtype.kind in "iuf"
    return isinstance(value, numbers.Real)


def number(name: str, value, accepted: str) -> float:
    """float(value) if it is a number (:func:`is_number`), else TypeError naming ``name`` and the ``accepted`` range."""
    if not is_number(value):
        raise TypeError(f"{name} must be a number ({accepted}), got {type(value).__name__} {value!r:.60}")
    return float(value)


def check_rho(rho, name: str) -> float:
    """float(rho) if it is a number in :data:`RHO_RANGE`: TypeError naming ``name`` for anything but a number,
    ValueError for a number outside the range."""
    value = number(name, rho, "finite, > 0")
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {rho!r}")
    if not rho_in_range(value):
        raise ValueError(f"{name} must be in [{RHO_RANGE[0]:g}, {RHO_RANGE[1]:g}] (admmkit's rho range), got {rho!r}")
    return value


def check_time_limit(time_limit) -> float | None:
    """None, or the wall-time limit in seconds: a finite number > 0 (TypeError for anything but a number)."""
    if time_limit is None:
        return None
    value = number("time_limit", time_limit, "seconds, finite, > 0, or None")
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"time_limit must be a finite number > 0 seconds or None, got {time_limit!r}")
    return value


def check_order(order) -> str:
    """'xz' or 'zx' from an order name (also 'admm1', 'admm2')."""
    key = str(order).lower()
    if key not in ORDERS:
        raise ValueError(f"order must be 'xz' (ADMM1, x-step first) or 'zx' (ADMM2, z-step first), got {order!r}")
    return ORDERS[key]


def check_alpha(alpha) -> float:
    """The over-relaxation parameter, a number in (0, 2) (TypeError for anything but a number)."""
    value = number("alpha", alpha, "in (0, 2)")
    if not (0.0 < value < 2.0):
        raise ValueError(f"alpha must be a number in (0, 2) (1: no relaxation; OSQP uses 1.6), got {alpha!r}")
    return value


def check_int(name: str, value, low: int) -> int:
    """value if it is an integer >= low, else ValueError naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    return int(value)


def make(policy) -> Policy:
    """A Policy from an object, a registered name or None (fixed rho)."""
    if policy is None:
        return Fixed()
    if isinstance(policy, str):
        return make_policy(policy)
    if isinstance(policy, Policy):
        return policy
    raise TypeError(f"policy must be a Policy object, a registered name or None, got {type(policy).__name__}")


def starting_point(problem, x0, z0, lam0, names=("x0", "z0", "lam0")):
    """(x0, z0, lam0) as float arrays: the given ones (checked, an error naming them by ``names``) or the
    problem's defaults."""
    own_start = type(problem).initial_point is not Problem.initial_point
    if x0 is None and not own_start and not isinstance(getattr(problem, "n", None), (int, np.integer)):
        raise TypeError(f"{type(problem).__name__} must set the attribute n (the number of x unknowns, an int) "
                        f"or override initial_point(), or solve() must be given x0")
    dx, dz, dlam = problem.initial_point()
    out = []
    for name, given, default in zip(names, (x0, z0, lam0), (dx, dz, dlam)):
        if given is None:                  # the plug-in's own start: only its finiteness is in doubt
            v = np.array(default, dtype=float)
            if not np.isfinite(v).all():
                raise ValueError(f"{type(problem).__name__}.initial_point() gave a non-finite {name}")
            out.append(v)
            continue
        if np.iscomplexobj(given):
            raise ValueError(f"{name} must be real, got complex values")
        try:
            v = np.array(given, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be an array of numbers of shape {np.shape(default)}, got {given!r:.80}") from None
        if v.shape != np.shape(default):
            raise ValueError(f"{name} must have shape {np.shape(default)}, got {v.shape}")
        if not np.all(np.isfinite(v)):
            bad = int(np.size(v) - np.count_nonzero(np.isfinite(v)))
            raise ValueError(f"{name} must be finite, got {bad} NaN or infinite entries of {v.size}")
        out.append(v)
    return out


def has_adjoint(problem, z) -> bool:
    """Whether ``problem.adjoint_norm`` is implemented: a problem class whose ``adjoint_norm_implemented`` is True
    says so (the QP's; no trial product at every solve), else a trial call on zeros tells."""
    if getattr(type(problem), "adjoint_norm_implemented", False) is True:
        return True
    try:
        problem.adjoint_norm(np.zeros_like(z))
    except NotImplementedError:
        return False
    return True


def check_requirements(problem, order: str, adjoint: bool, parts) -> None:
    """Refuse a run whose stopping rule or policy reads a quantity the problem cannot give.

    ``parts`` is a sequence of (role, object) with ``object.requires`` a tuple
    of record field names.  The only such quantities today are those built on
    Boyd's dual residual in order "xz", which need ``adjoint_norm``.
    """
    if order != "xz" or adjoint:
        return
    for role, obj in parts:
        missing = [name for name in getattr(obj, "requires", ()) if name in NEEDS_ADJOINT]
        if missing:
            raise ValueError(
                f"{role} {obj!r} needs Boyd's dual residual (it reads {', '.join(missing)}), which in order 'xz' is "
                f"rho ||A^T M (z^(k+1) - z^k)||: implement {type(problem).__name__}.adjoint_norm(y) to return "
                f"||A^T M y|| (a float, in the dual norm of the x space; the Euclidean norm for x in R^n), "
                f"or give A as an admmkit.blocks.operators.LinearMap (which derives it), or use order 'zx'"
                + (", or pass stop=admmkit.RelativeChange(...)" if role == "stop" else ""))


def check_step(problem, step: str, got, want: tuple, of: str) -> None:
    """Refuse what a step returned at the first iteration unless it is a numpy array of shape ``want`` (the shape
    of ``of``, "x" or "z"): a TypeError or ValueError naming the Problem class, the method and both shapes."""
    name = type(problem).__name__
    if not isinstance(got, np.ndarray):
        shape = f" of shape {np.shape(got)}" if isinstance(got, (list, tuple, np.generic)) else ""
        raise TypeError(f"{name}.{step}() returned {type(got).__name__}{shape}; it must return a numpy array "
                        f"of shape {want} (the shape of {of})")
    if got.shape != want:
        raise ValueError(f"{name}.{step}() returned an array of shape {got.shape}; it must have shape {want} "
                         f"(the shape of {of})")


def policy_answer(policy, rho_next, k: int) -> float:
    """The rho_(k+1) that ``policy.update`` returned at iteration ``k``, as a float, if it is one number, finite and
    > 0; else a TypeError (not a number: a bool, text, None, an array) or ValueError (NaN, inf, <= 0) naming the
    policy's class and the value.  (A number outside :data:`RHO_RANGE` is the loop's to judge: the run diverged.)"""
    name = type(policy).__name__
    if not is_number(rho_next):
        shape = f" of shape {np.shape(rho_next)}" if isinstance(rho_next, (np.ndarray, list, tuple)) else ""
        raise TypeError(f"policy {name}.update() returned {type(rho_next).__name__}{shape} {rho_next!r:.60} at "
                        f"iteration {k + 1}; it must return rho_(k+1), one number in (0, inf) (admmkit's rho is "
                        f"a scalar; a penalty per row is admmkit.RowPenalties(rho, weights) from a rule with "
                        f"per_row = True)")
    value = float(rho_next)
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"policy {name}.update() returned rho = {rho_next!r} at iteration {k + 1}; it must "
                         f"return rho_(k+1) in (0, inf)")
    return value


def row_weights_answer(policy, weights, k: int, shape: tuple) -> np.ndarray:
    """The row weights of a :class:`admmkit.RowPenalties` that ``policy.update`` returned at iteration ``k``, as a
    new float array, if the rule declares ``per_row = True`` and they are finite, > 0, of the shape of z
    (``shape``); else a TypeError or ValueError naming the policy's class."""
    name = type(policy).__name__
    if not getattr(policy, "per_row", False):
        raise TypeError(f"policy {name}.update() returned RowPenalties at iteration {k + 1} but {name} does not "
                        f"declare per_row = True (the loop checks that the problem takes a penalty per row "
                        f"before the first iteration)")
    try:
        w = np.array(weights, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"policy {name}.update() returned RowPenalties with weights {weights!r:.60} at iteration "
                        f"{k + 1}; they must be an array of numbers of shape {shape}") from None
    if w.shape != shape:
        raise ValueError(f"policy {name}.update() returned RowPenalties with weights of shape {w.shape} at "
                         f"iteration {k + 1}; they must have the shape of z, {shape}")
    if not (np.all(np.isfinite(w)) and np.all(w > 0)):
        raise ValueError(f"policy {name}.update() returned RowPenalties with weights outside (0, inf) at "
                         f"iteration {k + 1} (min {np.min(w)!r}); every row's weight must be finite and > 0")
    return w


def check_row_penalties(problem, policy, z) -> None:
    """Refuse a rule with ``per_row = True`` on a problem that cannot take a penalty per row: it needs
    ``update_row_weights(rho, w)`` and ``inner_weights()`` (the diagonal of M, of z's shape)."""
    if not getattr(policy, "per_row", False):
        return
    name = type(problem).__name__
    weights = getattr(problem, "inner_weights", None)
    if not (callable(getattr(problem, "update_row_weights", None)) and callable(weights)):
        raise ValueError(f"policy {policy!r} sets a penalty per row (per_row = True), which {name} does not take: "
                         f"a problem takes one by implementing update_row_weights(rho, w) and inner_weights() "
                         f"(its inner product M = diag(w); the QP plug-in does); use a rule with one rho for {name}")
    if np.shape(weights()) != np.shape(z):
        raise ValueError(f"policy {policy!r} sets a penalty per row, but {name}.inner_weights() has shape "
                         f"{np.shape(weights())}, not z's {np.shape(z)}")


def callback_answer(callback, answer):
    """``answer`` if it is what a callback may return: None or a bool (True: stop the run); else a TypeError naming
    the callback and what it returned."""
    if answer is None or isinstance(answer, (bool, np.bool_)):
        return answer
    name = getattr(callback, "__qualname__", None) or type(callback).__name__
    raise TypeError(f"callback {name} returned {type(answer).__name__} {answer!r:.60}; a callback returns None "
                    f"(go on) or a bool (True stops the run with status 'stopped')")


@dataclass
class Run:
    """One run of ``admmkit.solve``, checked and started: its arguments, its starting point
    (x0, z0, lam0 and A x0), the :class:`RunContext` its records share, and the problem's
    counters at the start."""

    problem: Problem
    order: str                   # "xz" or "zx"
    rho: float                   # rho_0
    policy: Policy
    stop: StoppingRule
    alpha: float
    max_iter: int
    check_every: int
    callback: Callable | None
    time_limit: float | None
    blas_threads: int | None
    history: History
    compiled: bool               # iterations nobody reads may run in the problem's compiled segment
    x: np.ndarray                # x^0, z^0, lam^0 and A x^0
    z: np.ndarray
    lam: np.ndarray
    Ax: np.ndarray
    ctx: RunContext
    counters_before: dict

    def blas_limit(self):
        """A context that holds BLAS to ``blas_threads`` threads (None: leaves them alone)."""
        if self.blas_threads is None:
            return contextlib.nullcontext()
        return limit_blas(self.blas_threads)          # a cached controller: ~15 us, not 0.5 ms


def prepare(problem, *, rho, policy, order, stop, max_iter, callback, x0, z0, lam0, time_limit, blas_threads,
            alpha, check_every, history, warm_start, compiled=True) -> Run:
    """Check the arguments of ``admmkit.solve`` (same names and meanings), start the run and return it.

    Bad input raises ValueError or TypeError naming the parameter.  Starting the run calls the
    problem's ``begin_run()`` (if it has one; building blocks count the run's work from there),
    resets the policy with rho_0 and notes the problem's counters.
    """
    order_key = check_order(order)
    if warm_start is not None:
        if not isinstance(warm_start, Result) or warm_start.x_iterate is None:
            raise TypeError(f"warm_start must be an admmkit.Result of solve(), got {type(warm_start).__name__}")
        names = tuple(name if given is not None else f"warm_start.{field}"
                      for name, given, field in (("x0", x0, "x_iterate"), ("z0", z0, "z"), ("lam0", lam0, "lam")))
        x0 = warm_start.x_iterate if x0 is None else x0
        z0 = warm_start.z if z0 is None else z0
        lam0 = warm_start.lam if lam0 is None else lam0
        rho_name = "rho" if rho is not None else "warm_start.rho"
        rho = warm_start.rho if rho is None else rho
    else:
        names, rho_name = ("x0", "z0", "lam0"), "rho"
    rho = check_rho(1.0 if rho is None else rho, rho_name)
    alpha = check_alpha(alpha)
    max_iter = check_int("max_iter", max_iter, 1)
    check_every = check_int("check_every", check_every, 1)
    history_log = History(history)
    time_limit = check_time_limit(time_limit)
    if blas_threads is not None and (isinstance(blas_threads, bool) or not isinstance(blas_threads, int) or blas_threads < 1):
        raise ValueError(f"blas_threads must be an integer >= 1 or None, got {blas_threads!r}")
    if callback is not None and not callable(callback):
        raise TypeError(f"callback must be callable or None, got {type(callback).__name__}")
    if not isinstance(compiled, bool):
        raise TypeError(f"compiled must be True or False, got {compiled!r}")
    stop = default_stop() if stop is None else stop
    if not isinstance(stop, StoppingRule):
        raise TypeError(f"stop must be a StoppingRule (e.g. RelativeChange(1e-5)), got {type(stop).__name__}")
    for name in ("x_step", "z_step", "apply_A"):
        if not callable(getattr(problem, name, None)):
            raise TypeError(f"problem must implement {name}() (see admmkit.Problem), got {type(problem).__name__}")
    policy = make(policy)

    x, z, lam = starting_point(problem, x0, z0, lam0, names)
    Ax = problem.apply_A(x)
    check_step(problem, "apply_A", Ax, z.shape, "z")
    Ax = np.asarray(Ax, dtype=float)
    if lam.shape != z.shape:
        raise ValueError(f"shapes do not match: z0 has shape {z.shape}, lam0 {lam.shape}")
    c = problem.c
    adjoint = order_key == "xz" and has_adjoint(problem, z)   # only order xz uses adjoint_norm
    check_requirements(problem, order_key, adjoint, (("policy", policy), ("stop", stop)))
    check_row_penalties(problem, policy, z)
    primal_unit = problem.norm(np.ones_like(z))
    dual_unit = math.sqrt(getattr(problem, "n", x.size)) if order_key == "xz" else primal_unit
    c_zero = np.isscalar(c) and c == 0
    c_norm = 0.0 if c_zero else problem.norm(np.broadcast_to(np.asarray(c, dtype=float), z.shape))
    ctx = RunContext(problem, order_key, alpha, c, c_norm, adjoint, primal_unit, dual_unit)

    begin_run = getattr(problem, "begin_run", None)
    if callable(begin_run):
        begin_run()
    policy.reset(rho)
    return Run(problem=problem, order=order_key, rho=rho, policy=policy, stop=stop, alpha=alpha, max_iter=max_iter,
               check_every=check_every, callback=callback, time_limit=time_limit, blas_threads=blas_threads,
               history=history_log, compiled=compiled, x=x, z=z, lam=lam, Ax=Ax, ctx=ctx,
               counters_before=dict(problem.counters()))


def inner_of(problem):
    """The problem's inner product of the constraint space (M), or the Euclidean one if it has none."""
    inner = getattr(problem, "inner", None)
    return inner if callable(inner) else (lambda a, b: float(np.vdot(a, b)))
