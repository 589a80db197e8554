"""``admmkit bench anderson-cost``: what an Anderson step adds to an iteration of the compiled QP segment.

    admmkit bench anderson-cost --out out/anderson_cost

Issue #50 asks Anderson acceleration on the compiled path to cost at most 1.3x
a plain iteration.  For each problem, ``solve_qp`` runs plain and with
``acceleration="anderson"`` (memory 10, the safeguard of
:mod:`admmkit.loop.acceleration`), both compiled, in turn, ``--repeat`` times;
the figure is the loop time per iteration (``timings["total"] / iterations``,
the best of the runs): setup, scaling and the first factorisation are left out,
and so is the difference in iteration counts, which the table gives apart
(``iterations ratio``).  BLAS on one thread, kernels compiled or loaded before
the first timing.  The default problems are the seven of docs/qp.md's table.
"""
from __future__ import annotations

import math
import os
import shlex
import sys
import time
from pathlib import Path

from admmkit.cli import Parser

#: the problems of docs/qp.md's Anderson table: small sparse ones, where Anderson's passes cost most, and larger
PROBLEMS = ("CVXQP1_S", "QADLITTL", "DUAL2", "PRIMAL1", "HS118", "CVXQP2_M", "HS268")
COLUMNS = ("problem", "n", "m", "eps", "plain_iterations", "anderson_iterations", "plain_us", "anderson_us",
           "cost_ratio", "iterations_ratio", "plain_status", "anderson_status")


def _run(qp, eps: float, max_iter: int, acceleration):
    """One compiled solve: (status, iterations, loop seconds)."""
    from admmkit.problems.qp import solve_qp
    res = solve_qp(qp, eps_abs=eps, eps_rel=eps, max_iter=max_iter, acceleration=acceleration)
    return res.termination or res.status.value, res.iterations, res.timings["total"]


def measure(qp, name: str, eps: float, max_iter: int, repeat: int) -> dict:
    """Plain and Anderson on one problem, taken in turn ``repeat`` times; the best loop time per iteration."""
    best = {}
    for _ in range(repeat):
        for key, acceleration in (("plain", None), ("anderson", "anderson")):
            status, iterations, loop = _run(qp, eps, max_iter, acceleration)
            per = loop / max(iterations, 1)
            if key not in best or per < best[key][2]:
                best[key] = (status, iterations, per)
    (ps, pi, pt), (as_, ai, at) = best["plain"], best["anderson"]
    return {"problem": name, "n": qp.n, "m": qp.m, "eps": eps, "plain_iterations": pi, "anderson_iterations": ai,
            "plain_us": 1e6 * pt, "anderson_us": 1e6 * at, "cost_ratio": at / pt,
            "iterations_ratio": ai / pi if pi else float("nan"), "plain_status": ps, "anderson_status": as_}


def main(argv=None, prog: str = "admmkit bench anderson-cost") -> int:
    """Run the study, print the table and write anderson_cost.csv and README.md under --out."""
    from admmkit.benchmarks.runner.costs import typical
    parser = Parser(prog=prog, description=__doc__.splitlines()[0] + typical("bench anderson-cost")
                    + " needs: numba, the Maros-Meszaros MAT files (--data)")
    from .qp_fidelity import DEFAULT_DATA, check_problems
    parser.add_argument("--data", default=str(DEFAULT_DATA), help="folder of Maros-Meszaros MAT files")
    parser.add_argument("--out", default="out/anderson_cost", help="output folder (default ./out/anderson_cost/)")
    parser.add_argument("--problems", nargs="+", default=list(PROBLEMS),
                        help=f"problems (default: {' '.join(PROBLEMS)})")
    parser.add_argument("--eps", type=float, default=1e-6, help="eps_abs = eps_rel (default 1e-6)")
    parser.add_argument("--max-iter", type=int, default=4000, help="iteration cap (default 4000, OSQP's)")
    parser.add_argument("--repeat", type=int, default=3, help="runs per configuration, the best kept (default 3)")
    args = parser.parse_args(argv)
    if not (0 < args.eps < math.inf) or args.max_iter < 1 or args.repeat < 1:
        parser.error("--eps must be a positive finite number, --max-iter and --repeat integers >= 1")
    from admmkit.benchmarks.runner.harness import require
    require(prog.removeprefix("admmkit "), "numba")          # the compiled path is what is measured
    check_problems(Path(args.data), args.problems)
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    import numpy as np
    from threadpoolctl import threadpool_limits
    from admmkit.io import write_text
    from admmkit.problems.qp import load_mat, random_qp
    from admmkit.benchmarks.runner.machine import machine_info
    from admmkit.benchmarks.runner.report import machine_markdown, write_csv
    command = prog + " " + " ".join(shlex.quote(a) for a in (argv if argv is not None else sys.argv[1:]))
    t0 = time.perf_counter()
    warm = random_qp(5, 5)
    for acceleration in (None, "anderson"):                  # compile or load every kernel before timing
        _run(warm, 1e-3, 100, acceleration)
    print(f"kernels ready in {time.perf_counter() - t0:.2f} s", flush=True)
    rows = []
    with threadpool_limits(1):
        for i, name in enumerate(args.problems):
            row = measure(load_mat(Path(args.data) / f"{name}.mat"), name, args.eps, args.max_iter, args.repeat)
            rows.append(row)
            print(f"[{i + 1}/{len(args.problems)}] {name}: plain {row['plain_us']:.2f} us/it, Anderson "
                  f"{row['anderson_us']:.2f} us/it, {row['cost_ratio']:.2f}x", flush=True)
    out = Path(args.out)
    write_csv(out / "anderson_cost.csv", rows, list(COLUMNS), float_format=".6g")
    ratios = np.array([r["cost_ratio"] for r in rows])
    lines = ["| problem | n | m | plain us/it | Anderson us/it | cost ratio | iterations (plain / Anderson) | status |",
             "|---|---:|---:|---:|---:|---:|---|---|"]
    lines += [f"| {r['problem']} | {r['n']} | {r['m']} | {r['plain_us']:.2f} | {r['anderson_us']:.2f} | "
              f"**{r['cost_ratio']:.2f}** | {r['plain_iterations']} / {r['anderson_iterations']} | "
              f"{r['plain_status']} / {r['anderson_status']} |" for r in rows]
    text = "\n".join([
        "# Anderson on the compiled QP path: cost per iteration", "", f"Command: `{command}`", "",
        f"Loop time per iteration (best of {args.repeat}, taken in turn), eps {args.eps:g}, memory 10, "
        "compiled segment, BLAS on one thread.", "", *lines, "",
        f"Cost ratio Anderson / plain: median **{float(np.median(ratios)):.2f}**, max {float(ratios.max()):.2f} "
        "(issue #50's target: at most 1.3).", "", machine_markdown(machine_info(pinned_blas=True))]) + "\n"
    write_text(out / "README.md", text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
