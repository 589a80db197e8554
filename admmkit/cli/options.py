"""The options every ``solve`` shares, their types and the checks made before a run (docs/cli.md).

Policy, order, rho, stopping rule, history, progress, quiet, JSON and CSV outputs: a plug-in's
``register`` adds them with :func:`add_common_options` and :func:`add_result_outputs`; the host calls
:func:`check_options` before the command runs, so a bad value is refused before anything is computed.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..io import check_writable
from .output import check_output_folder
from .words import did_you_mean, plain

#: exit codes (docs/cli.md)
EXIT_CONVERGED, EXIT_NOT_CONVERGED, EXIT_BAD_INPUT = 0, 1, 2


def _fraction(text: str) -> float:
    """``float(Fraction(text))``: "1/40" as the float nearest 1/40.  Two integers divide without importing
    fractions (and decimal: 5 ms of a fresh process at load, issue #49): int / int is correctly rounded, the same
    float."""
    numerator, _, denominator = text.partition("/")
    digits = numerator[1:] if numerator[:1] in ("+", "-") else numerator
    if digits.isascii() and digits.isdigit() and denominator.isascii() and denominator.isdigit():
        return int(numerator) / int(denominator)
    from fractions import Fraction
    return float(Fraction(text))


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0; accepts fractions such as 1/40."""
    try:
        value = _fraction(text) if "/" in text else float(text)
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


class LazyHelp(argparse._StoreAction):
    """A stored option whose help is made when argparse reads it: ``help`` may be a function returning the text.

    A help that lists what is installed (the rules, the bundled scenes) reads files or every package's entry
    points; a run that names its choice reads none of them (issue #49: 20-90 ms of a fresh process).
    """

    @property
    def help(self) -> str | None:
        """The help text, made now if it was given as a function, then :meth:`expand`-ed."""
        text = self._help() if callable(self._help) else self._help
        return text if text is None or text == argparse.SUPPRESS else self.expand(text)

    @help.setter
    def help(self, text) -> None:
        self._help = text

    def expand(self, text: str) -> str:
        """The text shown (as given; a subclass adds what it lists)."""
        return plain(text)


class _PolicyOption(LazyHelp):
    """``--policy NAME``, whose help lists the methods and every rule installed when the help is shown (the list
    reads every installed package's entry points, importlib.metadata: 40-90 ms of a fresh process)."""

    def __init__(self, *args, methods: dict | None = None, **kwargs):
        self.methods = dict(methods or {})
        super().__init__(*args, **kwargs)

    def expand(self, text: str) -> str:
        """The help given, with the names of the methods and of the rules installed now: after the words
        "penalty rule or method" where the help has them, at its end otherwise."""
        from ..policy import policy_names
        names = ", ".join([*self.methods, *policy_names()])
        if "penalty rule or method" in text:
            return text.replace("penalty rule or method", f"penalty rule or method: {names}", 1)
        return f"{text} (one of: {names})"


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
    parser.add_argument("--policy", default=policy, metavar="NAME", action=_PolicyOption, methods=methods,
                        help=f"penalty rule or method (default {policy})")
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
                        help="relative-change tolerance > 0 in the problem's x norm (the paper's rule; "
                             "default 1e-5 unless --eps-abs is given)")
    parser.add_argument("--eps-abs", type=positive_float, default=None,
                        help="Boyd's residual test: absolute tolerance > 0 (default: not used)")
    parser.add_argument("--eps-rel", type=float, default=None,
                        help="Boyd's residual test: relative tolerance >= 0 (default 0; needs --eps-abs)")
    parser.add_argument("--max-iter", type=positive_int, default=max_iter,
                        help=f"iteration cap, an integer >= 1 (default {max_iter})")
    add_output_file(parser, "--history", "CSV", "write the history to this CSV file: one complete row (every "
                    "norm computed) per tested iteration, the ones where the stopping rule is checked (every "
                    "iteration; every 25th in solve qp's osqp preset) and the last")
    parser.add_argument("--history-every-iteration", action="store_true",
                        help="with --history: test the stopping rule at every iteration (check_every = 1), so "
                             "the history has a row per iteration; it changes the timing, not the iterates, though "
                             "the run may stop at an earlier iteration than a test every 25 would (it matters in "
                             "solve qp's osqp preset; the other solves test every iteration already)")
    needs = dict(parser.get_default("option_needs") or {})
    needs["history_every_iteration"] = ("--history-every-iteration", "history", "--history FILE")
    parser.set_defaults(option_needs=needs)
    parser.add_argument("--progress", type=positive_int, default=None, metavar="N",
                        help="print a line of residuals every N >= 1 iterations instead of the bar (default: a "
                             "progress bar on stderr when a run takes more than 2 s; -q for neither)")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bar or lines (the summary stays)")


def set_help(parser: argparse.ArgumentParser, **helps: str) -> None:
    """Replace the help of options already added, by destination (``tol="..."``): a plug-in whose default differs.

    A hidden option (help ``argparse.SUPPRESS``, such as the alias ``--method`` of ``--policy``) stays hidden;
    a :class:`LazyHelp`'s text (``--policy``'s list of rules) is not made to find that out."""
    for action in parser._actions:
        if action.dest in helps and vars(action).get("help", vars(action).get("_help")) != argparse.SUPPRESS:
            action.help = plain(helps[action.dest])


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
    from ..io import resolved
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
    from ..io import is_stream
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
    from ..io import is_stream
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
    from ..policy import canonical_spec, is_spec, make_policy, policy_names
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
        known = [*methods, *policy_names()]
        raise ValueError(f"--policy: unknown name {name!r}; give one of {', '.join(known)}, or module:Class or "
                         f"path/to/file.py:Class{did_you_mean(key, known)}") from None


def stop_rule(args) -> StoppingRule:
    """The stopping rule the common options ask for."""
    from ..loop.stopping import AnyOf, RelativeChange, ResidualTolerance
    if args.eps_rel is not None and args.eps_abs is None:
        raise ValueError("--eps-rel needs --eps-abs (Boyd's residual test has both tolerances)")
    rules = []
    if args.eps_abs is not None:
        rules.append(ResidualTolerance(args.eps_abs, args.eps_rel or 0.0))
    if args.tol is not None or not rules:
        rules.append(RelativeChange(args.tol if args.tol is not None else 1e-5))
    return rules[0] if len(rules) == 1 else AnyOf(*rules)


