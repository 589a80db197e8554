"""The ``admmkit`` command line.

    admmkit --version
    admmkit solve qp --mat FILE | --random N M  [--policy summable --order zx --rho 1 ...]
    admmkit solve contact ...      (problems.contact)
    admmkit solve obstacle ...     (problems.obstacle)
    admmkit demo                   the main job: the paper's examples with SADMM

Each module in :data:`PLUGINS` may define, in any combination,
``add_solve_parser(subparsers)`` (an ``admmkit solve NAME`` sub-command),
``add_bench_parser(targets)`` (an ``admmkit bench TARGET`` sub-command) and
``add_commands(commands)`` (new top-level commands such as ``reproduce``).
Common options (policy, order, rho, stopping rule, history) are added by
:func:`add_common_options`.
"""
from __future__ import annotations

import argparse
import importlib
import sys
from fractions import Fraction

import admmkit
import policies  # noqa: F401  (registers the built-in rules)
from admmkit import RelativeChange, ResidualTolerance

#: command-line plug-ins (solve / bench / other commands); a missing one is skipped
PLUGINS = ("problems.qp.cli", "problems.contact.cli", "problems.obstacle.cli", "problems.benchmarks.cli", "problems.contact.cli_scale",
           "problems.policy_sweep")


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0; accepts fractions such as 1/40."""
    try:
        value = float(Fraction(text)) if "/" in text else float(text)
    except (ValueError, ZeroDivisionError):
        raise argparse.ArgumentTypeError(f"expected a number > 0 (e.g. 1e3 or 1/40), got {text!r}") from None
    if not (value > 0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text!r}")
    return value


def add_common_options(parser: argparse.ArgumentParser, *, policy: str = "summable", order: str = "zx",
                       rho: float = 1.0) -> None:
    """Options every ``solve`` sub-command shares."""
    parser.add_argument("--policy", default=policy, choices=admmkit.policy_names(), help=f"penalty rule (default {policy})")
    parser.add_argument("--order", default=order, choices=["xz", "zx"], help=f"xz = ADMM1, zx = ADMM2 (default {order})")
    parser.add_argument("--rho", type=positive_float, default=rho, help=f"initial penalty rho_0 > 0 (default {rho:g})")
    add_stop_options(parser)


def add_stop_options(parser: argparse.ArgumentParser, *, max_iter: int = 10_000) -> None:
    """Stopping rule, iteration cap, history and progress options (read by :func:`stop_rule`)."""
    parser.add_argument("--tol", type=positive_float, default=None,
                        help="relative-change tolerance in the problem's x norm (the paper's rule; "
                             "default 1e-5 unless --eps-abs is given)")
    parser.add_argument("--eps-abs", type=positive_float, default=None, help="Boyd's residual test: absolute tolerance")
    parser.add_argument("--eps-rel", type=float, default=0.0, help="Boyd's residual test: relative tolerance (default 0)")
    parser.add_argument("--max-iter", type=int, default=max_iter, help=f"iteration cap (default {max_iter})")
    parser.add_argument("--history", metavar="CSV", default=None, help="write the per-iteration history to this CSV file")
    parser.add_argument("--progress", type=int, default=0, metavar="N", help="print a line every N iterations")


def stop_rule(args) -> admmkit.StoppingRule:
    """The stopping rule the common options ask for."""
    rules = []
    if args.eps_abs is not None:
        rules.append(ResidualTolerance(args.eps_abs, args.eps_rel))
    if args.tol is not None or not rules:
        rules.append(RelativeChange(args.tol if args.tol is not None else 1e-5))
    return rules[0] if len(rules) == 1 else admmkit.AnyOf(*rules)


def progress_callback(every: int):
    """A callback that prints one line every ``every`` iterations (None if every <= 0)."""
    if every <= 0:
        return None

    def show(rec: admmkit.IterationRecord) -> None:
        if rec.k % every == 0:
            print(f"  k={rec.k:6d}  rho={rec.rho:.3e}  primal={rec.primal_residual:.3e}  "
                  f"dual={rec.dual_residual:.3e}  rel.change={rec.rel_change:.3e}", file=sys.stderr)
    return show


def run_solve(problem, args) -> admmkit.Result:
    """Solve with the common options, print the summary, write the history if asked."""
    if args.max_iter < 1:
        raise SystemExit(f"admmkit: error: --max-iter must be >= 1, got {args.max_iter}")
    result = admmkit.solve(problem, rho=args.rho, policy=args.policy, order=args.order, stop=stop_rule(args),
                           max_iter=args.max_iter, callback=progress_callback(args.progress))
    print(result.summary())
    if args.history:
        print(f"history      {result.history.to_csv(args.history)}")
    return result


def demo(args) -> int:
    """The main job: the paper's examples with SADMM (a QP demo if the contact plug-in is absent)."""
    try:
        from problems.contact.demo import run_demo
    except ModuleNotFoundError:
        from problems.qp import random_qp
        qp = random_qp(200, 300, kind="mixed", seed=0)
        print(f"QP demo ({qp.name}) with the paper's self-adaptive rule, order zx:")
        print(admmkit.solve(qp, rho=1.0, policy="summable", order="zx", stop=ResidualTolerance(1e-8, 1e-8)).summary())
        return 0
    return run_demo(args.out)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every installed plug-in's sub-commands."""
    parser = argparse.ArgumentParser(prog="admmkit", description="ADMM with adaptive penalty parameters.")
    parser.add_argument("--version", action="version", version=f"admmkit {admmkit.__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    d = commands.add_parser("demo", help="the main job: solve the paper's two examples with SADMM and plot them")
    d.add_argument("--out", default="out/demo", help="folder for the figures (default out/demo)")
    d.set_defaults(func=demo)
    solve = commands.add_parser("solve", help="solve one problem and print a summary")
    problems = solve.add_subparsers(dest="problem", metavar="PROBLEM", required=True)
    bench = commands.add_parser("bench", help="benchmarks: print figures and write them under docs/results/")
    targets = bench.add_subparsers(dest="target", metavar="TARGET", required=True)
    for name in PLUGINS:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as err:
            if err.name and name.startswith(err.name):  # plug-in not present
                continue
            raise
        if hasattr(module, "add_solve_parser"):
            module.add_solve_parser(problems)
        if hasattr(module, "add_bench_parser"):
            module.add_bench_parser(targets)
        if hasattr(module, "add_commands"):
            module.add_commands(commands)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``admmkit`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    try:
        return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError) as err:
        print(f"admmkit: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
