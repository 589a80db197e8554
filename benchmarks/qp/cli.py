"""The commands of the QP studies (``admmkit bench ...``), each registered by an entry point.

One function per command, found by the host :mod:`admmkit.cli` through the
entry-point group ``admmkit.commands`` in ``pyproject.toml``; the study itself
is imported only when its command runs.  A study becomes a command through
:func:`admmkit.benchmarks.runner.options.add_study` (the shared options, its
cost and needs), or :func:`~admmkit.benchmarks.runner.options.own_parser` when
it parses its own options.
"""
from __future__ import annotations

from admmkit.cli import positive_float, positive_int
from admmkit.benchmarks.runner.options import add_executor_options, add_study, executor_of, own_parser, split_list


def maros_meszaros(targets) -> None:
    """``admmkit bench qp``: every rule and OSQP on a folder of Maros-Meszaros QPs."""
    from admmkit.benchmarks.qp import maros_meszaros as mm
    b = add_study(targets, "qp", _maros_meszaros, sweep=False, out="maros_meszaros", aliases=["maros-meszaros"],
                  help="every penalty rule, with and without OSQP's machinery, and OSQP on a folder of QPs",
                  description="Penalty rules (both orders) in OSQP's machinery and in the textbook loop, "
                              "one-off ablations, and OSQP 1.x, at absolute accuracies 1e-3 and 1e-6, judged "
                              "by the neutral criteria; writes results.csv, summary.csv, README.md and "
                              "performance profiles (PNG, SVG) to --out.",
                  needs_line="osqp, the Maros-Meszaros MAT files (--data)",
                  modules=lambda args: () if args.no_osqp else ("osqp",))
    b.add_argument("--data", required=True, metavar="DIR", help="folder of MAT files, e.g. ../shared/data/maros_meszaros")
    b.add_argument("--policies", default=None, help="comma-separated rules (default: every registered rule)")
    b.add_argument("--orders", default="xz,zx", help="comma-separated orders (default xz,zx)")
    b.add_argument("--variants", default=None, help=f"comma-separated settings variants (default {','.join(mm.VARIANTS)})")
    b.add_argument("--eps", type=positive_float, action="append", default=None,
                   help="absolute accuracy (repeatable; default 1e-3 and 1e-6)")
    b.add_argument("--max-iter", type=positive_int, default=mm.MAX_ITER, help=f"iteration cap (default {mm.MAX_ITER})")
    b.add_argument("--time-limit", type=positive_float, default=mm.TIME_LIMIT,
                   help=f"CPU seconds per run (default {mm.TIME_LIMIT:g})")
    add_executor_options(b, workers=1)
    b.add_argument("--problems", default=None, help="comma-separated problem names (default: all)")
    b.add_argument("--no-osqp", action="store_true", help="do not run OSQP itself")
    b.add_argument("--resume", action="store_true",
                   help="keep the cases already in OUT/results.jsonl (without it the sweep starts afresh)")
    b.add_argument("-q", "--quiet", "--no-progress", dest="quiet", action="store_true", help="no progress lines")


def _maros_meszaros(args) -> int:
    from admmkit.benchmarks.qp.maros_meszaros import EPS, run_benchmark
    run_benchmark(args.data, args.out, policy_names=split_list(args.policies), orders=split_list(args.orders) or (),
                  eps=tuple(args.eps) if args.eps else EPS, max_iter=args.max_iter, time_limit=args.time_limit,
                  workers=args.workers, only=split_list(args.problems), osqp_direct=not args.no_osqp,
                  resume=args.resume, command=args.command_line, progress=not args.quiet, executor=executor_of(args),
                  variants=split_list(args.variants))
    return 0


qp_fidelity = own_parser("qp-fidelity", "admmkit.benchmarks.qp.qp_fidelity",
                          "admmkit's OSQP preset against OSQP 1.x, problem by problem (Maros-Meszaros)",
                          modules=("osqp",))


qp_agreement = own_parser("qp-agreement", "admmkit.benchmarks.qp.qp_agreement",
                           "random feasible QPs against cvxpy + Clarabel", modules=("cvxpy", "clarabel"))


qp_speed = own_parser("qp-speed", "admmkit.benchmarks.qp.qp_speed",
                      "a whole QP solve (compiled and Python) against OSQP 1.x's C, problem by problem",
                      modules=("osqp",))


anderson_cost = own_parser("anderson-cost", "admmkit.benchmarks.qp.anderson_cost",
                           "what an Anderson step adds to an iteration of the compiled QP segment",
                           modules=("numba",))
