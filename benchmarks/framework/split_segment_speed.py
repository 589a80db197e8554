"""Time per iteration of the building blocks with and without their compiled segment (issue #25).

The problems of ``admmkit bench four-problems`` (LASSO, weighted box LS,
consensus, 2-D TV; TV also on a larger image), their x-step factorised by
qdldl, solved with OSQP's rule (rho every 50 iterations), the test every 25
iterations, alpha = 1.6, for a fixed number of iterations (a tolerance that
cannot fire).  ``solve(..., compiled=True)`` and ``compiled=False`` run
interleaved in one process, BLAS on one thread; each time is the minimum of
``--repeats`` runs of the loop (``result.timings["total"]``).  Both give the
same iterates bit for bit (tests/admmkit/test_split_segment.py), checked here
again.  Usage: ``admmkit bench split-speed --out DIR`` (README.md and split_speed.csv there).
"""
from __future__ import annotations


from admmkit.cli import Parser

import numpy as np
from admmkit.benchmarks.runner.costs import typical


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


def main(argv=None, prog: str = "admmkit bench split-speed") -> int:
    """Print and write (``--out``) a table of microseconds per iteration, compiled and in Python, and their ratio."""
    import shlex
    import sys
    import time
    from pathlib import Path
    parser = Parser(prog=prog, description=__doc__.splitlines()[0] +   # one-line usage errors (admmkit.cli)
                    typical("bench split-speed") + " needs: numba (installed with admmkit)")
    parser.add_argument("--out", default="out/split_speed", help="output folder (default ./out/split_speed/)")
    parser.add_argument("--iterations", type=int, default=2000, help="iterations per run (default 2000)")
    parser.add_argument("--repeats", type=int, default=5, help="runs of each; the minimum counts (default 5)")
    parser.add_argument("--tv-side", type=int, default=64, help="side of the larger TV image (default 64)")
    args = parser.parse_args(argv)
    if args.iterations < 100 or args.repeats < 1 or args.tv_side < 4:
        parser.error("--iterations must be >= 100, --repeats >= 1 and --tv-side >= 4")
    from threadpoolctl import threadpool_limits
    from admmkit.io import write_text
    from admmkit.benchmarks.runner.machine import machine_info
    from admmkit.benchmarks.runner.report import machine_markdown, write_csv
    command = prog + " " + " ".join(shlex.quote(a) for a in (argv if argv is not None else sys.argv[1:]))
    lines = ["| problem | n | us/iteration compiled | us/iteration Python | Python / compiled | compiled iterations |",
             "|---|---|---|---|---|---|"]
    rows, start = [], time.perf_counter()
    print("\n".join(lines), flush=True)
    with threadpool_limits(1):
        for name, problem in problems(args.tv_side).items():
            time_per_iteration(problem, 60, 1)                      # load the kernels, factorise
            fast, slow, done = time_per_iteration(problem, args.iterations, args.repeats)
            rows.append(dict(problem=name, n=problem.n, us_compiled=1e6 * fast, us_python=1e6 * slow,
                             ratio=slow / fast, compiled_iterations=done, iterations=args.iterations))
            lines.append(f"| {name} | {problem.n} | {1e6 * fast:.2f} | {1e6 * slow:.2f} | {slow / fast:.1f} | "
                         f"{done} of {args.iterations} |")
            print(lines[-1], flush=True)
    out = Path(args.out)
    write_csv(out / "split_speed.csv", rows, list(rows[0]), float_format=".6g")
    write_text(out / "README.md", "\n".join([
        "# The building blocks' compiled segment: time per iteration", "", f"Command: `{command}`", "",
        f"OSQP's rule, the test every 25 iterations, alpha 1.6, {args.iterations} iterations per run, the minimum "
        f"of {args.repeats} interleaved runs, BLAS on one thread; the same iterates bit for bit in both paths "
        f"(checked in every run). Wall time {time.perf_counter() - start:.0f} s.", "", *lines, "",
        machine_markdown(machine_info(pinned_blas=True))]) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
