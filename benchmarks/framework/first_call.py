"""``admmkit bench first-call``: what a user waits for in a fresh process, side by side with OSQP.

Every figure is the wall time of a fresh Python process (``subprocess.run``,
measured from the parent), the median of ``--repeats`` runs, the rows
interleaved so that a load change hits both sides alike.  The children also
report their own phases (import, read, solve), from ``time.perf_counter``.

- ``import``: ``import admmkit`` against ``import osqp`` (admmkit's package file only: every public name is
  imported on first use), and ``from admmkit import solve`` (the loop, with numpy) against ``import osqp``;
- ``HS21, cached kernels``: import, read HS21 from its MAT file and solve it
  once with OSQP's settings (``solve_qp(qp, osqp_settings())``) against
  ``osqp.OSQP().setup(...).solve()`` on the same arrays (read with
  ``scipy.io``); numba's kernels are loaded from their cache (a warm-up process
  runs first);
- ``HS21, empty kernel cache``: the same admmkit process with
  ``NUMBA_CACHE_DIR`` pointing at an empty folder, as on a fresh install: every
  kernel the call needs is compiled;
- ``cvxpy``: a three-variable projection solved through cvxpy with
  ``solver=ADMMKIT()`` against ``solver=cp.OSQP``;
- ``admmkit --help`` and a whole ``admmkit solve contact --scene ex1 --h 1/40``
  process (no OSQP counterpart; FreeFEM++ took 0.48 s for the same SADMM on
  this machine in issue #49's measurement, not rerun here), twice: with an
  empty operator cache (``ADMMKIT_CACHE_DIR`` an empty folder: NGSolve
  imported, the scene assembled and stored) and with the entry the warm-up
  stored (read back, no NGSolve; problems/contact/model/operator_cache.py);
- ``import numpy, scipy.sparse.linalg, scipy.linalg``: issue #49's floor of the
  warm contact process, which imported them for SuperLU and LAPACK until
  28 November; ``import numpy, scipy.sparse``: its floor since, SuperLU and
  LAPACK being called from their compiled modules without those two imports
  (problems/contact/solvers/lapack.py).

The children run with Python's bytecode cache on (``PYTHONDONTWRITEBYTECODE``
removed from their environment), as an installed package has it: the warm-up
round writes what is missing.

Writes ``first_call.md``, ``first_call.csv`` and ``first_call.png`` to ``--out``.
"""
from __future__ import annotations

import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from admmkit.io import write_text

from admmkit.benchmarks.runner.machine import machine_info
from admmkit.benchmarks.runner.report import write_csv

#: the child programs; each prints one JSON line of its own phases (seconds)
CHILD = {
    "admmkit_import": "import time; t = time.perf_counter(); import admmkit; "
                      "import json; print(json.dumps({'import': time.perf_counter() - t}))",
    "admmkit_loop": "import time; t = time.perf_counter(); from admmkit import solve; "
                    "import json; print(json.dumps({'import': time.perf_counter() - t}))",
    "osqp_import": "import time; t = time.perf_counter(); import osqp; "
                   "import json; print(json.dumps({'import': time.perf_counter() - t}))",
    "admmkit_hs21": "import time, sys; t0 = time.perf_counter(); import admmkit; "
                    "from admmkit.problems.qp import load_mat, osqp_settings, solve_qp; t1 = time.perf_counter(); "
                    "qp = load_mat(sys.argv[1]); t2 = time.perf_counter(); r = solve_qp(qp, osqp_settings()); "
                    "t3 = time.perf_counter(); import json; print(json.dumps({'import': t1 - t0, 'read': t2 - t1, "
                    "'solve': t3 - t2, 'status': str(r.status.value), 'iterations': r.iterations}))",
    "osqp_hs21": "import time, sys; t0 = time.perf_counter(); import numpy as np, scipy.io, scipy.sparse as sp, osqp; "
                 "t1 = time.perf_counter(); d = scipy.io.loadmat(sys.argv[1]); "
                 "P = sp.csc_matrix(d['P']); A = sp.csc_matrix(d['A']); q = np.ravel(d['q']).astype(float); "
                 "l = np.ravel(d['l']).astype(float); u = np.ravel(d['u']).astype(float); "
                 "t2 = time.perf_counter(); m = osqp.OSQP(); m.setup(P=sp.triu(P, format='csc'), q=q, A=A, l=l, "
                 "u=u, verbose=False); r = m.solve(); t3 = time.perf_counter(); import json; "
                 "print(json.dumps({'import': t1 - t0, 'read': t2 - t1, 'solve': t3 - t2, "
                 "'status': r.info.status, 'iterations': r.info.iter}))",
    "admmkit_cvxpy": "import time; t0 = time.perf_counter(); import cvxpy as cp, numpy as np; "
                     "from admmkit.problems.qp.cvxpy_interface import ADMMKIT; t1 = time.perf_counter(); "
                     "x = cp.Variable(3); p = cp.Problem(cp.Minimize(cp.sum_squares(x - np.array([1., 2., 3.]))), "
                     "[cp.sum(x) == 1, x >= 0]); p.solve(solver=ADMMKIT()); t2 = time.perf_counter(); "
                     "import json; print(json.dumps({'import': t1 - t0, 'solve': t2 - t1, 'status': p.status}))",
    "osqp_cvxpy": "import time; t0 = time.perf_counter(); import cvxpy as cp, numpy as np; t1 = time.perf_counter(); "
                  "x = cp.Variable(3); p = cp.Problem(cp.Minimize(cp.sum_squares(x - np.array([1., 2., 3.]))), "
                  "[cp.sum(x) == 1, x >= 0]); p.solve(solver=cp.OSQP); t2 = time.perf_counter(); "
                  "import json; print(json.dumps({'import': t1 - t0, 'solve': t2 - t1, 'status': p.status}))",
    "floor_imports": "import time; t = time.perf_counter(); import numpy, scipy.sparse.linalg, scipy.linalg; "
                     "import json; print(json.dumps({'import': time.perf_counter() - t}))",
    "sparse_imports": "import time; t = time.perf_counter(); import numpy, scipy.sparse; "
                      "import json; print(json.dumps({'import': time.perf_counter() - t}))",
}
#: the rows of the table: (label, admmkit child, OSQP child or None)
ROWS = [("import", "admmkit_import", "osqp_import"),
        ("from admmkit import solve (the loop, numpy)", "admmkit_loop", "osqp_import"),
        ("HS21, cached kernels", "admmkit_hs21", "osqp_hs21"),
        ("HS21, empty kernel cache", "admmkit_hs21_cold", None),
        ("cvxpy, 3-variable projection", "admmkit_cvxpy", "osqp_cvxpy"),
        ("admmkit --help", "admmkit_help", None),
        ("solve contact --scene ex1 --h 1/40, empty operator cache", "admmkit_contact_cold", None),
        ("solve contact --scene ex1 --h 1/40, operator cache warm", "admmkit_contact", None),
        ("import numpy, scipy.sparse.linalg, scipy.linalg", "floor_imports", None),
        ("import numpy, scipy.sparse", "sparse_imports", None)]


def command(name: str, hs21: Path) -> list[str]:
    """The argv of child ``name``."""
    py = sys.executable
    if name == "admmkit_help":
        return [py, "-m", "admmkit", "--help"]
    if name.startswith("admmkit_contact"):
        return [py, "-m", "admmkit", "solve", "contact", "--scene", "ex1", "--h", "1/40", "-q"]
    code = CHILD[name.removesuffix("_cold")]
    return [py, "-c", code, str(hs21)] if "hs21" in name else [py, "-c", code]


def run_child(name: str, hs21: Path, env: dict) -> dict:
    """One fresh process: its wall time from the parent, and the phases it printed."""
    child_env = dict(env)
    cold = None
    if name.endswith("_cold"):      # an empty kernel cache (HS21) or operator cache (contact): a fresh one each run
        cold = tempfile.TemporaryDirectory(prefix="admmkit-empty-")
        child_env["ADMMKIT_CACHE_DIR" if "contact" in name else "NUMBA_CACHE_DIR"] = cold.name
    try:
        before, start = resource.getrusage(resource.RUSAGE_CHILDREN), time.perf_counter()
        done = subprocess.run(command(name, hs21), env=child_env, capture_output=True, text=True)
        wall, after = time.perf_counter() - start, resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    finally:
        if cold is not None:
            cold.cleanup()
    if done.returncode not in (0, 1) or (done.returncode and "contact" not in name):
        raise RuntimeError(f"{name} failed (exit {done.returncode}): {done.stderr.strip().splitlines()[-1:]}")
    phases = {}
    if name in CHILD or name.removesuffix("_cold") in CHILD:
        phases = json.loads(done.stdout.strip().splitlines()[-1])
    return {"wall": wall, "cpu": cpu, **phases}


def measure(hs21: Path, repeats: int, progress: bool = True) -> dict[str, list[dict]]:
    """{child: [one dict per repeat]}, the children interleaved round by round after one warm-up round."""
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    env.pop("PYTHONDONTWRITEBYTECODE", None)    # bytecode cached, as in an installed package
    env.pop("ADMMKIT_NO_CACHE", None)
    names = [n for row in ROWS for n in row[1:] if n]
    with tempfile.TemporaryDirectory(prefix="admmkit-operators-") as operators:
        env["ADMMKIT_CACHE_DIR"] = operators    # the warm contact rows read the entry the warm-up stores here
        for name in names:                      # warm-up: numba's and the operator cache filled, the page cache
            if not name.endswith("_cold"):
                run_child(name, hs21, env)
        runs: dict[str, list[dict]] = {n: [] for n in names}
        for r in range(repeats):
            for name in names:
                runs[name].append(run_child(name, hs21, env))
            if progress:
                print(f"  round {r + 1}/{repeats} done", file=sys.stderr, flush=True)
    return runs


def median(runs: list[dict], key: str = "wall") -> float:
    """The median of one field over the repeats (NaN where no run has it)."""
    values = [r[key] for r in runs if isinstance(r.get(key), (int, float))]
    return statistics.median(values) if values else float("nan")


def table_rows(runs: dict[str, list[dict]]) -> list[dict]:
    """One row per ROWS entry: admmkit's and OSQP's median wall times and their ratio."""
    rows = []
    for label, ours, theirs in ROWS:
        a = median(runs[ours])
        b = median(runs[theirs]) if theirs else float("nan")
        rows.append({"case": label, "admmkit_s": a, "osqp_s": b, "ratio": a / b if theirs else float("nan"),
                     "admmkit_import_s": median(runs[ours], "import"), "admmkit_solve_s": median(runs[ours], "solve"),
                     "osqp_solve_s": median(runs[theirs], "solve") if theirs else float("nan"),
                     "admmkit_cpu_s": median(runs[ours], "cpu"),
                     "status": runs[ours][-1].get("status", "")})
    return rows


def report(rows: list[dict], repeats: int, argv_line: str) -> str:
    """The Markdown report."""
    def f(v, bold=False):
        return "-" if v != v else (f"**{v:.2f}**" if bold else f"{v:.3f}")
    lines = ["# First call: fresh processes, admmkit against OSQP", "",
             f"Produced by `{argv_line}`; each figure is the median wall time of {repeats} fresh processes "
             "(interleaved, after one warm-up round), BLAS on one thread. `import` and `solve` are the children's "
             "own phases; `admmkit CPU` the median CPU seconds (user + system) of the admmkit process, which other "
             "load on the machine inflates less than its wall time. See the module docstring of "
             "admmkit.benchmarks.framework.first_call.", "",
             "| case | admmkit (s) | OSQP (s) | ratio | admmkit import (s) | admmkit solve (s) | OSQP solve (s) | status "
             "| admmkit CPU (s) |",
             "|---|---:|---:|---:|---:|---:|---:|---|---:|"]
    for r in rows:
        lines.append(f"| {r['case']} | {f(r['admmkit_s'])} | {f(r['osqp_s'])} | "
                     f"{f(r['ratio'], bold=True)} | {f(r['admmkit_import_s'])} | "
                     f"{f(r['admmkit_solve_s'])} | {f(r['osqp_solve_s'])} | {r['status']} | "
                     f"{f(r.get('admmkit_cpu_s', float('nan')))} |")
    info = machine_info()
    lines += ["", "Machine: " + ", ".join(f"{k} {info[k]}" for k in ("date", "cpu", "nproc", "python", "numpy",
                                                                        "osqp") if k in info), ""]
    return "\n".join(lines)


def chart(rows: list[dict], path: Path) -> None:
    """Horizontal bars: admmkit's and OSQP's median process times per case."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from admmkit.io import atomic_path
    fig, ax = plt.subplots(figsize=(9, 4.6))
    ys = range(len(rows))
    ax.barh([y + 0.2 for y in ys], [r["admmkit_s"] for r in rows], height=0.4, label="admmkit", color="C0")
    ax.barh([y - 0.2 for y in ys], [0 if r["osqp_s"] != r["osqp_s"] else r["osqp_s"] for r in rows], height=0.4,
            label="OSQP 1.x", color="C1")
    ax.set_yticks(list(ys), [r["case"] for r in rows])
    ax.invert_yaxis()
    ax.set_xlabel("wall time of a fresh process (s, median)")
    ax.set_title("What a user waits for in a fresh process")
    ax.legend(loc="upper right")
    ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None, prog: str = "admmkit bench first-call") -> int:
    """Parse the options, measure, print the table and write it where ``--out`` says."""
    from admmkit.cli import Parser           # a usage error is one line (admmkit.cli)
    parser = Parser(prog=prog, description="Fresh processes side by side with OSQP: import, "
                    "first HS21 solve with cached and with empty kernel cache, the cvxpy route, "
                    "admmkit --help, a whole solve contact. Typical: 1-2 min on 2 cores.")
    parser.add_argument("--out", default="out/first_call", help="output folder (default out/first_call)")
    parser.add_argument("--data", default="../shared/data/maros_meszaros",
                        help="folder holding HS21.mat (default ../shared/data/maros_meszaros)")
    parser.add_argument("--repeats", type=int, default=3, help="fresh processes per case, >= 1 (default 3)")
    args = parser.parse_args(argv)
    if args.repeats < 1:
        parser.error(f"--repeats must be an integer >= 1, got {args.repeats}")
    hs21 = Path(args.data) / "HS21.mat"
    if not hs21.is_file():
        parser.error(f"--data: no HS21.mat in {args.data!r}; give the folder of the Maros-Meszaros MAT files")
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        parser.error(f"--out {args.out!r} is a file; give a folder")
    out.mkdir(parents=True, exist_ok=True)
    print(f"bench first-call: {len(ROWS)} cases x {args.repeats} fresh processes (about 1-2 min)", file=sys.stderr)
    runs = measure(hs21, args.repeats)
    rows = table_rows(runs)
    argv_line = " ".join([prog, *(argv if argv is not None else sys.argv[1:])])
    text = report(rows, args.repeats, argv_line)
    print(text)
    write_text(out / "first_call.md", text)
    write_csv(out / "first_call.csv", rows)
    chart(rows, out / "first_call.png")
    for name in ("first_call.md", "first_call.csv", "first_call.png"):
        print(f"wrote {out / name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
