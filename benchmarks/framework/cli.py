"""The commands of the framework's own studies (``admmkit bench ...``), each registered by an entry point.

One function per command, found by the host :mod:`admmkit.cli` through the
entry-point group ``admmkit.commands`` in ``pyproject.toml``; the study itself
is imported only when its command runs.  A study becomes a command through
:func:`admmkit.benchmarks.runner.options.add_study` (the shared options, its
cost and needs), or :func:`~admmkit.benchmarks.runner.options.own_parser` when
it parses its own options.
"""
from __future__ import annotations

from admmkit.cli import positive_int
from admmkit.benchmarks.runner.options import add_study, own_parser, print_files


def executors(targets) -> None:
    """``admmkit bench executors``: the same sweep on local processes and on a Dask LocalCluster."""
    e = add_study(targets, "executors", _executors, sweep=False,
                  help="the bench-policies sweep on 2 local processes and a 2-worker Dask "
                       "LocalCluster: iterations identical?, wall-time ratio",
                  description="Runs the cases of `admmkit bench policies` on both executors, one after "
                              "the other, and compares iteration counts and wall times (needs dask).",
                  needs_line="ngsolve, dask[distributed] (pip install 'admmkit[sweep]')",
                  modules=("dask", "distributed", "cvxpy", "clarabel"))   # Dask; the references of bench policies
    e.add_argument("--quick", action="store_true", help="the coarse smoke grid of bench policies")
    e.add_argument("--rounds", type=positive_int, default=2,
                   help="rounds of the three executors, the order reversed every second round (default 2)")
    e.add_argument("-q", "--quiet", "--no-progress", dest="progress", action="store_false", help="no progress line")


def _executors(args) -> int:
    from admmkit.benchmarks.framework.executors import run
    print_files(run(args.out, quick=args.quick, rounds=args.rounds, progress=args.progress,
                     command=args.command_line))
    return 0


loop_overhead = own_parser("loop-overhead", "admmkit.benchmarks.framework.loop_overhead",
                            "the loop's cost per iteration against a bare numpy loop of the same updates")


four_problems = own_parser("four-problems", "admmkit.benchmarks.framework.four_problems",
                            "LASSO, weighted box LS, consensus and 2-D TV with the building blocks, against cvxpy",
                            modules=("cvxpy",))


split_speed = own_parser("split-speed", "admmkit.benchmarks.framework.split_segment_speed",
                         "time per iteration of the building blocks, compiled segment against the Python loop")


first_call = own_parser("first-call", "admmkit.benchmarks.framework.first_call",
                        "fresh processes side by side with OSQP: import, first solve (cached and empty kernel "
                        "cache), the cvxpy route, --help, a whole solve contact")
