"""``admmkit bench loop-overhead``: what admmkit.solve costs on top of the ADMM algorithm itself.

The problem is the README's 1-D obstacle problem, min 1/2 x'Dx - b'x subject
to x <= g, with D = diag(d), d log-spaced in [1e-6, 1] (slow components, so
that the iterates keep moving for thousands of iterations, SADMM's too).  The stopping rules
are given tolerances that cannot fire before the iterates stop changing; a
run that reaches a fixed point earlier ends there, and the other loops of that
configuration are timed for the same number of iterations (the table shows
the count).  For each size n and configuration the command times,
interleaved in one process with BLAS on one thread:

- ``bare``: a hand-written loop of the same updates (the problem's z_step,
  x_step, apply_A, then lam + rho (Ax - z)), order zx, no bookkeeping, no norms;
- ``hand``: the same ALGORITHM written by hand (:func:`hand_residual`,
  :func:`hand_sadmm`): the same updates plus exactly the numbers that the
  configuration's stopping rule and policy read, computed inline (Boyd's test:
  ||r||, ||Ax||, ||z||, ||lam|| and rho ||Ax - Ax_prev|| on test iterations;
  SADMM: rho ||r|| and rho ||Ax - Ax_prev|| every iteration, the summable rule in
  plain Python, ||x - x_prev|| and ||x|| on test iterations), a previous vector
  kept only when it is needed, lam^{k+1} written in place into r once ||r||
  is taken (the fastest of the hand-written forms tried); it ends at the same iteration with the same x and rho
  as admmkit (tests/benchmarks/test_loop_overhead.py checks this);
- ``inline``: the bare updates written out in numpy (no method calls, no copy
  in apply_A), for reference (CSV only);
- admmkit.solve (its loop, ``result.timings["total"]``; the once-per-run set-up
  and finish are reported separately): fixed rho with Boyd's residual test, and
  the paper's SADMM (order zx, policy "summable", RelativeChange), each with the
  test every iteration and every 25.

The targets of issue #14 (loop overhead <= 10 us per iteration at n = 10,
<= 15 % at n = 1e5 and 1e6) are judged against ``hand``: overhead =
(admmkit - hand) / iterations, in % of ``hand``.  The norms a rule reads are
part of the algorithm, not the framework's bookkeeping: any loop that runs
SADMM or tests Boyd's residuals computes them, so they are in the comparator.
The overhead against ``bare`` (which includes the cost of those norms) is
shown beside it.  Each time is the minimum over ``--repeats`` runs.
"""
from __future__ import annotations

import os
import shlex
import sys
import time
from pathlib import Path

import numpy as np

from admmkit.cli import Parser
from admmkit.io import write_text

from admmkit.benchmarks.runner.report import write_csv
from admmkit.benchmarks.framework.loop_hand import bare, hand_residual, hand_sadmm, inline
from admmkit.benchmarks.runner.costs import typical

class Obstacle1D:
    """The README's problem, written against admmkit.Problem (no adjoint_norm, Euclidean norms)."""

    def __init__(self, n: int):
        import admmkit

        class _P(admmkit.Problem):
            def __init__(self, d, b, g):
                self.d, self.b, self.g, self.n = d, b, g, len(d)

            def x_step(self, z, lam, rho, x):
                return (self.b - lam + rho * z) / (self.d + rho)

            def z_step(self, Ax, lam, rho, z):
                return np.minimum(self.g, Ax + lam / rho)

            def apply_A(self, x):
                return x.copy()

        rng = np.random.default_rng(0)
        self.problem = _P(np.logspace(-6, 0, n), rng.uniform(-1, 2, n), np.ones(n))


CONFIGS = {
    "fixed rho, ResidualTolerance, check every 1": dict(policy=None, stop="residual", check_every=1),
    "fixed rho, ResidualTolerance, check every 25": dict(policy=None, stop="residual", check_every=25),
    "SADMM (summable, RelativeChange), check every 1": dict(policy="summable", stop="relchange", check_every=1),
    "SADMM (summable, RelativeChange), check every 25": dict(policy="summable", stop="relchange", check_every=25),
}


def run_hand(problem, config: dict, iterations: int) -> tuple[float, int, np.ndarray, float]:
    """The hand-written algorithm of ``config`` (rho_0 = 1, the never-firing tolerances of run_admmkit):
    seconds, iterations, final x and final rho."""
    if config["policy"] is None:
        seconds, its, x = hand_residual(problem, 1.0, iterations, config["check_every"])
        return seconds, its, x, 1.0
    return hand_sadmm(problem, 1.0, iterations, config["check_every"])


def run_admmkit(problem, config: dict, iterations: int):
    """admmkit.solve (order zx, rho_0 = 1) with tolerances that never fire before the iterates stop changing:
    seconds of its loop, its iteration count, the seconds of the whole call (the difference is the
    once-per-run set-up and finish: checks, policy reset, result, KKT) and the result."""
    import admmkit
    from admmkit import policies

    stop = (admmkit.ResidualTolerance(1e-300, 1e-300) if config["stop"] == "residual"
            else admmkit.RelativeChange(1e-300))
    start = time.perf_counter()
    res = admmkit.solve(problem, rho=1.0, order="zx", policy=config["policy"], stop=stop, max_iter=iterations,
                        check_every=config["check_every"], blas_threads=None)
    return res.timings["total"], res.iterations, time.perf_counter() - start, res


def measure(n: int, iterations: int, repeats: int) -> list[dict]:
    """Rows of the table for one size: per-iteration times and overheads.

    Every configuration is timed with its own bare, inline and hand-written loops of the same
    iteration count, all interleaved; each figure is the minimum over ``repeats``.  The
    hand-written algorithm must end where admmkit does, with the same x and rho.
    """
    problem = Obstacle1D(n).problem
    rows = []
    for name, config in CONFIGS.items():
        best = {"admmkit": np.inf, "bare": np.inf, "inline": np.inf, "hand": np.inf, "call": np.inf}
        for _ in range(repeats):
            seconds, its, call, res = run_admmkit(problem, config, iterations)
            best["admmkit"] = min(best["admmkit"], seconds / its)
            best["call"] = min(best["call"], call - seconds)
            hand_s, hand_its, hand_x, hand_rho = run_hand(problem, config, iterations)
            if hand_its != its or hand_rho != res.rho or not np.array_equal(hand_x, res.x_iterate):
                raise RuntimeError(f"{name}, n={n}: the hand-written algorithm ({hand_its} iterations, rho "
                                   f"{hand_rho!r}) differs from admmkit ({its}, rho {res.rho!r})")
            best["hand"] = min(best["hand"], hand_s / its)
            best["bare"] = min(best["bare"], bare(problem, 1.0, its) / its)
            best["inline"] = min(best["inline"], inline(problem, 1.0, its) / its)
        vs_bare, vs_hand = best["admmkit"] - best["bare"], best["admmkit"] - best["hand"]
        pct_hand = 100 * vs_hand / best["hand"]
        rows.append({"n": n, "iterations": its, "configuration": name,
                     "bare_us": 1e6 * best["bare"], "inline_us": 1e6 * best["inline"], "hand_us": 1e6 * best["hand"],
                     "admmkit_us": 1e6 * best["admmkit"],
                     "overhead_vs_bare_us": 1e6 * vs_bare, "overhead_pct_of_bare": 100 * vs_bare / best["bare"],
                     "norms_read_us": 1e6 * (best["hand"] - best["bare"]),
                     "overhead_vs_hand_us": 1e6 * vs_hand, "overhead_pct_of_hand": pct_hand,
                     "per_run_setup_us": 1e6 * best["call"],
                     "target": "<= 10 us" if n <= 10 else "<= 15 %",
                     "met": (1e6 * vs_hand <= 10) if n <= 10 else (pct_hand <= 15)})
    return rows


def steady_allocator() -> bool:
    """Ask glibc to keep freed memory (no heap trimming, no mmap below 32 MB); True if it agreed.

    Without this, whether a freed 0.8 MB array goes back to the OS (and the next
    one page-faults) depends on the order of allocations, and the bare loop
    measured 30-50 % slower than the same updates inside admmkit.solve.  The
    setting applies to every loop of the run alike.
    """
    try:
        import ctypes
        libc = ctypes.CDLL("libc.so.6")
        return bool(libc.mallopt(-1, 1 << 30)) and bool(libc.mallopt(-3, 32 << 20))   # M_TRIM_, M_MMAP_THRESHOLD
    except (OSError, AttributeError):
        return False


def main(argv=None, prog: str = "admmkit bench loop-overhead") -> int:
    """Run the benchmark, print the table and write loop_overhead.csv and loop_overhead.md under --out."""
    parser = Parser(prog=prog, description=__doc__.splitlines()[0] +   # one-line usage errors (admmkit.cli)
                    typical("bench loop-overhead") + " needs: numpy (nothing beyond admmkit)")
    parser.add_argument("--out", default="out/loop_overhead", help="output folder (default ./out/loop_overhead/)")
    parser.add_argument("--sizes", default="10,100000,1000000", help="comma-separated n (default 10,1e5,1e6)")
    parser.add_argument("--iterations", default="3000,3000,300",
                        help="iterations per size, one per size or one for all (default 3000,3000,300)")
    parser.add_argument("--repeats", type=int, default=5, help="runs of each loop; the minimum counts (default 5)")
    args = parser.parse_args(argv)
    sizes = [int(float(s)) for s in args.sizes.split(",")]
    its = [int(float(s)) for s in args.iterations.split(",")]
    if len(its) == 1:
        its = its * len(sizes)
    if len(its) != len(sizes) or min(sizes) < 1 or min(its) < 1 or args.repeats < 1:
        parser.error("--sizes and --iterations must be positive and of the same length (or one iteration count)")
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    from threadpoolctl import threadpool_limits
    steady = steady_allocator()
    command = prog + " " + " ".join(shlex.quote(a) for a in (argv if argv is not None else sys.argv[1:]))
    rows = []
    load_before = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    with threadpool_limits(1):                             # BLAS on one thread for every loop alike
        for n, k in zip(sizes, its):
            rows.extend(measure(n, k, args.repeats))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "loop_overhead.csv", rows)
    lines = ["# Loop overhead of admmkit.solve (1-D obstacle problem, order zx, BLAS 1 thread)", "",
             f"Command: `{command}`", "",
             f"Machine load (1-minute average, {os.cpu_count()} CPUs): {load_before[0]:.1f} at the start, "
             f"{(os.getloadavg() if hasattr(os, 'getloadavg') else (float('nan'),))[0]:.1f} at the end "
             "(other jobs share the machine; the loops are interleaved so that they share the load).", "",
             "**The targets of issue #14 (<= 10 us per iteration at n = 10, <= 15 % at n = 1e5 and 1e6) are "
             "judged against the hand-written algorithm** (`hand`): the same updates plus exactly the norms "
             "the configuration's stopping rule and policy read, computed inline, and SADMM's rule in plain "
             "Python. The norms a rule reads are part of the algorithm, not the framework's bookkeeping: any "
             "loop that runs SADMM or tests Boyd's residuals must compute them. `hand` ends at the same "
             "iteration with the same x and rho as admmkit (checked in every repeat). The overhead against "
             "`bare` (the updates alone, no norms) is shown beside it; `hand - bare` is what the norms cost.", "",
             f"glibc heap trimming off: {'yes' if steady else 'no (not glibc)'}; "
             "each figure the minimum of the repeats, all measured interleaved in one process. "
             "admmkit us/it is the loop (`result.timings['total']`); the once-per-run set-up and finish of "
             "`solve` (checks, policy reset, the result and its KKT check) is in the CSV (`per_run_setup_us`), "
             "as is `inline` (the bare updates written out in numpy).", "",
             "| n | configuration | iterations | bare us/it | hand us/it | admmkit us/it "
             "| overhead vs bare us/it (%) | overhead vs hand us/it (%) | target (vs hand) | met |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['n']:g} | {r['configuration']} | {r['iterations']} | {r['bare_us']:.2f} | "
                     f"{r['hand_us']:.2f} | {r['admmkit_us']:.2f} | {r['overhead_vs_bare_us']:.2f} "
                     f"({r['overhead_pct_of_bare']:.1f} %) | {r['overhead_vs_hand_us']:.2f} "
                     f"({r['overhead_pct_of_hand']:.1f} %) | {r['target']} | {'yes' if r['met'] else 'NO'} |")
    text = "\n".join(lines) + "\n"
    write_text(out / "loop_overhead.md", text)
    print(text)
    print(f"wrote {out / 'loop_overhead.csv'} and {out / 'loop_overhead.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(prog="python benchmarks/framework/loop_overhead.py"))
