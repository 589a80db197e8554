"""The ADMM loop: one function, both orders, any policy, composable stopping rules.

Order "xz" (the paper's ADMM1, Koko 2020)::

    x^{k+1}   = argmin_x L_rho_k(x, z^k; lam^k)
    z^{k+1}   = argmin_z L_rho_k(x^{k+1}, z; lam^k)
    lam^{k+1} = lam^k + rho_k (A x^{k+1} - z^{k+1} - c)

Order "zx" (the paper's ADMM2, Algorithm 1; with an adaptive policy, its SADMM,
Algorithm 2)::

    z^{k+1}   = argmin_z L_rho_k(x^k, z; lam^k)          eq. (11)/(14)
    x^{k+1}   = argmin_x L_rho_k(x, z^{k+1}; lam^k)      eq. (12)/(15)
    lam^{k+1} = lam^k + rho_k (A x^{k+1} - z^{k+1} - c)   eq. (13)/(16)

then rho_{k+1} = policy.update(record of iteration k)     eq. (17).
"""
from __future__ import annotations

import math
import time
from contextlib import ExitStack
from typing import Callable

import numpy as np

from .blas import limit_blas
from .history import History
from .policy import Policy, make_policy
from .problem import Problem
from .record import IterationRecord
from .result import Result, Status
from .stopping import RelativeChange, StoppingRule

ORDERS = {"xz": "xz", "zx": "zx", "admm1": "xz", "admm2": "zx"}


class _Fixed(Policy):
    """Keeps rho constant (used when no policy is given)."""

    def update(self, rec: IterationRecord) -> float:
        return rec.rho


@np.errstate(over="ignore", invalid="ignore")  # a blow-up ends as status 'diverged'
def solve(
    problem: Problem,
    *,
    rho: float = 1.0,
    policy: Policy | str | None = None,
    order: str = "xz",
    stop: StoppingRule | None = None,
    max_iter: int = 10_000,
    callback: Callable[[IterationRecord], bool | None] | None = None,
    x0: np.ndarray | None = None,
    z0: np.ndarray | None = None,
    lam0: np.ndarray | None = None,
    time_limit: float | None = None,
    blas_threads: int | None = 1,
) -> Result:
    """Run ADMM on ``problem`` and return a :class:`Result`.

    Parameters
    ----------
    problem : Problem
        The plug-in.
    rho : float
        Initial penalty rho_0, finite and > 0.
    policy : Policy, str or None
        A :class:`Policy` (reset at the start of the run), a registered
        name such as ``"summable"`` (after ``import policies``), or None to
        keep rho fixed.
    order : str
        ``"xz"`` (ADMM1: x-step first) or ``"zx"`` (ADMM2: z-step first).
    stop : StoppingRule or None
        A stopping rule; default the paper's ``RelativeChange(1e-5)``.
    max_iter : int
        Iteration cap, an integer >= 1.
    callback : callable or None
        Called with each :class:`IterationRecord`; returning True stops
        the run with status ``stopped``.
    x0, z0, lam0 : numpy.ndarray or None
        Starting point (default ``problem.initial_point()``).
    time_limit : float or None
        Optional wall-time limit in seconds (for benchmarks; it makes
        a run machine-dependent, so it never steers rho).
    blas_threads : int or None
        BLAS threads during the run (default 1; None leaves them
        alone).  The loop's vector work is small, and a multithreaded BLAS
        spends more in thread hand-off than it saves: on the 2-core machine
        of docs/results/linsolve.md, pinning cut the residual work of contact
        Example 2 (h = 1/40, condensed) from 114 to 29 microseconds an iteration.
    """
    order_key = _check_order(order)
    rho = _check_rho(rho, "rho")
    if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
        raise ValueError(f"max_iter must be an integer >= 1, got {max_iter!r}")
    if time_limit is not None and not (math.isfinite(time_limit) and time_limit > 0):
        raise ValueError(f"time_limit must be a finite number > 0 seconds or None, got {time_limit!r}")
    if blas_threads is not None and (isinstance(blas_threads, bool) or not isinstance(blas_threads, int) or blas_threads < 1):
        raise ValueError(f"blas_threads must be an integer >= 1 or None, got {blas_threads!r}")
    if callback is not None and not callable(callback):
        raise TypeError(f"callback must be callable or None, got {type(callback).__name__}")
    stop = RelativeChange(1e-5) if stop is None else stop
    if not isinstance(stop, StoppingRule):
        raise TypeError(f"stop must be a StoppingRule (e.g. RelativeChange(1e-5)), got {type(stop).__name__}")
    for name in ("x_step", "z_step", "apply_A"):
        if not callable(getattr(problem, name, None)):
            raise TypeError(f"problem must implement {name}() (see admmkit.Problem), got {type(problem).__name__}")
    policy = _make_policy(policy)

    x, z, lam = _starting_point(problem, x0, z0, lam0)
    Ax = np.asarray(problem.apply_A(x), dtype=float)
    if Ax.shape != z.shape or lam.shape != z.shape:
        raise ValueError(f"shapes do not match: A x0 has shape {Ax.shape}, z0 {z.shape}, lam0 {lam.shape}")
    c = problem.c
    has_adjoint = order_key == "xz" and _has_adjoint(problem, z)   # only order xz uses adjoint_norm
    if order_key == "xz" and "dual_residual" in policy.requires and not has_adjoint:
        raise ValueError(
            f"policy {policy!r} needs Boyd's dual residual, which for order 'xz' needs "
            f"{type(problem).__name__}.adjoint_norm(); use order 'zx' or implement it"
        )
    primal_unit = problem.norm(np.ones_like(z))
    dual_unit = math.sqrt(getattr(problem, "n", x.size)) if order_key == "xz" else primal_unit
    c_norm = problem.norm(np.broadcast_to(np.asarray(c, dtype=float), z.shape))

    policy.reset(rho)
    counters_before = dict(problem.counters())
    history = History()
    timings = dict(x_step=0.0, z_step=0.0, policy=0.0, residuals=0.0, total=0.0)
    status, message, stopped_by = Status.MAX_ITER, f"reached max_iter={max_iter}", None
    rho_changes = 0
    limits = ExitStack()
    if blas_threads is not None:
        limits.enter_context(limit_blas(blas_threads))   # a cached controller: ~15 us, not 0.5 ms
    start = time.perf_counter()
    for k in range(max_iter):
        try:
            if order_key == "xz":
                t0 = time.perf_counter()
                x_new = problem.x_step(z, lam, rho, x)
                Ax_new = problem.apply_A(x_new)
                t1 = time.perf_counter()
                z_new = problem.z_step(Ax_new, lam, rho, z)
                t2 = time.perf_counter()
                timings["x_step"] += t1 - t0
                timings["z_step"] += t2 - t1
            else:
                t0 = time.perf_counter()
                z_new = problem.z_step(Ax, lam, rho, z)            # eq. (11)
                t1 = time.perf_counter()
                x_new = problem.x_step(z_new, lam, rho, x)         # eq. (12)
                Ax_new = problem.apply_A(x_new)
                t2 = time.perf_counter()
                timings["z_step"] += t1 - t0
                timings["x_step"] += t2 - t1
        except (np.linalg.LinAlgError, ArithmeticError) as err:
            status, message = Status.DIVERGED, f"a step failed at iteration {k}: {err}"
            break

        t0 = time.perf_counter()
        r = Ax_new - z_new - c
        lam_new = lam + rho * r                                    # eq. (13)
        primal_residual = problem.norm(r)
        rho_Ax_change = rho * problem.norm(Ax_new - Ax)
        z_change = problem.norm(z_new - z)
        lam_norm = problem.norm(lam_new)
        if order_key == "xz":
            dual_residual = rho * problem.adjoint_norm(z_new - z) if has_adjoint else math.nan
            dual_scale = problem.adjoint_norm(lam_new) if has_adjoint else math.nan
        else:
            dual_residual, dual_scale = rho_Ax_change, lam_norm
        x_norm = problem.x_norm(x_new)
        rec = IterationRecord(
            k=k, rho=rho, order=order_key,
            primal_residual=primal_residual, dual_residual=dual_residual,
            rho_Ax_change=rho_Ax_change, lam_change=rho * primal_residual,
            x_change=problem.x_distance(x_new, x), x_norm=x_norm, z_change=z_change,
            primal_scale=max(problem.norm(Ax_new), problem.norm(z_new), c_norm),
            dual_scale=dual_scale, primal_unit=primal_unit, dual_unit=dual_unit,
            time=time.perf_counter() - start,
            x=_readonly(x_new), z=_readonly(z_new), lam=_readonly(lam_new), Ax=_readonly(Ax_new),
            z_prev=_readonly(z), Ax_prev=_readonly(Ax), inner=problem.inner,
        )
        timings["residuals"] += time.perf_counter() - t0
        x, z, lam, Ax = x_new, z_new, lam_new, Ax_new

        if not all(math.isfinite(v) for v in (primal_residual, x_norm, lam_norm, z_change)):
            history.append(rec, rho)
            status, message = Status.DIVERGED, f"non-finite iterate at iteration {k}"
            break
        stopped_by = stop.fired(rec)
        if stopped_by:
            history.append(rec, rho)
            status, message = Status.CONVERGED, f"{stopped_by} fired at iteration {k}"
            break
        if rec.x_change == 0 and z_change == 0 and primal_residual == 0:
            history.append(rec, rho)
            status, message = Status.STALLED, f"iterates stopped changing at iteration {k} before {stop.name} fired"
            break

        t0 = time.perf_counter()
        rho_next = policy.update(rec)                              # eq. (17)
        timings["policy"] += time.perf_counter() - t0
        history.append(rec, rho_next)
        if not (isinstance(rho_next, (float, int, np.floating, np.integer)) and math.isfinite(rho_next) and rho_next > 0):
            status, message = Status.DIVERGED, f"policy {policy!r} returned rho={rho_next!r} at iteration {k}"
            break
        if rho_next != rho:
            rho_changes += 1
        rho = float(rho_next)

        if callback is not None and callback(rec):
            status, message = Status.STOPPED, f"callback stopped the run at iteration {k}"
            break
        if time_limit is not None and time.perf_counter() - start > time_limit:
            status, message = Status.TIME_LIMIT, f"time_limit={time_limit:g} s reached at iteration {k}"
            break

    timings["total"] = time.perf_counter() - start
    limits.close()
    x_final = problem.finalize(x)
    counters_after = problem.counters()
    counters = {key: counters_after[key] - counters_before.get(key, 0) for key in counters_after}
    finite = status is not Status.DIVERGED
    return Result(
        x=x_final, z=z, lam=lam, status=status, message=message, stopped_by=stopped_by,
        iterations=len(history), rho=rho, history=history, timings=timings, rho_changes=rho_changes,
        counters=counters,
        kkt=problem.kkt(x_final, z, lam) if finite else None,
        objective=problem.objective(x_final, z) if finite else None,
        order=order_key, policy=repr(policy),
    )


def _check_rho(rho, name: str) -> float:
    try:
        value = float(rho)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a finite number > 0, got {rho!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {rho!r}")
    return value


def _check_order(order) -> str:
    key = str(order).lower()
    if key not in ORDERS:
        raise ValueError(f"order must be 'xz' (ADMM1, x-step first) or 'zx' (ADMM2, z-step first), got {order!r}")
    return ORDERS[key]


def _make_policy(policy) -> Policy:
    if policy is None:
        return _Fixed()
    if isinstance(policy, str):
        return make_policy(policy)
    if isinstance(policy, Policy):
        return policy
    raise TypeError(f"policy must be a Policy object, a registered name or None, got {type(policy).__name__}")


def _starting_point(problem, x0, z0, lam0):
    dx, dz, dlam = problem.initial_point()
    out = []
    for name, given, default in (("x0", x0, dx), ("z0", z0, dz), ("lam0", lam0, dlam)):
        v = np.array(default if given is None else given, dtype=float)
        if given is not None and v.shape != np.shape(default):
            raise ValueError(f"{name} must have shape {np.shape(default)}, got {v.shape}")
        if not np.all(np.isfinite(v)):
            raise ValueError(f"{name} must be finite")
        out.append(v)
    return out


def _has_adjoint(problem, z) -> bool:
    try:
        problem.adjoint_norm(np.zeros_like(z))
    except NotImplementedError:
        return False
    return True


def _readonly(v: np.ndarray) -> np.ndarray:
    view = v.view()
    view.flags.writeable = False
    return view
