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

Every parser is a :class:`Parser`: a usage error is that one line too, with the
closest name for a misspelt command, option or choice, and no usage block
(``--help`` prints it); help texts are shown without markup.
"""
from __future__ import annotations

import argparse
import contextlib
import difflib
import os
import re
import shlex
import shutil
import sys
import textwrap
from fractions import Fraction
from importlib.metadata import PackageNotFoundError, distribution, entry_points
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
    """Replace the help of options already added, by destination (``tol="..."``): a plug-in whose default differs."""
    for action in parser._actions:
        if action.dest in helps:
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
        known = [*methods, *policy_names()]
        raise ValueError(f"--policy: unknown name {name!r}; give one of {', '.join(known)}, or module:Class or "
                         f"path/to/file.py:Class{did_you_mean(key, known)}") from None


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


def progress_callback(every: int | None):
    """A callback that prints one line every ``every`` iterations (None if ``every`` is None or <= 0)."""
    if not every or every <= 0:
        return None

    def show(rec) -> None:
        if (rec.k + 1) % every == 0:
            print(f"  iteration {rec.k + 1:6d}  rho={rec.rho:.3e}  primal={rec.primal_residual:.3e}  "
                  f"dual={rec.dual_residual:.3e}  rel.change={rec.rel_change:.3e}", file=sys.stderr)
    return show


class CompleteTested:
    """A callback that computes every norm of the tested iterations' records (iteration k with
    (k + 1) % ``every`` == 0), then calls ``inner`` (the progress display, or None).

    The history keeps the record's norms, so those rows become complete (``--history`` writes them,
    ``History.to_csv(rows="complete")``); the loop completes the last record itself.  It reads the records the
    loop computed anyway and returns what ``inner`` returns, so it changes no iterate and stops no run.
    """

    def __init__(self, every: int, inner=None) -> None:
        self.every, self.inner = int(every), inner
        self.every_record = getattr(inner, "every_record", True) if inner is not None else False

    def __call__(self, rec):
        if (rec.k + 1) % self.every == 0:
            rec.complete()
        return None if self.inner is None else self.inner(rec)


@contextlib.contextmanager
def progress(args, total: int, every: int = 1):
    """A ``Progress`` context (admmkit/cli_output.py) as the options ask, yielding the callback for the solve.

    ``--progress N``: a line every N iterations; otherwise a bar after 2 s; nothing with ``-q``.  With
    ``--history`` the callback also completes the records of the tested iterations (every ``every``-th:
    the solve's check_every), :class:`CompleteTested`.
    """
    quiet = getattr(args, "quiet", False)
    lines = None if quiet else getattr(args, "progress", None)
    with Progress(total, enabled=not quiet, lines=progress_callback(lines)) as show:
        yield CompleteTested(every, show) if getattr(args, "history", None) else show


def write_history(history, args) -> None:
    """``--history``: the complete rows of ``history`` as CSV (``History.to_csv(path, rows="complete")``), and a
    line saying where."""
    if getattr(args, "history", None):
        print(f"history      {history.to_csv(args.history, rows='complete')}")


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
    write_history(result.history, args)
    return result


def commands() -> dict[str, object]:
    """{command path: entry point} of every installed sub-command, e.g. ``{"solve.qp": EntryPoint(...)}``."""
    return {ep.name: ep for ep in entry_points(group=GROUP)}


def builtin_named(argv: list[str]) -> str | None:
    """The path of the built-in command ``argv`` names (``solve contact ...`` -> ``"solve.contact"``), else None."""
    words = [w for w in argv[:2] if not w.startswith("-")]
    for path in (".".join(words[:2]), words[0] if words else ""):
        if path in COMMAND_HELP:
            return path
    return None


def builtin_commands(path: str) -> dict[str, object] | None:
    """:func:`commands` read from admmkit's own distribution alone, if it declares ``path`` (else None).

    A command line that names a built-in command needs no other package's entry points: reading the one
    distribution took 20 ms where reading every installed package's took 90 ms (issue #49, ``solve contact``).
    """
    try:
        own = {ep.name: ep for ep in distribution("admmkit").entry_points if ep.group == GROUP}
    except PackageNotFoundError:             # a source tree that is not installed: the full search
        return None
    return own if path in own else None


def did_you_mean(word: str, candidates) -> str:
    """`` (did you mean X?)`` for the candidate closest to a misspelt ``word`` (difflib), else ``""``."""
    close = difflib.get_close_matches(str(word), [str(c) for c in candidates], n=1, cutoff=0.6)
    return f" (did you mean {close[0]}?)" if close else ""


def plain(text: str | None) -> str | None:
    """Help text without reStructuredText or Markdown markup: double or single backquotes, double or single
    stars and a role before backquotes (``:mod:`` and the like) are dropped, the text between them kept."""
    if not text:
        return text
    text = re.sub(r":[a-z]+:`~?([^`]+)`", r"\1", text)          # :mod:`admmkit.cli` -> admmkit.cli
    text = re.sub(r"`{1,2}([^`]+)`{1,2}", r"\1", text)           # ``x`` and `x` -> x
    text = re.sub(r"\*\*([^*]+)\*\*", r"\1", text)                   # **x** -> x
    return re.sub(r"(?<![\w*])\*([^*\s][^*]*?)\*(?![\w*])", r"\1", text)  # *x* -> x, but not a*b*c


def _wrap(text: str) -> str:
    """Wrap each paragraph of ``text`` to the terminal (at most 100 columns), keeping the blank lines between them."""
    width = max(40, min(100, shutil.get_terminal_size().columns) - 2)
    return "\n\n".join(textwrap.fill(" ".join(par.split()), width) for par in text.split("\n\n"))


class Parser(argparse.ArgumentParser):
    """The parser of every ``admmkit`` command: a usage error is ONE line on stderr, ``admmkit: error: ...``, exit 2.

    The line names the option and what it accepts and, for a misspelt command, option or choice, the closest
    name (``did you mean --policy?``, :func:`did_you_mean`); the usage block is printed only by ``--help``.
    Descriptions and help texts are shown without markup (:func:`plain`), each paragraph of a description on
    its own (a ``typical: ...`` paragraph stays a line of its own).  ``add_subparsers`` makes its sub-parsers
    of this class, so the plug-ins get it without asking for it.
    """

    def __init__(self, *args, **kwargs) -> None:
        for key in ("description", "epilog"):
            kwargs[key] = _wrap(plain(kwargs[key])) if kwargs.get(key) else None
        kwargs.setdefault("formatter_class", argparse.RawDescriptionHelpFormatter)
        super().__init__(*args, **kwargs)

    def add_argument(self, *args, **kwargs):
        """``ArgumentParser.add_argument`` with the help text shown without markup, and the default named
        where the help text does not name it."""
        text, default = kwargs.get("help"), kwargs.get("default")
        if isinstance(text, str) and text != argparse.SUPPRESS:
            optional = bool(args) and args[0][:1] == "-"
            if optional and "default" not in text and default not in (None, False, argparse.SUPPRESS):
                text += f" (default {', '.join(map(str, default)) if isinstance(default, (list, tuple)) else default})"
            kwargs["help"] = plain(text)
        return super().add_argument(*args, **kwargs)

    def parse_known_args(self, args=None, namespace=None):
        """``ArgumentParser.parse_known_args``, remembering the innermost parser that left arguments unread."""
        namespace, extras = super().parse_known_args(args, namespace)
        if extras and not hasattr(namespace, "_unread_by"):
            namespace._unread_by = self         # a sub-command's parser: its options are the ones to suggest
        return namespace, extras

    def parse_args(self, args=None, namespace=None):
        """``ArgumentParser.parse_args``; an unknown option is named with the closest option of its command."""
        namespace, extras = self.parse_known_args(args, namespace)
        if extras:
            self.error(vars(namespace).pop("_unread_by", self)._unknown(extras))
        for dest, (flag, other, other_flag) in (getattr(namespace, "option_needs", None) or {}).items():
            if getattr(namespace, dest, None) and not getattr(namespace, other, None):
                self.error(f"{flag} needs {other_flag}")
        return namespace

    def _unknown(self, extras: list[str]) -> str:
        word = extras[0]
        if not word.startswith("-"):
            return f"unexpected argument {word!r} for {self.prog}"
        flag = word.split("=", 1)[0]
        flags = [s for action in self._actions if action.help != argparse.SUPPRESS for s in action.option_strings]
        return f"unknown option {flag} for {self.prog}{did_you_mean(flag, flags)}"

    def _check_value(self, action, value):
        """A value outside ``choices``: the accepted values and the closest one (argparse calls this)."""
        if action.choices is None or value in action.choices:
            return
        names = [str(c) for c in action.choices]
        if isinstance(action, argparse._SubParsersAction):
            raise argparse.ArgumentError(None, f"{value!r} is not a command of {self.prog}; give one of "
                                               f"{', '.join(names)}{did_you_mean(value, names)}")
        raise argparse.ArgumentError(action, f"{value!r} is not accepted; give one of {', '.join(names)}"
                                             f"{did_you_mean(value, names)}")

    def error(self, message: str):
        """Print ``admmkit: error: MESSAGE`` as one line (no usage block) and exit with code 2."""
        message = re.sub(r"^argument ([^:]+): ", r"\1: ", str(message))
        if message.startswith("the following arguments are required"):
            commands = [a for a in self._actions if isinstance(a, argparse._SubParsersAction)]
            if commands:
                message = f"{self.prog} needs a command: one of {', '.join(commands[0].choices)}"
            else:
                message = f"{self.prog}: {message}"
        print(f"admmkit: error: {' '.join(message.split())}", file=sys.stderr)
        raise SystemExit(EXIT_BAD_INPUT)


#: each built-in command's one-line help, shown by ``admmkit --help`` and ``admmkit bench --help`` without importing
#: the command (its registrar, and the plug-in or study behind it, load only when the command line names it;
#: tests/admmkit/test_first_call_paths.py checks that each line is the one its registrar gives)
COMMAND_HELP = {
    "demo": "the main job: solve the paper's two examples with SADMM and plot them",
    "reproduce": "reproduce a paper's tables and figures",
    "warm-up": "compile (or load from numba's cache) every compiled kernel now, so that no later call waits for it",
    "solve.contact": "elastic contact with a rigid foundation, with or without friction (NGSolve, 2D and 3D)",
    "solve.obstacle": "-Delta u = f, u >= psi, u = u_D (P1 or P2, NGSolve)",
    "solve.qp": "min 1/2 x'Px + q'x s.t. l <= Ax <= u (OSQP's form)",
    "bench.adaptive": "adaptive against uniform refinement at the same true error (contact Examples 1 and 2, Hertz, "
                      "radial obstacle)",
    "bench.amg-crossover": "full / condensed / iterative x-steps against size; AMG reuse across rho",
    "bench.contact": "SADMM time / (one factorisation + solve of K), Ex. 1-2",
    "bench.contact-schur": "the Schur complement's set-up by backend, Ex. 1-2, and SADMM / (factor + solve)",
    "bench.contact3d": "3D block on a curved foundation with the AMG x-step; direct vs AMG",
    "bench.estimators": "ZZ and residual error estimators against the true error (obstacle, contact Example 1)",
    "bench.executors": "the bench-policies sweep on 2 local processes and a 2-worker Dask LocalCluster: iterations "
                       "identical?, wall-time ratio",
    "bench.first-call": "fresh processes side by side with OSQP: import, first solve (cached and empty kernel cache), "
                        "the cvxpy route, --help, a whole solve contact",
    "bench.four-problems": "LASSO, weighted box LS, consensus and 2-D TV with the building blocks, against cvxpy",
    "bench.friction": "Cattaneo-Mindlin partial slip under refinement, and every rule on frictional contact",
    "bench.hertz": "Hertz validation: half-cylinder on a rigid plane, a and p0 vs Hertz",
    "bench.linsolve": "sparse direct backends from 1e3 to 1e6 unknowns, 1 and 2 threads",
    "bench.loop-overhead": "the loop's cost per iteration against a bare numpy loop of the same updates",
    "bench.obstacle": "obstacle problem: convergence rates against the exact solution, rho sweep",
    "bench.paper-compare": "our ADMM1/ADMM2/SADMM times and iterations beside the paper's tables",
    "bench.policies": "penalty rules on contact Ex.1 and the radial obstacle, rho_0 over 12 decades",
    "bench.precision": "work-precision: true error against time, every method and peer",
    "bench.qp": "every penalty rule, with and without OSQP's machinery, and OSQP on a folder of QPs",
    "bench.qp-agreement": "random feasible QPs against cvxpy + Clarabel",
    "bench.qp-fidelity": "admmkit's OSQP preset against OSQP 1.x, problem by problem (Maros-Meszaros)",
    "bench.qp-speed": "a whole QP solve (compiled and Python) against OSQP 1.x's C, problem by problem",
    "bench.rules": "rank the penalty rules (and yours) on every family, with acceleration",
    "bench.scale": "Example 1 with the iterative x-step from 1e3 to 1e6 unknowns: time, memory",
    "bench.split-speed": "time per iteration of the building blocks, compiled segment against the Python loop",
    "bench.stability": "rho_0 over 13 decades, mesh, nu, P1/P2: iterations and failures",
}


class _Commands(argparse._SubParsersAction):
    """Sub-commands that load their registrar only when the command line names them.

    :meth:`add_command` adds a bare parser with the command's one-line help
    (:data:`COMMAND_HELP`), enough for the list of ``--help`` and for a
    did-you-mean on a misspelt name; when argparse reaches the command (the
    command line names it), :meth:`load` replaces the bare parser with the one
    its registrar builds, in the same place of the list.
    """

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.pending = {}            # command name -> (entry-point path, entry point) not loaded yet

    def add_command(self, name: str, path: str, entry_point) -> None:
        """A bare parser for the command ``name`` (entry point ``path``); its registrar waits for :meth:`load`."""
        self.add_parser(name, help=COMMAND_HELP.get(path, f"(a plug-in command: admmkit {path.replace('.', ' ')} "
                                                          f"--help says more)"), add_help=False)
        self.pending[name] = (path, entry_point)

    def load(self, name: str) -> None:
        """Replace the bare parser of ``name`` with its registrar's (a broken plug-in: one that says why)."""
        if name not in self.pending:
            return
        path, entry_point = self.pending.pop(name)
        order = list(self._name_parser_map)
        del self._name_parser_map[name]
        self._choices_actions = [a for a in self._choices_actions if a.dest != name]
        try:
            register = entry_point.load()
        except Exception as err:     # a broken plug-in (ImportError, SyntaxError, ...): its command says so, the others work
            register = _unloadable(name, entry_point.value, err)
        register(self)
        rank = {key: i for i, key in enumerate(order)}
        self._name_parser_map = dict(sorted(self._name_parser_map.items(), key=lambda kv: rank.get(kv[0], len(rank))))
        self.choices = self._name_parser_map
        self._choices_actions.sort(key=lambda a: rank.get(a.dest, len(rank)))

    def load_all(self) -> None:
        """Load every pending command (and the commands of the groups among them)."""
        for name in list(self.pending):
            self.load(name)
        for sub in self._name_parser_map.values():
            for action in sub._actions:
                if isinstance(action, _Commands):
                    action.load_all()

    def __call__(self, parser, namespace, values, option_string=None):
        """argparse reached the command ``values[0]``: load it, then parse its arguments."""
        if values:
            self.load(values[0])
        super().__call__(parser, namespace, values, option_string)


def build_parser(*, load_all: bool = False, named: str | None = None) -> argparse.ArgumentParser:
    """The argument parser with every installed sub-command.

    A command's registrar (and the plug-in or study it imports) loads only
    when the command line names it: ``admmkit --help`` and ``admmkit solve qp
    ...`` import no other plug-in.  ``load_all``: load every registrar now
    (a check that each loads and registers).  ``named``: the built-in command
    the command line names (:func:`builtin_named`): then only admmkit's own
    commands are listed, without searching every installed package.
    """
    parser = Parser(prog="admmkit", description="ADMM with adaptive penalty parameters.",
                    epilog="exit codes: 0 converged, 1 the run ended otherwise "
                           "(max_iter, diverged, converged_inaccurate, ...), 2 bad input")
    parser.add_argument("--version", action="version", version=f"admmkit {__version__}")
    top = parser.add_subparsers(dest="command", metavar="COMMAND", action=_Commands)
    found = (builtin_commands(named) if named else None) or commands()
    groups = {}
    for name, help_text in GROUPS.items():
        if any(path.startswith(name + ".") for path in found):
            sub = top.add_parser(name, help=help_text, description=help_text[0].upper() + help_text[1:] + ".")
            groups[name] = sub.add_subparsers(dest=name + "_target", metavar="TARGET", required=True,
                                              action=_Commands)
    for path in sorted(found):
        group, _, name = path.rpartition(".")
        (groups[group] if group else top).add_command(name, path, found[path])
    if load_all:
        top.load_all()
    return parser


def _unloadable(name: str, where: str, err: BaseException):
    """A ``register`` for a command whose entry point does not load: running it is one line, exit 2."""
    reason = f"the command {name!r} ({where}) could not be loaded: {type(err).__name__}: {err}"

    def fail(args):
        raise ValueError(reason)

    def register(subparsers) -> None:
        p = subparsers.add_parser(name, help="(could not be loaded: run it to see why)", description=reason,
                                  add_help=False, prefix_chars="\0")
        p.add_argument("argv", nargs=argparse.REMAINDER)
        p.set_defaults(func=fail)
    return register


def command_line(argv: list[str]) -> str:
    """The command as the user typed it, for the README of what it wrote."""
    return shlex.join(["admmkit", *argv])


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``admmkit`` console script; returns the exit code (0, 1 or 2, see the module)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(named=builtin_named(argv))
    try:
        args = parser.parse_args(argv)
    except SystemExit as stop:                  # Parser.error: its one line is on stderr (or --help printed)
        return int(stop.code or 0)
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    args.command_line = command_line(argv)
    try:
        check_options(args)
        with text_to_stderr(writes_stdout(args)):
            code = run_command(args)
        sys.stdout.flush()                      # a closed pipe shows here, not in Python's shutdown
        return code
    except BrokenPipeError:                     # the reader of stdout left (| head): end quietly, as Unix tools do
        quiet_stdout()
        return EXIT_CLOSED_PIPE
    except (ValueError, OSError) as err:
        print(f"admmkit: error: {_one_line(err)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("admmkit: interrupted", file=sys.stderr)
        return 130


#: the exit code of a run whose standard output was closed by its reader (128 + SIGPIPE, as ``yes | head``)
EXIT_CLOSED_PIPE = 141


def run_command(args) -> int:
    """``args.func(args)`` as an exit code; a ``sys.exit(CODE)`` in user code (a rule's ``update``) is bad input.

    The command's own ``SystemExit`` would end the program silently with the code user code chose (0 after
    a rule called ``sys.exit(0)``); here it becomes a ValueError, one line and exit 2.
    """
    try:
        return int(args.func(args) or 0)
    except SystemExit as stop:
        raise ValueError(f"user code called sys.exit({stop.code!r}) during the run") from None


def writes_stdout(args) -> bool:
    """True if an output option names ``-`` (standard output): then the text lines go to stderr."""
    from .io import STDOUT
    return any(value == STDOUT for _, value, _ in output_options(args))


class StdoutForData:
    """Standard output while a file is written to ``-``: text goes to stderr, the file to stdout.

    :mod:`admmkit.io` writes ``-`` through ``sys.stdout.buffer``, the bytes of the real standard output;
    ``print`` (the summary, the plug-in's lines) writes text, which goes to stderr.  So ``--json - | jq``
    reads the JSON alone.
    """

    def __init__(self, stdout, stderr) -> None:
        self.buffer, self._stdout, self._stderr = stdout.buffer, stdout, stderr

    def write(self, text: str) -> int:
        """Write ``text`` to stderr."""
        return self._stderr.write(text)

    def flush(self) -> None:
        """Flush both streams."""
        self._stderr.flush()
        self._stdout.flush()

    def __getattr__(self, name):
        return getattr(self._stderr, name)


@contextlib.contextmanager
def text_to_stderr(enabled: bool):
    """While ``enabled``: ``sys.stdout`` is a :class:`StdoutForData` (a stdout without bytes keeps it all)."""
    if not enabled or getattr(sys.stdout, "buffer", None) is None:
        yield
        return
    stdout = sys.stdout
    sys.stdout = StdoutForData(stdout, sys.stderr)
    try:
        yield
    finally:
        sys.stdout = stdout


def quiet_stdout() -> None:
    """Point standard output at the null device: Python's last flush into a closed pipe then prints nothing."""
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):       # not a file descriptor (a notebook, a test's capture)
        sys.stdout = open(os.devnull, "w")
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, fd)
    os.close(devnull)


def _one_line(err: BaseException) -> str:
    if isinstance(err, OSError) and err.filename:
        return f"cannot write or read {err.filename!r}: {err.strerror or err}"
    return " ".join(str(err).split())


if __name__ == "__main__":
    sys.exit(main())
