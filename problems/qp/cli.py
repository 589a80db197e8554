"""``admmkit solve qp`` (a MAT-file QP or a random one) and ``admmkit bench qp`` (the policy benchmark)."""
from __future__ import annotations

from problems.cli import add_common_options, positive_float, run_solve

from .generate import KINDS, random_qp
from .mat import load_mat


def add_solve_parser(subparsers) -> None:
    """Register ``solve qp``."""
    p = subparsers.add_parser("qp", help="min 1/2 x'Px + q'x s.t. l <= Ax <= u (OSQP's form)")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--mat", metavar="FILE", help="a MAT file with P, q, r, A, l, u (e.g. a Maros-Meszaros problem)")
    src.add_argument("--random", nargs=2, type=int, metavar=("N", "M"), help="a random feasible QP with N variables, M rows")
    p.add_argument("--kind", choices=KINDS, default="mixed", help="row types of the random QP (default mixed)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random QP")
    add_common_options(p, policy="residual_balancing", order="xz")
    p.set_defaults(func=run)


def run(args) -> int:
    """Build the QP, solve it, print the summary."""
    qp = load_mat(args.mat) if args.mat else random_qp(*args.random, kind=args.kind, seed=args.seed)
    print(f"problem      {qp.name}: n = {qp.n}, m = {qp.m}")
    run_solve(qp, args)
    return 0


def add_bench_parser(targets) -> None:
    """Register ``bench qp`` (alias ``bench maros-meszaros``)."""
    from . import bench
    b = targets.add_parser("qp", aliases=["maros-meszaros"],
                           help="every penalty rule (both orders) and OSQP on a folder of QPs (Maros-Meszaros)",
                           description="Penalty rules against OSQP on the QPs of a folder of MAT files, at OSQP's "
                                       "accuracies 1e-3 and 1e-6; writes results.csv, summary.csv, README.md and "
                                       "performance profiles (PNG, SVG) to --out.")
    b.add_argument("--data", required=True, metavar="DIR", help="folder of MAT files (P, q, r, A, l, u), "
                   "e.g. ../shared/data/maros_meszaros")
    b.add_argument("--out", default="docs/results/maros_meszaros", help="output folder")
    b.add_argument("--policies", default=None, help="comma-separated rules (default: every registered rule and "
                   f"{bench.OSQP_QP}, OSQP's rule with the QP's own normalisation)")
    b.add_argument("--orders", default="xz,zx", help="comma-separated orders (default xz,zx)")
    b.add_argument("--eps", type=positive_float, action="append", default=None,
                   help="accuracy eps_abs = eps_rel (repeatable; default 1e-3 and 1e-6)")
    b.add_argument("--max-iter", type=int, default=bench.MAX_ITER, help=f"iteration cap (default {bench.MAX_ITER})")
    b.add_argument("--time-limit", type=positive_float, default=bench.TIME_LIMIT,
                   help=f"seconds per problem and configuration (default {bench.TIME_LIMIT:g})")
    b.add_argument("--workers", type=int, default=1, help="worker processes, 1 or 2 (default 1)")
    b.add_argument("--problems", default=None, help="comma-separated problem names (default: all)")
    b.add_argument("--no-osqp", action="store_true", help="do not run OSQP itself")
    b.add_argument("--resume", action="store_true", help="keep the problems already in OUT/results.csv")
    b.add_argument("--quiet", action="store_true", help="no progress lines")
    b.set_defaults(func=_bench)


def _split(text):
    return [t.strip() for t in text.split(",") if t.strip()] if text else None


def _bench(args) -> int:
    from .bench import EPS, run_benchmark
    eps = tuple(args.eps) if args.eps else EPS
    command = "admmkit bench qp --data {} --out {}".format(args.data, args.out)
    for flag, value, default in (("--policies", args.policies, None), ("--orders", args.orders, "xz,zx"),
                                 ("--max-iter", args.max_iter, 20_000), ("--time-limit", args.time_limit, 10.0),
                                 ("--workers", args.workers, 1), ("--problems", args.problems, None)):
        if value != default:
            command += f" {flag} {value:g}" if isinstance(value, float) else f" {flag} {value}"
    if args.eps:
        command += "".join(f" --eps {e:g}" for e in args.eps)
    if args.no_osqp:
        command += " --no-osqp"
    run_benchmark(args.data, args.out, policy_names=_split(args.policies), orders=_split(args.orders) or (),
                  eps=eps, max_iter=args.max_iter, time_limit=args.time_limit, workers=args.workers,
                  only=_split(args.problems), osqp_direct=not args.no_osqp, resume=args.resume,
                  command=command, progress=not args.quiet)
    return 0
