"""``admmkit bench precision``, registered by an entry point in ``pyproject.toml`` (the study: ``study.py``)."""
from __future__ import annotations

from admmkit.cli import positive_float, positive_int
from admmkit.benchmarks.runner.options import add_study, executor_of, print_files


def precision(targets) -> None:
    """``admmkit bench precision``: work-precision of every rule and the peers."""
    p = add_study(targets, "precision", _precision,
                  help="work-precision: true error against time, every method and peer",
                  description="Error against time for every ADMM method and the peers (PDAS, cvxpy+Clarabel, "
                              "cvxpy+OSQP, OSQP) on contact, obstacle and QP problems.",
                  needs_line="ngsolve, cvxpy, clarabel, osqp (pip install 'admmkit[test]')",
                  modules=("cvxpy", "clarabel", "osqp"))      # the peers: cvxpy + Clarabel, cvxpy + OSQP, OSQP
    p.add_argument("--repeats", type=positive_int, default=3, help="repeats, median time (default 3)")
    p.add_argument("--scene", action="append", default=None, dest="scenes",
                   help="ex1, ex2, radial, qp:random-mixed, qp:DUAL2, ... (repeatable; default all)")
    p.add_argument("--h", type=positive_float, action="append", default=None, dest="hs",
                   help="mesh size (repeatable; default 1/20, 1/40, 1/80, 1/160)")
    p.add_argument("--methods", default=None, help="comma-separated ADMM methods (default: every policy, both orders)")
    p.add_argument("--time-limit", type=positive_float, default=60.0, help="seconds per ADMM/OSQP run (default 60)")


def _precision(args) -> int:
    from admmkit.benchmarks.fixtures.families import kind_of
    from admmkit.benchmarks.fixtures.methods import parse_methods
    from admmkit.benchmarks.precision import study
    for s in args.scenes or []:
        kind_of(s)   # ValueError naming the known scenes
    print_files(study.run(args.out, quick=args.quick, workers=args.workers, repeats=args.repeats,
                          scenes=args.scenes, hs=tuple(args.hs) if args.hs else None,
                          methods=parse_methods(args.methods), progress=args.progress, command=args.command_line,
                          time_limit=args.time_limit, report_only=args.report_only, executor=executor_of(args)))
    return 0
