"""Benchmark the sparse direct solvers of admmkit.linalg.linsolve on this machine.

    python benchmarks/contact/linsolve_backends.py [--max-n N] [--out docs/results/linsolve.md]

Matrices: 2D plane-strain linear elasticity, P1 triangles on the unit square,
clamped on the left side, assembled with NGSolve (free DOFs only), about 1e3,
1e4, 1e5 and 1e6 unknowns.  For each installed backend we time
``admmkit.linalg.linsolve.factorize`` (factorisation) and one solve, medians of a few
repeats.  Everything is measured twice, in worker subprocesses with
OMP/OPENBLAS/MKL_NUM_THREADS (and ngsolve.SetNumThreads) = 1 and = 2, together with a tiny numpy
operation, to see whether pinning BLAS/OpenMP to one thread helps.
A backend/size pair whose factorisation is predicted (from the previous size,
time ~ n^1.5) to take more than --max-seconds is skipped.
"""
import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from admmkit.cli import Parser  # noqa: E402
from admmkit.io import write_text  # noqa: E402  (after the path, for `python benchmarks/contact/linsolve_backends.py`)
from admmkit.benchmarks.runner.costs import typical
from admmkit.benchmarks.runner.machine import machine_info

GRIDS = [22, 70, 223, 707]  # n = 2 N (N + 1) free DOFs: ~1e3, 1e4, 1e5, 1e6
THREADS = [1, 2]


def elasticity_matrix(N, E=1.0, nu=0.3):
    """P1 plane-strain stiffness on an N x N triangulated unit square, left side clamped."""
    import ngsolve as ng
    import scipy.sparse as sp
    from ngsolve.meshes import MakeStructured2DMesh
    mesh = MakeStructured2DMesh(quads=False, nx=N, ny=N)
    fes = ng.VectorH1(mesh, order=1, dirichlet="left")
    u, v = fes.TnT()
    mu, lam = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    a = ng.BilinearForm(fes)
    a += (2 * mu * ng.InnerProduct(ng.Sym(ng.Grad(u)), ng.Sym(ng.Grad(v)))
          + lam * ng.div(u) * ng.div(v)) * ng.dx
    a.Assemble()
    val, col, ind = a.mat.CSR()
    A = sp.csr_matrix((np.array(val), np.array(col), np.array(ind)), shape=(fes.ndof, fes.ndof))
    free = np.flatnonzero(np.array(fes.FreeDofs(), dtype=bool))
    return A[free][:, free].tocsc()


def median_time(fn, repeats):
    """Median wall time of fn() over `repeats` calls, and the last result."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times)), out


def worker(max_n, repeats, max_seconds):
    """Measure all backends/sizes in this process; return a JSON-able dict."""
    import ngsolve  # has its own thread pool (used inside sparsecholesky)
    from admmkit.linalg.linsolve import available_backends, factorize
    ngsolve.SetNumThreads(int(os.environ["OMP_NUM_THREADS"]))
    x = np.random.default_rng(0).standard_normal(1000)
    y = np.random.default_rng(1).standard_normal(1000)
    dot_1e3, _ = median_time(lambda: [np.dot(x, y) for _ in range(1000)], 7)
    X = np.random.default_rng(0).standard_normal(10**6)
    dot_1e6, _ = median_time(lambda: np.dot(X, X), 21)
    rows, skipped, last = [], [], {}
    for N in GRIDS:
        if 2 * N * (N + 1) > max_n:
            continue
        A = elasticity_matrix(N)
        n = A.shape[0]
        b = np.random.default_rng(n).standard_normal(n)
        for name in available_backends():
            if name in last:
                n0, t0 = last[name]
                predicted = t0 * (n / n0) ** 1.5
                if predicted > max_seconds:
                    skipped.append(dict(backend=name, n=n, predicted=predicted))
                    continue
            start = time.perf_counter()
            solve = factorize(A, name)  # first call also warms up imports
            first = time.perf_counter() - start
            reps = repeats if first < 5 else 1
            if reps > 1:
                del solve
                t_factor, solve = median_time(lambda: factorize(A, name), reps)
            else:
                t_factor = first
            t_solve, u = median_time(lambda: solve(b), 2 * repeats + 1)
            residual = float(np.linalg.norm(A @ u - b) / np.linalg.norm(b))
            del solve
            last[name] = (n, t_factor)
            rows.append(dict(backend=name, n=n, nnz=int(A.nnz), factor=t_factor,
                             solve=t_solve, residual=residual, repeats=reps))
    return dict(dot_1e3=dot_1e3 / 1000, dot_1e6=dot_1e6, rows=rows, skipped=skipped,
                load=open("/proc/loadavg").read().split()[0])


def run_worker(threads, args):
    """Run `worker` in a subprocess with all thread-count variables set to `threads`."""
    env = dict(os.environ, OMP_NUM_THREADS=str(threads), OPENBLAS_NUM_THREADS=str(threads),
               MKL_NUM_THREADS=str(threads))
    cmd = [sys.executable, __file__, "--worker", "--max-n", str(args.max_n),
           "--repeats", str(args.repeats), "--max-seconds", str(args.max_seconds)]
    out = subprocess.run(cmd, env=env, check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


#: the versions this study reports: the sparse direct backends' besides the usual ones
LIBRARIES = ("numpy", "scipy", "ngsolve", "qdldl", "scikit-sparse", "pypardiso", "mkl")


def report(results, args):
    """Markdown report from {threads: worker result}."""
    t1, t2 = results[1], results[2]
    key = lambda r: (r["n"], r["backend"])
    two = {key(r): r for r in t2["rows"]}
    lines = ["# Sparse direct solvers on this machine", "",
             "Produced by `python benchmarks/contact/linsolve_backends.py "
             + " ".join(sys.argv[1:]) + "`", "",
             *(f"- {k}: {v}" for k, v in machine_info(libraries=LIBRARIES).items()), "",
             "Plane-strain P1 elasticity (E=1, nu=0.3) on the unit square, clamped on the "
             "left side, free DOFs only. `factor` = `admmkit.linalg.linsolve.factorize` "
             f"(median of {args.repeats}, or 1 if one takes > 5 s), `solve` = one 1-D solve "
             f"(median of {2 * args.repeats + 1}); seconds. `1 thr` / `2 thr`: "
             "OMP/OPENBLAS/MKL_NUM_THREADS and ngsolve.SetNumThreads = 1 / 2 (2 = the default on "
             "this 2-core machine). 1-minute load average at the end of the 1 / 2 thread runs: "
             f"{t1['load']} / {t2['load']} (other processes share the 2 cores).",
             "", "| n | nnz | backend | factor 1 thr | factor 2 thr | solve 1 thr | solve 2 thr "
             "| rel. residual |", "|---:|---:|---|---:|---:|---:|---:|---:|"]
    for r in sorted(t1["rows"], key=key):
        s = two.get(key(r))
        f2, s2 = (f"{s['factor']:.4g}", f"{s['solve']:.3g}") if s else ("-", "-")
        lines.append(f"| {r['n']} | {r['nnz']} | {r['backend']} | {r['factor']:.4g} | {f2} "
                     f"| {r['solve']:.3g} | {s2} | {r['residual']:.1e} |")
    lines += ["", "Fastest per size:", ""]
    for threads, t in results.items():
        for n in sorted({r["n"] for r in t["rows"]}):
            rs = [r for r in t["rows"] if r["n"] == n]
            bf = min(rs, key=lambda r: r["factor"])
            bs = min(rs, key=lambda r: r["solve"])
            lines.append(f"- {threads} thr, n = {n}: factor {bf['backend']} ({bf['factor']:.3g} s), "
                         f"solve {bs['backend']} ({bs['solve']:.3g} s)")
    skipped = {(s["backend"], s["n"]): s for t in (t1, t2) for s in t["skipped"]}
    if skipped:
        lines += ["", f"Skipped (predicted factorisation > {args.max_seconds:g} s):", ""]
        lines += [f"- {b}, n = {n} (predicted {s['predicted']:.0f} s)"
                  for (b, n), s in sorted(skipped.items())]
    lines += ["", "Thread count and a tiny numpy operation (seconds per call):", "",
              "| operation | 1 thr | 2 thr |", "|---|---:|---:|",
              f"| np.dot, 1e3-vectors | {t1['dot_1e3']:.3g} | {t2['dot_1e3']:.3g} |",
              f"| np.dot, 1e6-vectors | {t1['dot_1e6']:.3g} | {t2['dot_1e6']:.3g} |", "",
              "Ratio time(2 threads) / time(1 thread), geometric mean over sizes "
              "(< 1: threads help, > 1: pinning to 1 thread helps):", ""]
    for name in sorted({r["backend"] for r in t1["rows"]}):
        pairs = [(r, two[key(r)]) for r in t1["rows"] if r["backend"] == name and key(r) in two]
        gf = np.exp(np.mean([np.log(b["factor"] / a["factor"]) for a, b in pairs]))
        gs = np.exp(np.mean([np.log(b["solve"] / a["solve"]) for a, b in pairs]))
        lines.append(f"- {name}: factor {gf:.2f}, solve {gs:.2f}")
    lines += ["", "The order used by `backend=\"auto\"` and the reasons for it are in the "
              "comment above `AUTO_ORDER` in `admmkit/linalg/linsolve.py`."]
    return "\n".join(lines) + "\n"


def main(argv=None, prog: str = "admmkit bench linsolve") -> int:
    """Command-line entry point (``admmkit bench linsolve``)."""
    parser = Parser(prog=prog, description=__doc__.split("\n")[0] +   # one-line usage errors (admmkit.cli)
                    typical("bench linsolve") + " needs: scipy; it also times the optional backends that are installed: qdldl, "
                    "scikit-sparse (cholmod), pypardiso, ngsolve")
    parser.add_argument("--max-n", type=int, default=1_100_000, help="largest system size")
    parser.add_argument("--repeats", type=int, default=3, help="factorisations per median")
    parser.add_argument("--max-seconds", type=float, default=60.0,
                        help="skip a backend/size pair predicted to factorise slower")
    parser.add_argument("--out", default=None, help="write the Markdown table here")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        print(json.dumps(worker(args.max_n, args.repeats, args.max_seconds)))
        return 0
    results = {t: run_worker(t, args) for t in THREADS}
    text = report(results, args)
    print(text)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        write_text(Path(args.out), text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(prog="python benchmarks/contact/linsolve_backends.py"))
