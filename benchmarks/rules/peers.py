"""The peers a user would otherwise pick, run on the same discrete QP, timed the same way.

- ``clarabel``: cvxpy + Clarabel (interior point); time = building the cvxpy
  problem + ``prob.solve`` (what a user pays: canonicalisation included; the
  solver's own time is recorded as ``solver_time``).
- ``cvxpy-osqp``: cvxpy + OSQP, timed the same way.
- ``osqp``: OSQP called directly (setup with its KKT factorisation + solve).
- ``pdas``: the primal-dual active set baseline (:mod:`admmkit.benchmarks.rules.pdas`),
  contact and obstacle only; for contact it uses the same boundary Schur
  complement as ADMM's condensed mode, and its setup is timed with it.

Each interior-point / OSQP point is a separate solve at one tolerance of a
ladder (four tolerances; two above ``LARGE`` unknowns, where one solve takes minutes); PDAS gives one point per Newton step of one run (the time at that
step, the error of that step's iterate).  Times are medians over ``repeats``
(one repeat when the first takes longer than ``long_run`` seconds).
"""
from __future__ import annotations

import statistics
import time

import numpy as np
import scipy.sparse as sp

from admmkit.benchmarks.runner.machine import median_time
from admmkit.benchmarks.rules.families import Discrete
from admmkit.benchmarks.rules.references import clarabel_solve, cvxpy_duals, cvxpy_problem, pdas_form
from admmkit.benchmarks.runner.sweep import clean_float

PEERS = ("pdas", "clarabel", "cvxpy-osqp", "osqp")
LADDERS = {"clarabel": (1e-3, 1e-5, 1e-7, 1e-9),
           "cvxpy-osqp": (1e-2, 1e-4, 1e-6, 1e-8),
           "osqp": (1e-2, 1e-4, 1e-6, 1e-8)}
#: above this many unknowns every tolerance is a long solve: two rungs per peer
LARGE = 150_000
LADDERS_LARGE = {"clarabel": (1e-4, 1e-8), "cvxpy-osqp": (1e-3, 1e-6), "osqp": (1e-3, 1e-6)}


def applicable(peer: str, kind: str) -> bool:
    """PDAS needs one-sided constraints (contact, obstacle); the others take any QP."""
    return peer != "pdas" or kind in ("contact", "obstacle")


def _osqp_tolerances(d: Discrete, tol: float) -> dict:
    """eps_abs/eps_rel: relative only for the PDE problems (their units are physical), both for QPs."""
    return {"eps_abs": 0.0, "eps_rel": tol} if d.kind != "qp" else {"eps_abs": tol, "eps_rel": tol}


def run_peer(d: Discrete, peer: str, *, repeats: int = 3, long_run: float = 10.0, time_limit: float = 60.0,
             max_iter: int = 20_000) -> dict:
    """Run one peer on problem ``d``; return {"points": [...], ...} for the work-precision chart."""
    if peer == "pdas":
        return _run_pdas(d, repeats, long_run)
    points = []
    for tol in (LADDERS_LARGE if d.n > LARGE else LADDERS)[peer]:
        if peer == "clarabel":
            fn = lambda: _clarabel(d, tol)  # noqa: E731
        elif peer == "cvxpy-osqp":
            fn = lambda: _cvxpy_osqp(d, tol, time_limit, max_iter)  # noqa: E731
        else:
            fn = lambda: _osqp(d, tol, time_limit, max_iter)  # noqa: E731
        wall, t, times, (x, y, status, solver_time, iters) = median_time(fn, repeats, long_run)
        point = {"tol": tol, "time": t, "times": times, "wall": wall, "solver_time": clean_float(solver_time),
                 "iterations": iters, "status": status}
        if x is not None and np.all(np.isfinite(x)):
            point.update(d.errors(x, None if y is None else y / d.weights))
        points.append(point)
    return {"points": points}


def _clarabel(d: Discrete, tol: float):
    x, y, status, stats = clarabel_solve(d, tol)
    return x, y, status, getattr(stats, "solve_time", None), getattr(stats, "num_iters", None)


def _cvxpy_osqp(d: Discrete, tol: float, time_limit: float, max_iter: int):
    import cvxpy as cp

    prob, x, cons = cvxpy_problem(d)
    try:
        prob.solve(solver=cp.OSQP, max_iter=max_iter, time_limit=time_limit, **_osqp_tolerances(d, tol))
    except cp.error.SolverError as err:
        return None, None, f"solver error: {err}", None, None
    stats = prob.solver_stats
    if x.value is None:
        return None, None, prob.status, None, getattr(stats, "num_iters", None)
    return (np.asarray(x.value), cvxpy_duals(d, cons), prob.status, getattr(stats, "solve_time", None),
            getattr(stats, "num_iters", None))


def _osqp(d: Discrete, tol: float, time_limit: float, max_iter: int):
    import osqp

    solver = osqp.OSQP()
    solver.setup(P=sp.triu(d.P, format="csc"), q=d.q, A=d.A.tocsc(), l=d.l, u=d.u, verbose=False,
                 max_iter=max_iter, time_limit=time_limit, **_osqp_tolerances(d, tol))
    res = solver.solve()
    status = str(res.info.status)
    x = None if res.x is None else np.asarray(res.x, dtype=float)
    y = None if res.y is None else np.asarray(res.y, dtype=float)
    return x, y, status, float(res.info.run_time), int(res.info.iter)


def _run_pdas(d: Discrete, repeats: int, long_run: float) -> dict:
    from admmkit.benchmarks.rules.pdas import pdas

    K, f, B, g, to_lam = pdas_form(d)

    def once():
        t0, c0 = time.perf_counter(), time.process_time()
        kwargs = d.pdas_args()
        kwargs.pop("weights", None)
        t_args, c_args = time.perf_counter() - t0, time.process_time() - c0
        res = pdas(K, f, B, g, max_iter=200, keep_iterates=True, **kwargs)
        return (t_args, c_args), res

    runs, totals = [], []
    for i in range(repeats):
        t_args, res = once()
        runs.append((t_args, res))
        totals.append(t_args[0] + res.time)
        if totals[0] > long_run:
            break
    res = runs[-1][1]
    points = []
    for k, (u, mu) in enumerate(zip(res.iterates, res.multipliers)):
        step_times = [t[1] + r.history[k]["cpu"] for t, r in runs if k < len(r.history)]
        step_walls = [t[0] + r.history[k]["time"] for t, r in runs if k < len(r.history)]
        point = {"tol": None, "step": k + 1, "time": statistics.median(step_times), "times": step_times,
                 "wall": statistics.median(step_walls),
                 "iterations": k + 1, "status": res.status if k + 1 == res.iterations else "step",
                 "active": res.history[k]["active"], "changed": res.history[k]["changed"]}
        point.update(d.errors(u, to_lam(mu)))
        points.append(point)
    return {"points": points, "method": res.method, "status": res.status, "kkt": res.kkt,
            "setup_time": statistics.median([t[0] for t, _ in runs]) + res.setup_time,
            "total_time": statistics.median(totals)}
