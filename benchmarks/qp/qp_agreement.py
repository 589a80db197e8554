"""``admmkit bench qp-agreement``: the QP plug-in (OSQP preset) against cvxpy + Clarabel on random feasible QPs.

    admmkit bench qp-agreement --count 1000 --seed 0 --out docs/results/qp_agreement

``--count`` random QPs from one seed, of mixed shapes: the kinds of
:func:`admmkit.problems.qp.random_qp` (two-sided inequalities; equalities; mixed
two-sided, one-sided, free and equality rows; LPs and rank-deficient QPs with
a box), n from 2 to 80, m from 1 to 120, density 0.1 to 0.6.  Each is solved by
Clarabel through cvxpy (tolerances 1e-10) and by ``solve_qp`` with
``osqp_settings(eps_abs=eps, eps_rel=eps)`` (eps = 1e-6 by default), without
and with polishing.  Reported: how many runs ended "solved", the relative
objective error |f - f_ref| / max(1, |f_ref|), the distance of x to Clarabel's
(relative to max(1, ||x_ref||_inf), strictly convex kinds only: LP and
rank-deficient solutions need not be unique), and how many answers meet the
neutral criteria (primal, dual, gap <= eps, absolute).
"""
from __future__ import annotations


from admmkit.cli import Parser
import os
import shlex
import sys
import time
from pathlib import Path

import numpy as np
from admmkit.benchmarks.runner.costs import typical

KINDS = ("inequality", "equality", "mixed", "lp", "psd")
UNIQUE = ("inequality", "equality", "mixed")
COLUMNS = ("index", "kind", "n", "m", "density", "seed", "config", "status", "iterations", "objective",
           "objective_ref", "objective_error", "x_error", "neutral_primal", "neutral_dual", "neutral_gap",
           "neutral_ok", "polish")


def instances(count: int, seed: int):
    """(kind, n, m, density, qp seed) of ``count`` QPs drawn from one generator."""
    rng = np.random.default_rng(seed)
    for i in range(count):
        kind = KINDS[i % len(KINDS)]
        n = int(rng.integers(2, 81))
        m = int(rng.integers(1, 121))
        yield kind, n, m, float(rng.uniform(0.1, 0.6)), int(rng.integers(2**31))


def compare(index, kind, n, m, density, qp_seed, eps, max_iter) -> list[dict]:
    """Clarabel's reference and the admmkit runs of one QP."""
    from admmkit.problems.qp import random_qp, solve_qp
    from admmkit.problems.qp.reference import solve_with_cvxpy
    from admmkit.problems.qp.residuals import neutral_residuals
    qp = random_qp(n, m, kind=kind, density=density, seed=qp_seed)
    base = {"index": index, "kind": kind, "n": qp.n, "m": qp.m, "density": density, "seed": qp_seed}
    try:
        x_ref, _, obj_ref = solve_with_cvxpy(qp, tol_gap_abs=1e-10, tol_gap_rel=1e-10, tol_feas=1e-10)
    except Exception as err:
        return [{**base, "config": "clarabel", "status": f"error: {err}"[:100]}]
    rows = []
    for config, polish in (("admmkit", False), ("admmkit+polish", True)):
        res = solve_qp(qp, eps_abs=eps, eps_rel=eps, max_iter=max_iter, polish=polish)
        nr = neutral_residuals(qp, res.x, res.lam)
        obj = res.objective
        row = {**base, "config": config, "status": res.termination or res.status.value, "iterations": res.iterations,
               "objective": obj, "objective_ref": obj_ref,
               "objective_error": abs(obj - obj_ref) / max(1.0, abs(obj_ref)) if np.isfinite(obj) else np.inf,
               "x_error": (np.max(np.abs(res.x - x_ref)) / max(1.0, np.max(np.abs(x_ref)))) if kind in UNIQUE else np.nan,
               "neutral_primal": nr["primal"], "neutral_dual": nr["dual"], "neutral_gap": nr["gap"],
               "neutral_ok": res.termination == "solved" and max(nr.values()) <= eps,
               "polish": (res.polish or {}).get("status", "")}
        rows.append(row)
    return rows


def summary(rows: list[dict], eps: float) -> list[str]:
    """Markdown lines: per configuration and kind, solved, agreement and neutral counts."""
    from admmkit.benchmarks.runner.report import fmt, md_table
    lines = []
    for config in ("admmkit", "admmkit+polish"):
        table = []
        for kind in KINDS + ("all",):
            sel = [r for r in rows if r.get("config") == config and (kind == "all" or r["kind"] == kind)]
            if not sel:
                continue
            solved = [r for r in sel if r["status"] == "solved"]
            err = np.array([r["objective_error"] for r in solved]) if solved else np.array([np.nan])
            xerr = np.array([r["x_error"] for r in solved if np.isfinite(r["x_error"])]) if solved else np.array([])
            table.append([kind, len(sel), len(solved), sum(e <= 1e-5 for e in err), sum(e <= 1e-4 for e in err),
                          fmt(np.nanmedian(err)), fmt(np.nanmax(err)),
                          fmt(np.max(xerr)) if xerr.size else "-",
                          sum(r["neutral_ok"] for r in sel)])
        lines += [f"## {config}", "",
                  md_table(["kind", "QPs", "solved", "objective error <= 1e-5", "<= 1e-4", "median objective error",
                            "max objective error", "max x error (unique kinds)", f"neutral criteria met (eps {eps:g})"],
                           table), ""]
    return lines


def main(argv=None, prog: str = "admmkit bench qp-agreement") -> int:
    """Run the comparison, print the table and write qp_agreement.csv and README.md under --out."""
    parser = Parser(prog=prog, description=__doc__.splitlines()[0] +   # one-line usage errors (admmkit.cli)
                    typical("bench qp-agreement") + " needs: cvxpy, clarabel (installed with admmkit)")
    parser.add_argument("--out", default="out/qp_agreement", help="output folder (default ./out/qp_agreement/)")
    parser.add_argument("--count", type=int, default=1000, help="number of random QPs (default 1000)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the generator of the QPs (default 0)")
    parser.add_argument("--eps", type=float, default=1e-6, help="eps_abs = eps_rel of admmkit (default 1e-6)")
    parser.add_argument("--max-iter", type=int, default=20_000, help="iteration cap (default 20000)")
    args = parser.parse_args(argv)
    if args.count < 1 or args.eps <= 0 or args.max_iter < 1:
        parser.error("--count, --eps and --max-iter must be positive")
    from admmkit.benchmarks.runner.harness import require
    require(prog.removeprefix("admmkit "), "cvxpy", "clarabel")     # the reference: cvxpy + Clarabel
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    from admmkit.io import write_text

    from admmkit.benchmarks.runner.machine import machine_info
    from admmkit.benchmarks.runner.report import machine_markdown, write_csv
    command = prog + " " + " ".join(shlex.quote(a) for a in (argv if argv is not None else sys.argv[1:]))
    rows, start = [], time.perf_counter()
    out = Path(args.out)
    for i, inst in enumerate(instances(args.count, args.seed)):
        rows += compare(i, *inst, args.eps, args.max_iter)
        if (i + 1) % 100 == 0:
            print(f"{i + 1}/{args.count} QPs ({time.perf_counter() - start:.0f} s)", flush=True)
            write_csv(out / "qp_agreement.csv", rows, list(COLUMNS), float_format=".6g")
    write_csv(out / "qp_agreement.csv", rows, list(COLUMNS), float_format=".6g")
    failed_ref = [r for r in rows if r.get("config") == "clarabel"]
    lines = [f"# admmkit's QP plug-in (OSQP preset) against cvxpy + Clarabel on {args.count} random feasible QPs", "",
             f"Command: `{command}`", "",
             f"eps_abs = eps_rel = {args.eps:g}, iteration cap {args.max_iter}; Clarabel at 1e-10; "
             f"objective error |f - f_ref| / max(1, |f_ref|); x error max|x - x_ref| / max(1, max|x_ref|); "
             f"Clarabel failed on {len(failed_ref)} QPs (left out); wall time {time.perf_counter() - start:.0f} s.", ""]
    lines += summary(rows, args.eps)
    text = "\n".join(lines) + "\n\n" + machine_markdown(machine_info(pinned_blas=True))
    write_text(out / "README.md", text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
