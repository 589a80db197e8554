"""``admmkit bench qp-fidelity``: the QP plug-in with the OSQP preset against OSQP 1.x, problem by problem.

    admmkit bench qp-fidelity --data ../shared/data/maros_meszaros --max-nnz 20000 --out docs/results/qp_fidelity

For every Maros-Meszaros problem with nnz(P) + nnz(A) <= ``--max-nnz`` (the
small and mid-sized ones) and each accuracy eps (eps_abs = eps_rel), it runs

- OSQP 1.x (pip ``osqp``) with its defaults, deterministic: adaptive_rho 1
  (every 50 iterations), check_termination 25, the duality-gap test on,
  polishing off, the same max_iter and time limit;
- admmkit ``solve_qp`` with ``osqp_settings()`` and OSQP's rule (policy "osqp").

Reported per problem: the status and iterations of both, the ratio
admmkit / OSQP where both solved, rho updates, the time per iteration of
both loops (admmkit's ``timings['total'] / iterations`` against OSQP's
``solve_time / iter``, interleaved in one process, BLAS on one thread) and
whether each answer passes the neutral criteria (qpbenchmark's: primal
residual, dual residual and duality gap <= eps absolute, in inf-norms, for a
run that reported solved).  ``--rules`` adds every registered penalty rule in
OSQP's machinery (order xz), judged by the same criteria; ``--polish`` turns
polishing on for every configuration; ``--preset textbook`` and ``--order zx``
run the rules in admmkit's textbook loop and in the other order (OSQP and
admmkit with OSQP's rule stay as they are, for the comparison); ``--ablate``
runs OSQP's rule with one piece of the machinery off at a time.
"""
from __future__ import annotations


from admmkit.cli import Parser
import os
import shlex
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import scipy.io
import scipy.sparse as sp
from admmkit.benchmarks.runner.costs import typical

#: the README runs every command from the repository root, with the shared data beside the clone
DEFAULT_DATA = Path("../shared/data/maros_meszaros")
EPS = (1e-3, 1e-6)
MAX_ITER = 10_000
TIME_LIMIT = 20.0
MAX_NNZ = 20_000
#: mid-sized problems for the time per iteration: n + m in this range
MID = (1_000, 20_000)
COLUMNS = ("problem", "n", "m", "nnz", "eps", "solver", "status", "solved", "iterations", "rho_updates", "time",
           "us_per_iter", "neutral_primal", "neutral_dual", "neutral_gap", "neutral_ok")


def check_problems(data: Path, names: list[str] | None) -> None:
    """ValueError naming ``--problems`` if a name is no problem of the ``--data`` folder (with the closest names)."""
    if not data.is_dir():
        raise ValueError(f"--data: no folder {data}")
    if not names:
        return
    import difflib

    from admmkit.problems.qp.mat import list_problems
    known = [f.stem for f in list_problems(data)]
    unknown = [n for n in names if n not in known]
    if unknown:
        upper = {k.upper(): k for k in known}
        close = [upper[c] for c in difflib.get_close_matches(unknown[0].upper(), list(upper), n=3, cutoff=0.7)]
        hint = (f"; did you mean {', '.join(close)}?" if close else
                f"; it holds {len(known)} problems" + (f", e.g. {', '.join(known[:5])}" if known else ""))
        raise ValueError(f"--problems: no problem named {', '.join(unknown)} in --data {data}{hint}")


def select(data: Path, max_nnz: float, names: list[str] | None, skipped: dict | None = None) -> list[tuple[str, int]]:
    """(name, nnz) of the convex problems with nnz(P) + nnz(A) <= max_nnz (or the named ones), smallest first;
    a nonconvex one (``load_mat`` refuses it) goes into ``skipped`` with the reason."""
    from admmkit.problems.qp.convexity import check_convex
    from admmkit.problems.qp.mat import list_problems, read_matrices
    out = []
    for f in list_problems(data):
        if names and f.stem not in names:
            continue
        try:
            P, A = read_matrices(f)
        except ValueError as err:        # an unreadable file is listed as skipped, with its name
            if skipped is not None:
                skipped[f.stem] = str(err)
            continue
        nnz = P.nnz + A.nnz
        if names or nnz <= max_nnz:
            try:
                check_convex(P)
            except ValueError as err:
                if skipped is not None:
                    skipped[f.stem] = str(err)
                continue
            out.append((f.stem, nnz))
    return sorted(out, key=lambda t: (t[1], t[0]))


def run_osqp(qp, eps: float, max_iter: int, time_limit: float, polish: bool = False) -> dict:
    """OSQP 1.x, deterministic, polishing only if asked; (status, iterations, time, x, y)."""
    import osqp
    solver = osqp.OSQP()
    solver.setup(sp.triu(qp.P, format="csc"), qp.q, qp.A, qp.l, qp.u, verbose=False, polishing=polish,
                 eps_abs=eps, eps_rel=eps, max_iter=max_iter, time_limit=time_limit, adaptive_rho=1,
                 adaptive_rho_interval=50, check_termination=25, check_dualgap=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = solver.solve()
    info = res.info
    return {"status": info.status, "solved": info.status == "solved", "iterations": info.iter,
            "rho_updates": info.rho_updates, "time": info.solve_time, "x": res.x, "y": res.y}


#: one piece of OSQP's machinery switched off at a time (``--ablate``)
ABLATIONS = {"no_scaling": dict(scaling=0), "uniform_rows": dict(row_weights="uniform"),
             "no_relaxation": dict(alpha=1.0, relax_x=False), "no_gap": dict(gap=False),
             "check_every_1": dict(check_every=1), "reduced_xstep": dict(xstep="reduced")}


def run_admmkit(qp, eps: float, max_iter: int, time_limit: float, policy="osqp", polish: bool = False,
                preset: str = "osqp", order: str = "xz", **changes) -> dict:
    """admmkit's solve_qp with the OSQP preset (or admmkit's textbook loop) in the given order."""
    from admmkit.problems.qp import osqp_settings, solve_qp, textbook_settings
    make = osqp_settings if preset == "osqp" else textbook_settings
    res = solve_qp(qp, make(eps_abs=eps, eps_rel=eps, max_iter=max_iter, time_limit=time_limit, polish=polish,
                            order=order, **changes), policy=policy)
    status = res.termination or res.status.value
    return {"status": status, "solved": res.termination == "solved", "iterations": res.iterations,
            "rho_updates": res.rho_changes, "time": res.timings["total"], "x": res.x, "y": res.lam}


def measure(name: str, nnz: int, data: Path, eps_list, max_iter: int, time_limit: float, rules: list[str],
            polish: bool = False, preset: str = "osqp", order: str = "xz", ablate: bool = False) -> list[dict]:
    """All runs of one problem."""
    from admmkit.problems.qp import load_mat
    from admmkit.problems.qp.residuals import neutral_residuals
    qp = load_mat(data / f"{name}.mat")
    rows = []
    for eps in eps_list:
        runs = [("OSQP", lambda: run_osqp(qp, eps, max_iter, time_limit, polish)),
                ("admmkit-osqp", lambda: run_admmkit(qp, eps, max_iter, time_limit, polish=polish))]
        tag = "" if (preset, order) == ("osqp", "xz") else f"[{preset},{order}]"
        runs += [(f"admmkit-{r}{tag}", lambda r=r: run_admmkit(qp, eps, max_iter, time_limit, policy=r, polish=polish,
                                                               preset=preset, order=order))
                 for r in rules]
        if ablate:
            runs += [(f"admmkit-osqp[{k}]", lambda c=c: run_admmkit(qp, eps, max_iter, time_limit, polish=polish, **c))
                     for k, c in ABLATIONS.items()]
        for label, run in runs:
            try:
                out = run()
            except Exception as err:                  # a failure is a result, not a crash of the study
                out = {"status": f"error: {type(err).__name__}: {err}"[:120], "solved": False, "iterations": 0,
                       "rho_updates": 0, "time": float("nan"), "x": None, "y": None}
            row = {"problem": name, "n": qp.n, "m": qp.m, "nnz": nnz, "eps": eps, "solver": label,
                   **{k: out[k] for k in ("status", "solved", "iterations", "rho_updates", "time")}}
            row["us_per_iter"] = 1e6 * out["time"] / out["iterations"] if out["iterations"] else float("nan")
            if out["x"] is not None and np.all(np.isfinite(out["x"])) and np.all(np.isfinite(out["y"])):
                nr = neutral_residuals(qp, out["x"], out["y"])
                row.update(neutral_primal=nr["primal"], neutral_dual=nr["dual"], neutral_gap=nr["gap"])
                row["neutral_ok"] = bool(out["solved"] and max(nr.values()) <= eps)
            else:
                row.update(neutral_primal=float("nan"), neutral_dual=float("nan"), neutral_gap=float("nan"),
                           neutral_ok=False)
            rows.append(row)
    return rows


def _sgm(values, shift: float = 10.0) -> float:
    """Shifted geometric mean exp(mean(log(v + shift))) - shift."""
    v = np.asarray(values, dtype=float)
    return float(np.exp(np.mean(np.log(v + shift))) - shift) if v.size else float("nan")


def summarise(rows: list[dict], eps_list, max_iter: int = MAX_ITER, time_limit: float = TIME_LIMIT) -> tuple[list[str], dict]:
    """The Markdown summary lines and the headline figures."""
    from admmkit.benchmarks.runner.report import fmt, md_table
    lines, figures = [], {}
    solvers = list(dict.fromkeys(r["solver"] for r in rows))
    for eps in eps_list:
        by = {(r["problem"], r["solver"]): r for r in rows if r["eps"] == eps}
        problems = list(dict.fromkeys(r["problem"] for r in rows if r["eps"] == eps))
        both = [p for p in problems if by[p, "OSQP"]["solved"] and by[p, "admmkit-osqp"]["solved"]]
        ratios = [by[p, "admmkit-osqp"]["iterations"] / by[p, "OSQP"]["iterations"] for p in both]
        equal = sum(by[p, "admmkit-osqp"]["iterations"] == by[p, "OSQP"]["iterations"] for p in both)
        far = [p for p, q in zip(both, ratios) if abs(q - 1) > 0.25]
        only = {s: [p for p in problems if by[p, s]["solved"] and not by[p, "OSQP" if s != "OSQP" else "admmkit-osqp"]["solved"]]
                for s in ("OSQP", "admmkit-osqp")}
        q = np.percentile(ratios, [0, 10, 25, 50, 75, 90, 100]) if ratios else [float("nan")] * 7
        figures[eps] = dict(both=len(both), equal=equal, median=q[3], far=far, only=only, problems=len(problems))
        lines += [f"## eps = {eps:g} ({len(problems)} problems)", "",
                  f"Both solved: {len(both)}; equal iteration counts: {equal}; ratio admmkit/OSQP of iterations: "
                  f"min {fmt(q[0])}, p10 {fmt(q[1])}, p25 {fmt(q[2])}, median {fmt(q[3])}, p75 {fmt(q[4])}, "
                  f"p90 {fmt(q[5])}, max {fmt(q[6])}.", "",
                  f"Differing by more than 25 %: {', '.join(far) or 'none'}.", "",
                  f"Solved by OSQP only: {', '.join(only['OSQP']) or 'none'}; by admmkit only: "
                  f"{', '.join(only['admmkit-osqp']) or 'none'}.", ""]
        table = []
        for s in solvers:
            sel = [by[p, s] for p in problems]
            solved = sum(r["solved"] for r in sel)
            neutral = sum(r["neutral_ok"] for r in sel)
            infeas = sum("infeasible" in str(r["status"]) for r in sel)
            its = [r["iterations"] if r["neutral_ok"] else max_iter for r in sel]
            secs = [r["time"] if r["neutral_ok"] and np.isfinite(r["time"]) else time_limit for r in sel]
            table.append([s, solved, neutral, infeas, fmt(_sgm(its)), fmt(_sgm(secs, 1e-3), ".3g")])
        lines += [md_table(["solver", "solved (own test)", "solved and neutral criteria met", "declared infeasible",
                            "SGM iterations", "SGM seconds"], table),
                  "", "SGM: shifted geometric mean (shift 10 iterations, 1 ms) over all problems, a run that did not "
                  "meet the neutral criteria counting as the iteration cap and the time limit.", ""]
        mid = [p for p in both if MID[0] <= by[p, "OSQP"]["n"] + by[p, "OSQP"]["m"] <= MID[1]]
        tr = [by[p, "admmkit-osqp"]["us_per_iter"] / by[p, "OSQP"]["us_per_iter"] for p in mid
              if by[p, "OSQP"]["us_per_iter"] > 0]
        if tr:
            figures[eps]["time_ratio_mid"] = statistics.median(tr)
            lines += [f"Time per iteration, admmkit / OSQP, mid-sized problems ({MID[0]} <= n + m <= {MID[1]}, "
                      f"{len(tr)} solved by both): median {statistics.median(tr):.2f}, min {min(tr):.2f}, "
                      f"max {max(tr):.2f}.", ""]
    return lines, figures


def main(argv=None, prog: str = "admmkit bench qp-fidelity") -> int:
    """Run the study, print the summary and write qp_fidelity.csv and README.md under --out."""
    parser = Parser(prog=prog, description=__doc__.splitlines()[0] +   # one-line usage errors (admmkit.cli)
                    typical("bench qp-fidelity") + " needs: osqp, the Maros-Meszaros MAT files (--data)")
    parser.add_argument("--data", default=str(DEFAULT_DATA), help="folder of Maros-Meszaros MAT files")
    parser.add_argument("--out", default="out/qp_fidelity", help="output folder (default ./out/qp_fidelity/)")
    parser.add_argument("--max-nnz", type=float, default=MAX_NNZ, help=f"largest nnz(P) + nnz(A) (default {MAX_NNZ})")
    parser.add_argument("--problems", nargs="*", help="only these problems")
    parser.add_argument("--eps", type=float, nargs="+", default=list(EPS), help="accuracies (default 1e-3 1e-6)")
    parser.add_argument("--max-iter", type=int, default=MAX_ITER, help=f"iteration cap (default {MAX_ITER})")
    parser.add_argument("--time-limit", type=float, default=TIME_LIMIT,
                        help=f"seconds per run, both solvers (default {TIME_LIMIT:g})")
    parser.add_argument("--rules", nargs="*", default=None,
                        help="also these registered rules in OSQP's machinery (no names: every registered rule; "
                             "'osqp' is always run, with OSQP's own normalisation)")
    parser.add_argument("--polish", action="store_true", help="polishing on, for OSQP and admmkit alike")
    parser.add_argument("--preset", choices=("osqp", "textbook"), default="osqp",
                        help="settings of the --rules runs: OSQP's machinery (default) or admmkit's textbook loop")
    parser.add_argument("--order", choices=("xz", "zx"), default="xz", help="order of the --rules runs (default xz)")
    parser.add_argument("--ablate", action="store_true",
                        help="also OSQP's rule with one piece of the machinery off at a time: " + ", ".join(ABLATIONS))
    args = parser.parse_args(argv)
    if args.max_iter < 1 or args.time_limit <= 0 or args.max_nnz <= 0 or min(args.eps) <= 0:
        parser.error("--max-iter, --time-limit, --max-nnz and --eps must be positive")
    from admmkit.benchmarks.runner.harness import require
    require(prog.removeprefix("admmkit "), "osqp")        # the other solver of the comparison
    check_problems(Path(args.data), args.problems)
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    import admmkit
    from threadpoolctl import threadpool_limits
    from admmkit.io import write_text

    from admmkit.benchmarks.runner.machine import machine_info
    from admmkit.benchmarks.runner.report import machine_markdown, write_csv
    data = Path(args.data)
    rules = [r for r in ((admmkit.policy_names() if args.rules == [] else args.rules) or [])
             if r != "osqp" or (args.preset, args.order) != ("osqp", "xz")]
    command = prog + " " + " ".join(shlex.quote(a) for a in (argv if argv is not None else sys.argv[1:]))
    skipped: dict[str, str] = {}
    chosen = select(data, args.max_nnz, args.problems, skipped)
    print(f"{len(chosen)} problems; eps {args.eps}; rules {rules or 'OSQP rule only'}", flush=True)
    rows, start = [], time.perf_counter()
    out = Path(args.out)
    with threadpool_limits(1):
        for i, (name, nnz) in enumerate(chosen):
            new = measure(name, nnz, data, args.eps, args.max_iter, args.time_limit, rules, args.polish,
                          args.preset, args.order, args.ablate)
            rows += new
            brief = "  ".join(f"{r['solver']}@{r['eps']:g}:{r['status']}/{r['iterations']}" for r in new[:4])
            print(f"[{i + 1}/{len(chosen)}] {name} ({time.perf_counter() - start:.0f} s)  {brief}", flush=True)
            write_csv(out / "qp_fidelity.csv", rows, list(COLUMNS), float_format=".6g")
    lines, _ = summarise(rows, args.eps, args.max_iter, args.time_limit)
    text = "\n".join([f"# admmkit's QP plug-in with the OSQP preset against OSQP 1.x (Maros-Meszaros)", "",
                      f"Command: `{command}`", "",
                      f"Problems: the {len(chosen)} with nnz(P) + nnz(A) <= {args.max_nnz:g}: "
                      + ", ".join(n for n, _ in chosen) + ".", "",
                      *(f"Skipped, not a convex QP: {name} ({why})." for name, why in sorted(skipped.items())), "",
                      f"Iteration cap {args.max_iter}, time limit {args.time_limit:g} s per run, polishing "
                      f"{'on' if args.polish else 'off'}; wall time of the "
                      f"study {time.perf_counter() - start:.0f} s.", ""] + lines) + "\n"
    text += "\n" + machine_markdown(machine_info(pinned_blas=True))
    write_text(out / "README.md", text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
