"""One measured contact run at a given size, in its own process (for peak memory).

    python -m admmkit.benchmarks.contact.scale_runs --example ex1 --h 1/500 --mode iterative

:func:`run_case` assembles the paper's Example 1 (or 2, or the 3D analogue of
Example 2, ``ex2_3d``) at mesh size h,
builds the contact problem in the requested mode and solves it with SADMM
(rho_0 = 1e3, the paper's stopping rule).  It reports wall times of the
phases and the process's peak resident memory (``resource.getrusage``,
ru_maxrss: everything the process held at its peak, Python, NGSolve and the
solver's C/C++ allocations included).  Run in a fresh process per size so
that the peak belongs to that size alone; :func:`run_in_subprocess` does
that.  A size whose memory estimate exceeds the available memory is refused
before anything is assembled.

With ``accuracy=True`` (``admmkit bench scale``) :func:`accuracy_at_stop` adds,
after the clock and the peak memory were read, what the computed solution is
worth: the ZZ estimate of its discretisation error, the last relative change
(the stop's quantity), its energy, and its algebraic error against a tight
solution of the same discrete problem: an interior-point reference up to
:data:`REFERENCE_MAX_N` unknowns, above that the same run continued from its
stop to a relative change of :data:`TIGHT_CHANGE`.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import time
from fractions import Fraction
from pathlib import Path

import numpy as np

EXAMPLES = ("ex1", "ex2", "ex2_3d")
RUN_MODES = ("full", "condensed", "iterative")
#: the tight reference (cvxpy + Clarabel, cross-checked by SADMM) up to this many unknowns: 17 s at 1.0e5
REFERENCE_MAX_N = 200_000
#: above it, the run is continued (warm start, same method and mode) to this relative change: at 1.0e5 unknowns
#: its algebraic error of the paper's stop, 7.4286e-05, agreed with the reference's 7.4240e-05
TIGHT_CHANGE = 1e-8
#: the child's environment: BLAS on one thread (small vector work dominates), and numpy's advice to back arrays
#: of 4 MB and more by transparent huge pages off (numpy's documented switch): on this project's machine (a VM,
#: THP in madvise mode) that advice made the 1e6-unknown case's set-up phases 2.5-3 s slower (assembly +0.4 s,
#: x-step set-up +1.1 s, AMG set-up +0.9 s; 18.0-18.5 s against 15.4-15.5 s, two runs each, 2bf734d) for
#: 0.2-0.4 s less in CG.  Users of large runs can set it the same way.
CHILD_ENVIRONMENT = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
                     "NUMPY_MADVISE_HUGEPAGE": "0"}


def environment_text() -> str:
    """The child processes' environment settings, as the reports state them."""
    return ", ".join(f"`{k}={v}`" for k, v in CHILD_ENVIRONMENT.items())


def peak_rss_bytes() -> int:
    """Peak resident set size of this process so far (Linux reports ru_maxrss in KiB)."""
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024


def accuracy_at_stop(ops, result, tight=None, reference_max: int | None = None) -> dict:
    """What the returned displacement u is worth, measured after the run (not in its times or peak memory).

    ``zz``: the ZZ estimate of the discretisation error ||u - u_h||_a (an estimate, not a bound);
    ``u_energy``: ||u_h||_a = sqrt(u'Ku); ``zz_rel`` their ratio; ``energy``: J(u_h) = u'Ku/2 - f'u;
    ``last_change``: the stop's quantity ||x^k - x^(k-1)|| / ||x^k|| at the last iteration;
    ``alg_error``: ||u_h - u*||_a / ||u*||_a against the tight reference u* of the same discrete problem
    (:func:`admmkit.problems.contact.validation.reference.reference_solution`) up to ``reference_max``
    unknowns (default :data:`REFERENCE_MAX_N`); above, against ``tight()``'s Result (the run continued to a
    tight stop), or NaN without it.  ``reference`` names the one used, ``reference_s`` its seconds.
    """
    from admmkit.problems.contact.solvers.estimate import zz_estimate
    from admmkit.problems.contact.validation.reference import energy, energy_norm, errors_against, reference_solution
    u = np.asarray(result.x)
    t0 = time.perf_counter()
    zz, norm = zz_estimate(ops, u), energy_norm(ops, u)
    rec = result.last_record
    out = {"zz": zz, "u_energy": norm, "zz_rel": zz / norm if norm > 0 else math.nan,
           "energy": energy(ops, u), "zz_s": time.perf_counter() - t0,
           "last_change": rec.x_change / rec.x_norm if rec is not None and rec.x_norm > 0 else math.nan,
           "alg_error": math.nan, "reference_s": math.nan, "reference": None}
    if ops.n_free <= (REFERENCE_MAX_N if reference_max is None else reference_max):
        ref = reference_solution(ops)
        out |= {"alg_error": errors_against(ops, ref, u, result.lam)["err_u_energy"], "reference": ref.solver,
                "reference_s": ref.seconds}
    elif tight is not None:
        t0 = time.perf_counter()
        ref = tight()
        out |= {"alg_error": energy_norm(ops, u - ref.x) / energy_norm(ops, ref.x),
                "reference_s": time.perf_counter() - t0,
                "reference": f"the run continued to relative change {TIGHT_CHANGE:g}: {ref.status.value}, "
                             f"{ref.iterations} more iterations"}
    return out


def run_case(example: str, h: float, mode: str, rho: float = 1e3, max_iter: int = 2000,
             accuracy: bool = False) -> dict:
    """Assemble, set up and solve one case; the figures of the run as a dict (and :func:`accuracy_at_stop`'s)."""
    import admmkit
    from admmkit import policies
    from admmkit import RelativeChange

    from admmkit.problems.contact.solvers.problem import contact_problem
    from admmkit.problems.contact.model.memory import InsufficientMemory, available_memory, memory_need
    from admmkit.problems.contact.model.scene import example1, example2

    if example not in EXAMPLES:
        raise ValueError(f"example must be one of {', '.join(EXAMPLES)}, got {example!r}")
    if mode not in RUN_MODES:
        raise ValueError(f"mode must be one of {', '.join(RUN_MODES)}, got {mode!r}")
    t0 = time.perf_counter()
    try:
        if example == "ex2_3d":
            from admmkit.problems.contact.model.assembly3d import assemble3d
            from admmkit.problems.contact.model.scene3d import example2_3d, memory_need3d
            scene = example2_3d(h=h)
            need, have = memory_need3d(scene, mode), available_memory()
        else:
            scene = (example1 if example == "ex1" else example2)(h=h)
            need, have = memory_need(scene, mode), available_memory()
    except InsufficientMemory as err:            # the scene itself refuses: not even the iterative mode fits now
        return {"example": example, "h": h, "mode": mode, "rho0": rho, "estimate_bytes": math.nan,
                "available_bytes": available_memory(), "status": "refused", "message": str(err)}
    row = {"example": example, "h": h, "mode": mode, "rho0": rho, "estimate_bytes": need, "available_bytes": have}
    if need > have:
        return row | {"status": "refused", "message": f"needs about {need / 2**30:.3g} GiB, "
                                                      f"{have / 2**30:.3g} GiB available"}
    from admmkit.problems.contact.model.assembly import assemble
    ops = assemble3d(scene) if example == "ex2_3d" else assemble(scene)
    t1 = time.perf_counter()
    problem = contact_problem(ops, mode=mode)
    t2 = time.perf_counter()
    sadmm_order, sadmm_rule = policies.method("sadmm")   # policies/paper_methods.py
    result = admmkit.solve(problem, rho=rho, policy=sadmm_rule, order=sadmm_order,
                           stop=RelativeChange(1e-5), max_iter=max_iter)
    t3 = time.perf_counter()
    kkt = result.kkt or {}
    row |= {"n_free": int(ops.n_free), "n_c": int(ops.n_c), "status": result.status.value,
            "iterations": int(result.iterations), "rho_changes": int(result.rho_changes),
            "counters": {k: int(v) for k, v in result.counters.items()},
            "assemble_s": t1 - t0, "setup_s": t2 - t1, "solve_s": t3 - t2, "total_s": t3 - t0,
            "x_step_s": result.timings["x_step"],
            "penetration": kkt.get("penetration"), "stationarity": kkt.get("stationarity"),
            "contact_force": kkt.get("contact_force"), "message": result.message,
            "max_un": float((ops.B @ result.x).max()),
            "peak_rss_bytes": peak_rss_bytes()}
    solver = getattr(problem, "solver", None)
    if solver is not None:
        row |= {"amg_setup_s": solver.setup_time, "amg_refresh_s": solver.refresh_time, "cg_s": solver.solve_time}
    if not accuracy:
        return row

    def tight():
        return admmkit.solve(problem, rho=result.rho, policy=sadmm_rule, order=sadmm_order,
                             stop=RelativeChange(TIGHT_CHANGE), max_iter=5 * max_iter, warm_start=result)
    t4 = time.perf_counter()
    row |= accuracy_at_stop(ops, result, tight)
    return row | {"accuracy_s": time.perf_counter() - t4}


def print_run(r: dict) -> None:
    """One progress line for a finished :func:`run_in_subprocess` case."""
    if r.get("status") == "converged":
        print(f"        n = {r['n_free']}  setup {r['setup_s']:.2f} s  SADMM {r['solve_s']:.2f} s  "
              f"({r['iterations']} it.)  peak {r['peak_rss_bytes'] / 1e9:.2f} GB", flush=True)
    else:
        print(f"        {r.get('status')}: {r.get('message', '')}", flush=True)


def run_in_subprocess(example: str, h: float, mode: str, timeout: float = 900.0, rho: float = 1e3,
                      accuracy: bool = False) -> dict:
    """run_case in a fresh Python process with BLAS pinned to one thread and without numpy's huge-page
    advice (:data:`CHILD_ENVIRONMENT`); timeouts are reported."""
    env = dict(os.environ, **CHILD_ENVIRONMENT)
    root = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = root + os.pathsep + env.get("PYTHONPATH", "")
    cmd = [sys.executable, "-m", "admmkit.benchmarks.contact.scale_runs", "--example", example, "--h", repr(h), "--mode", mode,
           "--rho", repr(rho)] + (["--accuracy"] if accuracy else [])
    start = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        return {"example": example, "h": h, "mode": mode, "status": "timeout",
                "message": f"no answer within {timeout:g} s", "wall_s": time.perf_counter() - start}
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        tail = (proc.stderr.strip().splitlines() or ["?"])[-1]
        return {"example": example, "h": h, "mode": mode, "status": "failed", "message": tail, "wall_s": wall}
    return json.loads(proc.stdout.strip().splitlines()[-1]) | {"wall_s": wall}


def main(argv=None) -> int:
    """Command line of the child process: one JSON line on stdout."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--example", default="ex1", choices=EXAMPLES)
    p.add_argument("--h", required=True, help="mesh size (fractions allowed)")
    p.add_argument("--mode", default="iterative", choices=RUN_MODES)
    p.add_argument("--rho", type=float, default=1e3)
    p.add_argument("--accuracy", action="store_true", help="add the ZZ estimate and the error against a reference")
    args = p.parse_args(argv)
    h = float(Fraction(args.h)) if "/" in args.h else float(args.h)
    from threadpoolctl import threadpool_limits
    with threadpool_limits(1):
        row = run_case(args.example, h, args.mode, rho=args.rho, accuracy=args.accuracy)
    print(json.dumps(row))
    return 0


if __name__ == "__main__":
    sys.exit(main())
