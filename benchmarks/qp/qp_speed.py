"""``admmkit bench qp-speed``: a whole QP solve, admmkit against OSQP 1.x's C, problem by problem.

    admmkit bench qp-speed --max-size 3000 --out docs/results/qp_speed

What a user of the plug-in waits for, from the arrays to the answer, for every
convex Maros-Meszaros problem with n + m <= ``--max-size``:

- ``osqp``: ``osqp.OSQP().setup(...)`` then ``solve()`` (OSQP 1.x, deterministic:
  rho every 50 iterations, the test every 25, the gap test on, no polishing);
- ``admmkit``: ``QP(P, q, A, l, u)`` then ``solve_qp(qp)`` with the OSQP preset,
  the iterations between checks in the compiled segment (:mod:`admmkit.loop.segments`);
- ``admmkit-python``: the same with ``compiled=False`` (every iteration in Python).

Each is timed whole (``perf_counter`` around construction and solve), the best
of ``--repeat`` runs taken in turn, in one process with BLAS on one thread;
the loop alone too (OSQP's ``solve_time``, admmkit's ``timings["total"]``).
The numba kernels are compiled (or loaded from numba's cache) before the
first timing; that one-off time is reported apart.  The summary gives the
ratios admmkit / OSQP over the problems both solve with the same iteration
count, for small (n + m < 1000) and larger problems.
"""
from __future__ import annotations


from admmkit.cli import Parser
import math
import os
import shlex
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from .qp_fidelity import DEFAULT_DATA, check_problems, select
from admmkit.benchmarks.runner.costs import typical

CONFIGS = ("osqp", "admmkit", "admmkit-python")
COLUMNS = ("problem", "n", "m", "eps", "solver", "status", "iterations", "whole_ms", "loop_ms", "ratio_whole",
           "ratio_loop")
SMALL = 1000
LARGE = 5000


def _osqp(P, q, A, l, u, eps: float, max_iter: int):
    import osqp
    t0 = time.perf_counter()
    solver = osqp.OSQP()
    solver.setup(sp.triu(P, format="csc"), q, A, l, u, verbose=False, polishing=False, eps_abs=eps, eps_rel=eps,
                 max_iter=max_iter, adaptive_rho=1, adaptive_rho_interval=50, check_termination=25,
                 check_dualgap=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = solver.solve()
    whole = time.perf_counter() - t0
    return res.info.status, res.info.iter, whole, res.info.solve_time


def _admmkit(P, q, A, l, u, eps: float, max_iter: int, compiled: bool):
    from admmkit.problems.qp import QP, solve_qp
    t0 = time.perf_counter()
    res = solve_qp(QP(P, q, A, l, u), eps_abs=eps, eps_rel=eps, max_iter=max_iter, compiled=compiled)
    whole = time.perf_counter() - t0
    return res.termination or res.status.value, res.iterations, whole, res.timings["total"]


def measure(name: str, data: Path, eps: float, max_iter: int, repeat: int) -> list[dict]:
    """The three configurations on one problem, each the best of ``repeat`` runs taken in turn."""
    from admmkit.problems.qp import load_mat
    qp = load_mat(data / f"{name}.mat")
    P, q, A, l, u = qp.P, qp.q, qp.A, qp.l, qp.u
    runs = {"osqp": lambda: _osqp(P, q, A, l, u, eps, max_iter),
            "admmkit": lambda: _admmkit(P, q, A, l, u, eps, max_iter, True),
            "admmkit-python": lambda: _admmkit(P, q, A, l, u, eps, max_iter, False)}
    best: dict[str, tuple] = {}
    for _ in range(repeat):
        for config in CONFIGS:
            out = runs[config]()
            if config not in best or out[2] < best[config][2]:
                best[config] = out
    base = best["osqp"]
    rows = []
    for config in CONFIGS:
        status, iterations, whole, loop = best[config]
        rows.append({"problem": name, "n": qp.n, "m": qp.m, "eps": eps, "solver": config, "status": status,
                     "iterations": iterations, "whole_ms": 1e3 * whole, "loop_ms": 1e3 * loop,
                     "ratio_whole": whole / base[2], "ratio_loop": (loop / iterations) / (base[3] / base[1])
                     if iterations and base[1] and base[3] > 0 else float("nan")})
    return rows


def _stats(values) -> str:
    if not values:
        return "none"
    v = np.sort(np.asarray(values))
    return (f"median {np.median(v):.2f} (p10 {np.percentile(v, 10):.2f}, p90 {np.percentile(v, 90):.2f}, "
            f"max {v[-1]:.2f}; {len(v)} problems)")


def comparable(rows: list[dict]) -> dict[str, dict]:
    """Per problem and eps: the rows of the three configurations, kept where all solved with the same iterations."""
    by: dict[tuple, dict] = {}
    for r in rows:
        by.setdefault((r["problem"], r["eps"]), {})[r["solver"]] = r
    return {k: v for k, v in by.items() if len(v) == len(CONFIGS)
            and all(r["status"] == "solved" for r in v.values())
            and len({r["iterations"] for r in v.values()}) == 1}


GROUPS = ((f"n + m < {SMALL}", lambda size: size < SMALL), (f"{SMALL} <= n + m < {LARGE}", lambda size: SMALL <= size < LARGE),
          (f"n + m >= {LARGE}", lambda size: size >= LARGE), ("all", lambda size: True))


def summarise(rows: list[dict]) -> list[str]:
    """Markdown lines: per eps, the ratios admmkit / OSQP, whole solve and loop per iteration, by size."""
    same = comparable(rows)
    lines = [f"Problems solved by all three with the same iteration count: {len(same)} "
             f"(of {len({(r['problem'], r['eps']) for r in rows})} problem and eps pairs)."]
    for eps in sorted({r["eps"] for r in rows}, reverse=True):
        lines += ["", f"## eps = {eps:g}", "",
                  "| admmkit / OSQP | problems | whole solve, compiled | whole solve, Python | loop per iteration, "
                  "compiled | loop per iteration, Python |", "|---|---|---|---|---|---|"]
        for label, keep in GROUPS:
            group = [v for (_, e), v in same.items() if e == eps and keep(v["osqp"]["n"] + v["osqp"]["m"])]
            if not group and label != "all":
                continue
            cells = [_stats([v[c][key] for v in group]) for key in ("ratio_whole", "ratio_loop")
                     for c in ("admmkit", "admmkit-python")]
            lines.append(f"| {label} | {len(group)} | {cells[0]} | {cells[1]} | {cells[2]} | {cells[3]} |")
    return lines


def plot(rows: list[dict], path: Path) -> None:
    """Whole-solve ratio admmkit / OSQP against n + m, compiled and Python, on a log scale, one panel per eps."""
    from admmkit.figures import save_figure
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FormatStrFormatter, LogLocator, NullFormatter
    same = comparable(rows)
    epss = sorted({e for (_, e) in same}, reverse=True) or [None]
    fig, axes = plt.subplots(1, len(epss), figsize=(5.2 * len(epss), 4.2), sharey=True, squeeze=False)
    for ax, eps in zip(axes[0], epss):
        cases = [v for (_, e), v in same.items() if e == eps]
        for config, marker in (("admmkit-python", "x"), ("admmkit", "o")):
            ratios = [v[config]["ratio_whole"] for v in cases]
            ax.scatter([v["osqp"]["n"] + v["osqp"]["m"] for v in cases], ratios, marker=marker, s=18,
                       label=f"{config} (median {np.median(ratios) if ratios else float('nan'):.2f}x)")
        ax.axhline(1, color="k", lw=0.8)
        ax.axhline(2, color="k", lw=0.8, ls="--", label="2x OSQP")
        ax.set(xscale="log", yscale="log", xlabel="n + m", title=f"eps = {eps:g}" if eps else "")
        for axis in (ax.xaxis, ax.yaxis):                 # labels at 1, 2, 5 x 10^k, none crowded on a narrow decade
            axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
            axis.set_major_formatter(FormatStrFormatter("%g"))
            axis.set_minor_formatter(NullFormatter())
        ax.legend(fontsize=8)
    axes[0][0].set_ylabel("whole solve time / OSQP's")
    fig.suptitle("A whole QP solve against OSQP 1.x (Maros-Meszaros, same iterations)", fontsize=10)
    save_figure(fig, path)
    plt.close(fig)


def main(argv=None, prog: str = "admmkit bench qp-speed") -> int:
    """Run the study, print the summary and write qp_speed.csv, qp_speed.png and README.md under --out."""
    parser = Parser(prog=prog, description=__doc__.splitlines()[0] +   # one-line usage errors (admmkit.cli)
                    typical("bench qp-speed") + " needs: osqp, the Maros-Meszaros MAT files (--data)")
    parser.add_argument("--data", default=str(DEFAULT_DATA), help="folder of Maros-Meszaros MAT files")
    parser.add_argument("--out", default="out/qp_speed", help="output folder (default ./out/qp_speed/)")
    parser.add_argument("--max-size", type=int, default=3000, help="largest n + m (default 3000)")
    parser.add_argument("--min-size", type=int, default=0, help="smallest n + m (default 0)")
    parser.add_argument("--problems", nargs="*", help="only these problems")
    parser.add_argument("--eps", type=float, nargs="+", default=[1e-3, 1e-6],
                        help="eps_abs = eps_rel, one study each (default 1e-3 1e-6)")
    parser.add_argument("--max-iter", type=int, default=4000, help="iteration cap (default 4000, OSQP's)")
    parser.add_argument("--repeat", type=int, default=3, help="runs per configuration, the best kept (default 3)")
    args = parser.parse_args(argv)
    if args.max_size < 1 or args.min_size < 0 or not all(0 < e < math.inf for e in args.eps) or args.max_iter < 1 \
            or args.repeat < 1:
        parser.error("--max-size, --eps, --max-iter and --repeat must be positive, --min-size >= 0 (and --eps finite)")
    from admmkit.benchmarks.runner.harness import require
    require(prog.removeprefix("admmkit "), "osqp")        # the other solver of the comparison
    check_problems(Path(args.data), args.problems)
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    from threadpoolctl import threadpool_limits
    from admmkit.io import write_text
    from admmkit.problems.qp import random_qp
    from admmkit.problems.qp.mat import read_matrices
    from admmkit.benchmarks.runner.machine import machine_info
    from admmkit.benchmarks.runner.report import machine_markdown, write_csv
    data, out = Path(args.data), Path(args.out)
    command = prog + " " + " ".join(shlex.quote(a) for a in (argv if argv is not None else sys.argv[1:]))
    chosen = []
    for name, _ in select(data, float("inf"), args.problems):
        P, A = read_matrices(data / f"{name}.mat")
        if args.problems or args.min_size <= P.shape[0] + A.shape[0] <= args.max_size:
            chosen.append(name)
    if not chosen:
        raise ValueError(f"--min-size/--max-size: no convex problem of --data {data} has "
                         f"{args.min_size} <= n + m <= {args.max_size}")
    t0 = time.perf_counter()
    warm = (lambda p: (p.P, p.q, p.A, p.l, p.u))(random_qp(5, 5))    # numba: compile or load every kernel (a
    _admmkit(*warm, 1e-3, 100, True)                                   # tight eps runs the infeasibility tests)
    _admmkit(*warm, 1e-12, 60, True)
    jit = time.perf_counter() - t0
    print(f"{len(chosen)} problems with {args.min_size} <= n + m <= {args.max_size}; kernels ready in {jit:.2f} s",
          flush=True)
    rows, start = [], time.perf_counter()
    with threadpool_limits(1):
        for i, (eps, name) in enumerate((e, n) for e in args.eps for n in chosen):
            new = measure(name, data, eps, args.max_iter, args.repeat)
            rows += new
            print(f"[{i + 1}/{len(chosen) * len(args.eps)}] {name} (eps {eps:g}): " + "  ".join(
                f"{r['solver']} {r['whole_ms']:.2f} ms/{r['iterations']} it" for r in new), flush=True)
    write_csv(out / "qp_speed.csv", rows, list(COLUMNS), float_format=".6g")
    plot(rows, out / "qp_speed.png")
    text = "\n".join([
        "# A whole QP solve: admmkit against OSQP 1.x (Maros-Meszaros)", "", f"Command: `{command}`", "",
        f"{len(chosen)} convex problems with {args.min_size} <= n + m <= {args.max_size}, eps_abs = eps_rel = "
        f"{', '.join(f'{e:g}' for e in args.eps)}, "
        f"iteration cap {args.max_iter}, best of {args.repeat} runs taken in turn, BLAS on one thread; "
        f"the numba kernels were ready after {jit:.2f} s (compiled, or loaded from numba's cache) before the "
        f"first timing. Study wall time {time.perf_counter() - start:.0f} s.", "",
        *summarise(rows), "", "![ratios](qp_speed.png)", "", machine_markdown(machine_info(pinned_blas=True))]) + "\n"
    write_text(out / "README.md", text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
