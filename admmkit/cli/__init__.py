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

The package, by job: ``cli/host.py`` (the parser, the sub-commands and
``main``), ``cli/options.py`` (the options every ``solve`` shares:
policy, order, rho, stopping rule, history, progress, quiet, JSON and CSV
outputs; docs/cli.md), ``cli/run.py`` (a solve with them),
``cli/output.py`` (summary, files, progress display),
``cli/adaptive.py`` (the options of adaptive refinement) and
``cli/words.py`` (did-you-mean, help without markup).  ``main`` is
the one place that turns an error into one line on stderr and an exit code:

- 0: the run converged (status ``converged``);
- 1: the run ended otherwise (``max_iter``, ``diverged``, ``converged_inaccurate``,
  ``stalled``, ...): the summary says why, the files asked for are written;
- 2: bad input (an option out of range, an unknown name, an output path that
  cannot be written): one line on stderr, nothing computed, nothing written.

Every parser is a ``Parser``: a usage error is that one line too, with the
closest name for a misspelt command, option or choice, and no usage block
(``--help`` prints it); help texts are shown without markup.
"""
from .host import (COMMAND_HELP, EXIT_CLOSED_PIPE, GROUP, GROUPS, Parser, build_parser, command_line, commands,  # noqa: F401
                   main)
from .options import (EXIT_BAD_INPUT, EXIT_CONVERGED, EXIT_NOT_CONVERGED, LazyHelp, add_common_options,  # noqa: F401
                      add_output_file, add_result_outputs, add_stop_options, check_options, level_file,
                      positive_float, positive_int, resolve_policy, set_help, stop_rule)
from .output import (Progress, check_output_folder, exit_code, print_summary, provenance,  # noqa: F401
                     write_result_csv, write_result_json)
from .words import did_you_mean, plain  # noqa: F401

#: a solve's helpers (``cli/run.py``), imported on first use: they bring the loop and numpy, which the host's help
#: and a sub-command's parser do not need
_RUN_NAMES = ("progress", "run_solve", "write_history")


def __getattr__(name: str):
    """``admmkit.cli.run_solve``, ``progress`` and ``write_history``: ``cli/run.py`` imported on first use."""
    if name not in _RUN_NAMES:
        raise AttributeError(f"module 'admmkit.cli' has no attribute {name!r}")
    from . import run
    return getattr(run, name)
