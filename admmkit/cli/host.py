"""The host of the ``admmkit`` command line: the parser, the sub-commands found by entry point, ``main``.

Every parser is a :class:`Parser`: a usage error is one line, ``admmkit: error: ...``, with the closest
name for a misspelt command, option or choice, and no usage block (``--help`` prints it); help texts are
shown without markup.  :func:`main` turns an error into that one line and an exit code (docs/cli.md).
"""
from __future__ import annotations

import argparse
import contextlib
import os
import re
import shlex
import shutil
import sys
import textwrap

from .. import __version__
from ..installed import own_entry_points
from .deferred_modules import defer_unused_numpy_modules
from .options import EXIT_BAD_INPUT, check_options, output_options
from .words import did_you_mean, plain

#: the entry-point group that holds the sub-commands
GROUP = "admmkit.commands"
#: commands that group others (``admmkit solve NAME``, ``admmkit bench NAME``)
GROUPS = {"solve": "solve one problem and print a summary",
          "bench": "benchmarks and studies: print figures and write them where --out says (default ./out/STUDY/)"}


def commands() -> dict[str, object]:
    """{command path: entry point} of every installed sub-command, e.g. ``{"solve.qp": EntryPoint(...)}``."""
    from importlib.metadata import entry_points
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
    distribution's took 20 ms where reading every installed package's took 90 ms (issue #49, ``solve contact``),
    and reading its ``entry_points.txt`` without importing importlib.metadata 1-6 ms
    (:mod:`admmkit.installed`).
    """
    own = own_entry_points(GROUP)
    return own if own and path in own else None             # None: not installed, the full search


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
    "bench.anderson-cost": "what an Anderson step adds to an iteration of the compiled QP segment",
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
    """Entry point of the ``admmkit`` console script; returns the exit code (0, 1 or 2, see the module).

    Called without ``argv`` (the console script, ``python -m admmkit``), the process is the command line's:
    numpy's test tools and f2py, which ``import scipy`` would run, load at first use instead
    (:mod:`admmkit.cli.deferred_modules`)."""
    if argv is None:
        defer_unused_numpy_modules()
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
    from ..io import STDOUT
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

