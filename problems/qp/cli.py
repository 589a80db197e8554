"""``admmkit solve qp``: a MAT-file QP or a random one (the study is ``admmkit bench qp``, in benchmarks/)."""
from __future__ import annotations

import policies  # noqa: F401  (registers the rules the --policy option offers)
from admmkit.cli import add_common_options, run_solve

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
    add_common_options(p, policy="residual_balancing", order="xz")
    p.set_defaults(func=run)


def run(args) -> int:
    """Build the QP, solve it, print the summary."""
    qp = load_mat(args.mat) if args.mat else random_qp(*args.random, kind=args.kind, seed=args.seed)
    print(f"problem      {qp.name}: n = {qp.n}, m = {qp.m}")
    run_solve(qp, args)
    return 0
