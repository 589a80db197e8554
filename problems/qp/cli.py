"""``admmkit solve qp``: a MAT-file QP or a random one (the study is ``admmkit bench qp``, in benchmarks/)."""
from __future__ import annotations

import policies  # noqa: F401  (registers the rules the --policy option offers)
from admmkit.cli import add_common_options, add_result_outputs, exit_code, run_solve, write_result_csv, write_result_json
from policies.paper_methods import PAPER_METHODS

from .generate import KINDS, random_qp
from .mat import load_mat


def register(subparsers) -> None:
    """Register ``solve qp``."""
    p = subparsers.add_parser("qp", help="min 1/2 x'Px + q'x s.t. l <= Ax <= u (OSQP's form)")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--mat", metavar="FILE", help="a MAT file with P, q, r, A, l, u (e.g. a Maros-Meszaros problem)")
    src.add_argument("--random", nargs=2, type=int, metavar=("N", "M"), help="a random feasible QP with N variables, M rows")
    p.add_argument("--kind", choices=KINDS, default="mixed", help="row types of the random QP (default mixed)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random QP")
    add_common_options(p, policy="residual_balancing", order="xz", methods=PAPER_METHODS)
    add_result_outputs(p, json_help="write the run (provenance, summary, x, z = Ax, lam) as JSON",
                       csv_help="write the solution as CSV: one row per variable (x) and one per row of A (z, lam, l, u)")
    p.set_defaults(func=run)


def run(args) -> int:
    """Build the QP, solve it, print the summary; exit code 0 only if it converged."""
    if args.random is not None and min(args.random) < 1:
        raise ValueError(f"--random N M: both must be integers >= 1, got {args.random[0]} {args.random[1]}")
    qp = load_mat(args.mat) if args.mat else random_qp(*args.random, kind=args.kind, seed=args.seed)
    print(f"problem      {qp.name}: n = {qp.n}, m = {qp.m}")
    result = run_solve(qp, args)
    problem = {"name": qp.name, "n": qp.n, "m": qp.m, "source": args.mat or
               {"random": list(args.random), "kind": args.kind, "seed": args.seed}}
    if args.json:
        arrays = {"x": result.x, "z": result.z, "lam": result.lam}
        print(f"json         {write_result_json(args.json, result, args, problem=problem, arrays=arrays)}")
    if args.csv:
        import numpy as np
        n, m = qp.n, qp.m
        nan_n, nan_m = np.full(n, np.nan), np.full(m, np.nan)
        columns = {"kind": ["x"] * n + ["row"] * m, "index": np.r_[np.arange(n), np.arange(m)],
                   "x": np.r_[result.x, nan_m], "z": np.r_[nan_n, result.z], "lam": np.r_[nan_n, result.lam],
                   "l": np.r_[nan_n, qp.l], "u": np.r_[nan_n, qp.u]}
        print(f"csv          {write_result_csv(args.csv, columns)}")
    return exit_code(result)
