"""Time per iteration of the building blocks with and without their compiled segment (issue #25).

The problems of ``admmkit bench four-problems`` (LASSO, weighted box LS,
consensus, 2-D TV; TV also on a larger image), their x-step factorised by
qdldl, solved with OSQP's rule (rho every 50 iterations), the test every 25
iterations, alpha = 1.6, for a fixed number of iterations (a tolerance that
cannot fire).  ``solve(..., compiled=True)`` and ``compiled=False`` run
interleaved in one process, BLAS on one thread; each time is the minimum of
``--repeats`` runs of the loop (``result.timings["total"]``).  Both give the
same iterates bit for bit (tests/admmkit/test_split_segment.py), checked here
again.  Usage: ``python benchmarks/framework/split_segment_speed.py``.
"""
from __future__ import annotations

import argparse

import numpy as np


def problems(tv_side: int):
    """name -> SplitProblem: the four problems with a qdldl x-step, and TV on a tv_side x tv_side image."""
    import admmkit
    from admmkit.benchmarks.framework import four_problems as fp
    out = {}
    makers = dict(fp.PROBLEMS, **{f"tv_2d_{tv_side}": lambda: fp.tv_denoise(side=tv_side)})
    for name, make in makers.items():
        problem = make()[0]
        f = problem.f
        problem.f = admmkit.QuadraticXStep(f.P, f.q, f.A, solver="direct", backend="qdldl")
        out[name] = problem
    return out


def time_per_iteration(problem, iterations: int, repeats: int) -> tuple[float, float, int]:
    """(seconds per iteration compiled, in Python, compiled iterations) over ``repeats`` interleaved runs."""
    import admmkit
    kw = dict(policy="osqp", check_every=25, alpha=1.6, max_iter=iterations,
              stop=admmkit.ResidualTolerance(1e-300, 1e-300))
    best = {True: np.inf, False: np.inf}
    for _ in range(repeats):
        runs = {flag: admmkit.solve(problem, compiled=flag, **kw) for flag in (True, False)}
        assert np.array_equal(runs[True].x, runs[False].x) and runs[True].iterations == runs[False].iterations
        for flag, res in runs.items():
            best[flag] = min(best[flag], res.timings["total"] / res.iterations)
    return best[True], best[False], runs[True].counters.get("compiled_iterations", 0)


def main(argv=None) -> int:
    """Print a table of microseconds per iteration, compiled and in Python, and their ratio."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=2000, help="iterations per run (default 2000)")
    parser.add_argument("--repeats", type=int, default=5, help="runs of each; the minimum counts (default 5)")
    parser.add_argument("--tv-side", type=int, default=64, help="side of the larger TV image (default 64)")
    args = parser.parse_args(argv)
    from threadpoolctl import threadpool_limits
    print("| problem | n | us/iteration compiled | us/iteration Python | Python / compiled | compiled iterations |")
    print("|---|---|---|---|---|---|")
    with threadpool_limits(1):
        for name, problem in problems(args.tv_side).items():
            time_per_iteration(problem, 60, 1)                      # load the kernels, factorise
            fast, slow, done = time_per_iteration(problem, args.iterations, args.repeats)
            print(f"| {name} | {problem.n} | {1e6 * fast:.2f} | {1e6 * slow:.2f} | {slow / fast:.1f} | "
                  f"{done} of {args.iterations} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
