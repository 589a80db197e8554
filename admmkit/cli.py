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
stopping rule, history, progress, quiet, JSON and CSV outputs; docs/cli.md)
and the one place that turns an error into one line on stderr and an exit code:

- 0: the run converged (status ``converged``);
- 1: the run ended otherwise (``max_iter``, ``diverged``, ``converged_inaccurate``,
  ``stalled``, ...): the summary says why, the files asked for are written;
- 2: bad input (an option out of range, an unknown name, an output path that
  cannot be written): one line on stderr, nothing computed, nothing written.
"""
from __future__ import annotations

import argparse
import shlex
import sys
from fractions import Fraction
from importlib.metadata import entry_points
from pathlib import Path

from . import __version__
from .cli_output import (Progress, check_output_folder, exit_code, print_summary,  # noqa: F401  (re-exported)
                         provenance, write_result_csv, write_result_json)
from .io import check_writable
from .policy import canonical_spec, is_spec, make_policy, policy_names
from .result import Result
from .solver import solve
from .stopping import AnyOf, RelativeChange, ResidualTolerance, StoppingRule

#: the entry-point group that holds the sub-commands
GROUP = "admmkit.commands"
#: commands that group others (``admmkit solve NAME``, ``admmkit bench NAME``)
GROUPS = {"solve": "solve one problem and print a summary",
          "bench": "benchmarks and studies: print figures and write them where --out says (default ./out/STUDY/)"}
#: exit codes (docs/cli.md)
EXIT_CONVERGED, EXIT_NOT_CONVERGED, EXIT_BAD_INPUT = 0, 1, 2


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


class _DeprecatedAlias(argparse.Action):
    """Store into ``dest`` like the new option, with a note on stderr (``--method`` -> ``--policy``)."""

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"admmkit: {option_string} is deprecated; use {self.metavar}", file=sys.stderr)
        setattr(namespace, self.dest, values)


def add_common_options(parser: argparse.ArgumentParser, *, policy: str = "summable", order: str = "zx",
                       rho: float = 1.0, methods: dict | None = None, max_iter: int = 10_000) -> None:
    """Options every ``solve`` sub-command shares: policy, order, rho_0, the stop and output options.

    ``methods`` maps extra names to ``(order, factory)`` (the paper's
    ``admm1``/``admm2``/``sadmm``: ``admmkit.policies.paper_methods.PAPER_METHODS``);
    such a name runs in its own order unless ``--order`` is given, a
    registered rule in ``order``.  ``--method`` stays as a deprecated alias.
    """
    names = [*(methods or {}), *policy_names()]
    parser.add_argument("--policy", default=policy, metavar="NAME",
                        help=f"penalty rule or method: {', '.join(names)} (default {policy})")
    parser.add_argument("--method", dest="policy", action=_DeprecatedAlias, metavar="--policy",
                        help=argparse.SUPPRESS)
    parser.add_argument("--order", default=None, choices=["xz", "zx"],
                        help=f"xz = ADMM1, zx = ADMM2 (default: the method's own, else {order})")
    parser.add_argument("--rho", type=positive_float, default=rho, help=f"initial penalty rho_0 > 0 (default {rho:g})")
    parser.set_defaults(policy_methods=dict(methods or {}), default_order=order)
    add_stop_options(parser, max_iter=max_iter)


def add_stop_options(parser: argparse.ArgumentParser, *, max_iter: int = 10_000) -> None:
    """Stopping rule, iteration cap, history, progress and quiet options (read by :func:`stop_rule`)."""
    parser.add_argument("--tol", type=positive_float, default=None,
                        help="relative-change tolerance in the problem's x norm (the paper's rule; "
                             "default 1e-5 unless --eps-abs is given)")
    parser.add_argument("--eps-abs", type=positive_float, default=None, help="Boyd's residual test: absolute tolerance")
    parser.add_argument("--eps-rel", type=float, default=None,
                        help="Boyd's residual test: relative tolerance (default 0; needs --eps-abs)")
    parser.add_argument("--max-iter", type=positive_int, default=max_iter, help=f"iteration cap (default {max_iter})")
    add_output_file(parser, "--history", "CSV", "write the per-iteration history to this CSV file")
    parser.add_argument("--progress", type=int, default=0, metavar="N",
                        help="print a line of residuals every N iterations (default: a progress bar on "
                             "stderr when a run takes more than 2 s)")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bar or lines (the summary stays)")


def add_output_file(parser: argparse.ArgumentParser, flag: str, metavar: str, help: str,
                    extensions: tuple[str, ...] = ()) -> None:
    """Add an output-file option that :func:`check_outputs` checks before any work (docs/cli.md, "Output files").

    ``extensions``: the endings a file name must have (``(".vtu",)`` for
    ``--vtk``), checked and never appended: the file is written under the
    name given.  Empty: any name.
    """
    parser.add_argument(flag, metavar=metavar, default=None, help=help)
    dest = flag.lstrip("-").replace("-", "_")
    files = dict(parser.get_default("output_files") or {})
    files[dest] = (flag, tuple(extensions))
    parser.set_defaults(output_files=files)


def add_result_outputs(parser: argparse.ArgumentParser, json_help: str, csv_help: str) -> None:
    """``--json FILE`` and ``--csv FILE``, the same two names in every ``solve``."""
    add_output_file(parser, "--json", "FILE", json_help)
    add_output_file(parser, "--csv", "FILE", csv_help)


def check_options(args) -> None:
    """Refuse bad input before any work: the policy name, the stop options and every output path."""
    if hasattr(args, "default_order"):           # add_common_options was used
        resolve_policy(args)
        stop_rule(args)
    check_outputs(args)


def check_outputs(args) -> None:
    """Refuse, before any work, every output file that cannot be written as asked (docs/cli.md, "Output files").

    Each path must pass :func:`admmkit.io.check_writable` (not empty, not a
    folder, its folder existing and writable), a file name must end in one of
    its option's extensions, and no two options may name the same file
    (compared after following symbolic links; ``-`` is standard output).
    A ``--out`` folder must not be a file.
    """
    from .io import resolved
    seen = {}
    for flag, value, extensions in output_options(args):
        check_writable(value, flag)
        if flag == "--vtk" and writes_levels(args):
            check_level_base(value)                  # a base name: FILE_level<k>.vtu are written, not FILE itself
            continue
        check_extension(flag, value, extensions)
        key = str(resolved(value))
        if key in seen:
            raise ValueError(same_file_message(*seen[key], flag, value, key))
        seen[key] = (flag, value)
    if isinstance(getattr(args, "out", None), str):
        check_output_folder(args.out, "--out")


def output_options(args) -> list[tuple[str, str, tuple[str, ...]]]:
    """(flag, path, accepted extensions) of every output-file option given (:func:`add_output_file`)."""
    given = []
    for dest, (flag, extensions) in (getattr(args, "output_files", None) or {}).items():
        value = getattr(args, dest, None)
        if value is not None:
            given.append((flag, str(value), (extensions,) if isinstance(extensions, str) and extensions
                          else tuple(extensions or ())))
    return given


def check_extension(flag: str, value: str, extensions: tuple[str, ...]) -> None:
    """Refuse a file name without one of ``extensions`` (a stream, ``-`` or a FIFO, takes any name)."""
    from .io import is_stream
    if extensions and value and not is_stream(value) and Path(value).suffix.lower() not in extensions:
        raise ValueError(f"{flag} {value!r}: give a file name ending in {' or '.join(extensions)} "
                         f"(the file is written under the name given, never renamed)")


def same_file_message(flag_a: str, value_a: str, flag_b: str, value_b: str, target: str) -> str:
    """One line naming both options that name one file."""
    if value_a == value_b:
        return f"{flag_a} and {flag_b} name the same file {value_a!r}; give each output its own file"
    return (f"{flag_a} {value_a!r} and {flag_b} {value_b!r} name the same file {target!r}; "
            f"give each output its own file")


def writes_levels(args) -> bool:
    """True if ``--vtk`` names one file per level: ``--target-error`` was given (docs/obstacle.md, docs/contact.md)."""
    return bool(getattr(args, "vtk", None)) and getattr(args, "target_error", None) is not None


def check_level_base(value: str) -> None:
    """Refuse a ``--vtk`` base name that cannot take ``_level<k>.vtu``: a stream, or another extension than .vtu."""
    from .io import is_stream
    if is_stream(value) or Path(value).suffix.lower() not in ("", ".vtu"):
        raise ValueError(f"--vtk {value!r}: with --target-error, --vtk writes one file per level, FILE_level<k>.vtu; "
                         f"give FILE or FILE.vtu")


def level_file(base: str | Path, k: int) -> Path:
    """The VTU file of level ``k`` for the ``--vtk`` name ``base``: ``out/u`` or ``out/u.vtu`` -> ``out/u_level3.vtu``."""
    base = Path(base)
    stem = base.name[:-4] if base.name.lower().endswith(".vtu") else base.name
    return base.with_name(f"{stem}_level{k}.vtu")


def resolve_policy(args) -> tuple[str, object, str]:
    """(order, fresh policy, name) from ``--policy`` and ``--order``; ValueError naming ``--policy``."""
    name = args.policy if isinstance(args.policy, str) else None
    if name is None:                                           # a Policy object (from Python)
        return args.order or args.default_order, args.policy, type(args.policy).__name__
    if is_spec(name):                                          # module:Class or path/to/file.py:Class
        try:
            return args.order or getattr(args, "default_order", "zx"), make_policy(canonical_spec(name)), name
        except (TypeError, ValueError) as err:
            raise ValueError(f"--policy: {err}") from None
    key = name.strip().lower().replace("-", "_")
    methods = getattr(args, "policy_methods", None) or {}
    if key in methods:
        own_order, make = methods[key]
        return args.order or own_order, make(), key
    try:
        return args.order or getattr(args, "default_order", "zx"), make_policy(key), key
    except ValueError:
        raise ValueError(f"--policy: unknown name {name!r}; give one of "
                         f"{', '.join([*methods, *policy_names()])}, or module:Class or path/to/file.py:Class") from None


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
        if (rec.k + 1) % every == 0:
            print(f"  iteration {rec.k + 1:6d}  rho={rec.rho:.3e}  primal={rec.primal_residual:.3e}  "
                  f"dual={rec.dual_residual:.3e}  rel.change={rec.rel_change:.3e}", file=sys.stderr)
    return show


def progress(args, total: int):
    """A ``Progress`` context (admmkit/cli_output.py) as the options ask.

    ``--progress N``: a line every N iterations; otherwise a bar after 2 s; nothing with ``-q``.
    """
    lines = 0 if getattr(args, "quiet", False) else getattr(args, "progress", 0)
    return Progress(total, enabled=not getattr(args, "quiet", False), lines=progress_callback(lines))


def run_solve(problem, args, stop: StoppingRule | None = None) -> Result:
    """Solve with the common options, print the summary, write the history if asked.

    ``stop``: a plug-in's own stopping rule (e.g. one balanced with its error estimate) in place of the
    one the common options ask for.
    """
    order, policy, name = resolve_policy(args)
    stop = stop if stop is not None else stop_rule(args)
    with progress(args, args.max_iter) as show:
        result = solve(problem, rho=args.rho, policy=policy, order=order, stop=stop,
                       max_iter=args.max_iter, callback=show)
    args.resolved = {"policy": name, "order": order, "policy_repr": repr(policy), "stop": stop.name}
    print_summary(result, name, args.rho)
    if args.history:
        print(f"history      {result.history.to_csv(args.history)}")
    return result


def commands() -> dict[str, object]:
    """{command path: entry point} of every installed sub-command, e.g. ``{"solve.qp": EntryPoint(...)}``."""
    return {ep.name: ep for ep in entry_points(group=GROUP)}


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every installed sub-command."""
    parser = argparse.ArgumentParser(prog="admmkit", description="ADMM with adaptive penalty parameters.",
                                     epilog="exit codes: 0 converged, 1 the run ended otherwise "
                                            "(max_iter, diverged, converged_inaccurate, ...), 2 bad input")
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
    """Entry point of the ``admmkit`` console script; returns the exit code (0, 1 or 2, see the module)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as stop:                  # argparse: usage and one error line already on stderr
        return int(stop.code or 0)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    args.command_line = command_line(argv)
    try:
        check_options(args)
        return int(args.func(args) or 0)
    except (ValueError, OSError) as err:
        print(f"admmkit: error: {_one_line(err)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("admmkit: interrupted", file=sys.stderr)
        return 130


def _one_line(err: BaseException) -> str:
    if isinstance(err, OSError) and err.filename:
        return f"cannot write or read {err.filename!r}: {err.strerror or err}"
    return " ".join(str(err).split())


if __name__ == "__main__":
    sys.exit(main())
