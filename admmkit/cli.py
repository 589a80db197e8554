"""The ``admmkit`` command line: a host that finds its sub-commands by entry point.

    admmkit --version
    admmkit solve qp | contact | obstacle ...   (one per plug-in)
    admmkit bench STUDY ...                     (one per study in benchmarks/)
    admmkit demo | reproduce ...                (top-level commands)

A package adds a command by declaring an entry point in the group
``admmkit.commands``.  The entry point's name is the command's path: ``solve.qp``
becomes ``admmkit solve qp``, ``bench.precision`` becomes ``admmkit bench
precision`` and a name without a dot (``demo``) a top-level command.  Its value
is a function ``register(subparsers)`` that adds one parser and sets ``func``
(called with the parsed arguments; its return value is the exit code).  The
host imports no plug-in: this package's own ``pyproject.toml`` declares the
built-in commands the same way a third-party package would.

This module also holds the options every ``solve`` shares (policy, order, rho,
stopping rule, history, progress) and the one place that turns an error into
one line on stderr and a non-zero exit code.
"""
from __future__ import annotations

import argparse
import shlex
import sys
from fractions import Fraction
from importlib.metadata import entry_points

from . import __version__
from .policy import make_policy, policy_names
from .result import Result
from .solver import solve
from .stopping import AnyOf, RelativeChange, ResidualTolerance, StoppingRule

#: the entry-point group that holds the sub-commands
GROUP = "admmkit.commands"
#: commands that group others (``admmkit solve NAME``, ``admmkit bench NAME``)
GROUPS = {"solve": "solve one problem and print a summary",
          "bench": "benchmarks and studies: print figures and write them where --out says (default ./out/STUDY/)"}


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0; accepts fractions such as 1/40."""
    try:
        value = float(Fraction(text)) if "/" in text else float(text)
    except (ValueError, ZeroDivisionError, OverflowError):
        raise argparse.ArgumentTypeError(f"expected a number > 0 (e.g. 1e3 or 1/40), got {text!r}") from None
    if not (0 < value < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a finite number > 0, got {text!r}")
    return value


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}")
    return value


def add_common_options(parser: argparse.ArgumentParser, *, policy: str = "summable", order: str = "zx",
                       rho: float = 1.0) -> None:
    """Options every ``solve`` sub-command shares: policy, order, rho_0 and the stop options.

    The ``--policy`` choices are the rules registered when the parser is built:
    a plug-in's command module imports ``policies`` before calling this.
    """
    parser.add_argument("--policy", default=policy, choices=policy_names(), help=f"penalty rule (default {policy})")
    parser.add_argument("--order", default=order, choices=["xz", "zx"], help=f"xz = ADMM1, zx = ADMM2 (default {order})")
    parser.add_argument("--rho", type=positive_float, default=rho, help=f"initial penalty rho_0 > 0 (default {rho:g})")
    add_stop_options(parser)


def add_stop_options(parser: argparse.ArgumentParser, *, max_iter: int = 10_000) -> None:
    """Stopping rule, iteration cap, history and progress options (read by :func:`stop_rule`)."""
    parser.add_argument("--tol", type=positive_float, default=None,
                        help="relative-change tolerance in the problem's x norm (the paper's rule; "
                             "default 1e-5 unless --eps-abs is given)")
    parser.add_argument("--eps-abs", type=positive_float, default=None, help="Boyd's residual test: absolute tolerance")
    parser.add_argument("--eps-rel", type=float, default=None,
                        help="Boyd's residual test: relative tolerance (default 0; needs --eps-abs)")
    parser.add_argument("--max-iter", type=positive_int, default=max_iter, help=f"iteration cap (default {max_iter})")
    parser.add_argument("--history", metavar="CSV", default=None, help="write the per-iteration history to this CSV file")
    parser.add_argument("--progress", type=int, default=0, metavar="N", help="print a line every N iterations")


def stop_rule(args) -> StoppingRule:
    """The stopping rule the common options ask for."""
    if args.eps_rel is not None and args.eps_abs is None:
        raise ValueError("--eps-rel needs --eps-abs (Boyd's residual test has both tolerances)")
    rules = []
    if args.eps_abs is not None:
        rules.append(ResidualTolerance(args.eps_abs, args.eps_rel or 0.0))
    if args.tol is not None or not rules:
        rules.append(RelativeChange(args.tol if args.tol is not None else 1e-5))
    return rules[0] if len(rules) == 1 else AnyOf(*rules)


def progress_callback(every: int):
    """A callback that prints one line every ``every`` iterations (None if every <= 0)."""
    if every <= 0:
        return None

    def show(rec) -> None:
        if rec.k % every == 0:
            print(f"  k={rec.k:6d}  rho={rec.rho:.3e}  primal={rec.primal_residual:.3e}  "
                  f"dual={rec.dual_residual:.3e}  rel.change={rec.rel_change:.3e}", file=sys.stderr)
    return show


def run_solve(problem, args) -> Result:
    """Solve with the common options, print the summary, write the history if asked."""
    policy = make_policy(args.policy) if isinstance(args.policy, str) else args.policy
    result = solve(problem, rho=args.rho, policy=policy, order=args.order, stop=stop_rule(args),
                   max_iter=args.max_iter, callback=progress_callback(args.progress))
    print(result.summary())
    if args.history:
        print(f"history      {result.history.to_csv(args.history)}")
    return result


def commands() -> dict[str, object]:
    """{command path: entry point} of every installed sub-command, e.g. ``{"solve.qp": EntryPoint(...)}``."""
    return {ep.name: ep for ep in entry_points(group=GROUP)}


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every installed sub-command."""
    parser = argparse.ArgumentParser(prog="admmkit", description="ADMM with adaptive penalty parameters.")
    parser.add_argument("--version", action="version", version=f"admmkit {__version__}")
    top = parser.add_subparsers(dest="command", metavar="COMMAND")
    found = commands()
    groups = {}
    for name, help_text in GROUPS.items():
        if any(path.startswith(name + ".") for path in found):
            sub = top.add_parser(name, help=help_text)
            groups[name] = sub.add_subparsers(dest=name + "_target", metavar="TARGET", required=True)
    for path in sorted(found):
        group, _, _ = path.rpartition(".")
        register = found[path].load()
        register(groups[group] if group else top)
    return parser


def command_line(argv: list[str]) -> str:
    """The command as the user typed it, for the README of what it wrote."""
    return shlex.join(["admmkit", *argv])


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``admmkit`` console script: one line on stderr and exit 2 for bad input."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    args.command_line = command_line(argv)
    try:
        return int(args.func(args) or 0)
    except (ValueError, OSError) as err:
        print(f"admmkit: error: {_one_line(err)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("admmkit: interrupted", file=sys.stderr)
        return 130


def _one_line(err: BaseException) -> str:
    if isinstance(err, OSError) and err.filename:
        return f"cannot write or read {err.filename!r}: {err.strerror or err}"
    return " ".join(str(err).split())


if __name__ == "__main__":
    sys.exit(main())
