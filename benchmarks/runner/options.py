"""The shared pieces of every study's command: the output folder, where a sweep runs, the sweep options.

Each subject's ``cli.py`` (``admmkit.benchmarks.<subject>.cli``) registers its
commands with these, so that every study takes the same options with the same
meanings (``--out``, ``--workers``, ``--dask-workers``, ``--scheduler``,
``--case-timeout``, ``--chunk``, ``--quick``, ``--report-only``, ``-q``).
"""
from __future__ import annotations

import argparse
import functools
import importlib
import sys
from pathlib import Path

from admmkit.cli import positive_float, positive_int  # noqa: F401  (positive_float: for the studies' own options)
from admmkit.benchmarks.runner.costs import announce, typical
from admmkit.benchmarks.runner.harness import HarnessFailed, require, require_executor

#: the exit code of a study some of whose cases failed in the harness (docs/cli.md, "Studies")
EXIT_HARNESS = 1

def add_out(p, study: str) -> None:
    """``--out FOLDER``: where the study writes its files (default ``out/STUDY``)."""
    p.add_argument("--out", default=f"out/{study}", help=f"output folder (default out/{study})")


def add_out_file(p, default: str) -> None:
    """``--out FILE``: the one Markdown file a study writes, under that name; its folder is created.

    Its own dest, ``out_file``, so that the host's check of an ``--out`` folder leaves it alone (it refused
    an existing file); :func:`study` checks it before any work (:func:`check_out_file`).
    """
    p.add_argument("--out", dest="out_file", metavar="FILE", default=default,
                   help=f"the Markdown file to write, the only file written; its folder is created (default {default})")


def check_out_file(value: str) -> Path:
    """A file a study may write: not a folder, in a folder that exists writable or can be created; ValueError
    naming ``--out`` otherwise."""
    from admmkit.cli.output import check_output_folder
    from admmkit.io import check_writable
    path = Path(value)
    check_output_folder(path.parent, "--out")
    if path.parent.is_dir():
        check_writable(path, "--out")
    return path


def add_executor_options(p, workers: int = 2) -> None:
    """Where a sweep's cases run: local processes (--workers) or Dask (--dask-workers, --scheduler)."""
    p.add_argument("--workers", type=positive_int, default=workers,
                   help=f"local worker processes, one BLAS thread each (default {workers}"
                        + (" = the cores of this machine)" if workers == 2 else ")"))
    where = p.add_mutually_exclusive_group()
    where.add_argument("--dask-workers", type=positive_int, default=None, metavar="N",
                       help="run on a Dask LocalCluster of N single-threaded worker processes (needs dask[distributed])")
    where.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="run on the Dask cluster of this scheduler, e.g. tcp://head:8786 (docs/sweeps.md)")
    p.add_argument("--case-timeout", type=positive_float, default=None, metavar="SECONDS",
                   help="record a case that runs longer than this as a timeout and go on (default: no limit)")
    p.add_argument("--chunk", type=positive_int, default=None, metavar="N",
                   help="at most N cases per task (default: a group per task locally, 8 on Dask)")


def executor_of(args):
    """The sweep executor of the parsed options."""
    from admmkit.benchmarks.runner.sweep import Executor
    return Executor(workers=args.workers, dask_workers=args.dask_workers, scheduler=args.scheduler,
                    timeout=args.case_timeout, chunk=args.chunk)


def add_sweep_options(p, study: str) -> None:
    """The options of the resumable sweeps (admmkit.benchmarks.runner.sweep)."""
    add_out(p, study)
    add_executor_options(p)
    p.add_argument("--quick", action="store_true", help="a tiny grid (the smoke test)")
    p.add_argument("-q", "--quiet", "--no-progress", dest="progress", action="store_false", help="no progress line")
    p.add_argument("--report-only", action="store_true",
                   help="run nothing: write the files from the cases already in <out>/results.jsonl")


def command_name(args) -> str:
    """``bench rules``, ``reproduce``: the command the parsed arguments belong to (for one-line errors)."""
    top = getattr(args, "command", None) or "admmkit"
    target = getattr(args, f"{top}_target", None) or getattr(args, "target", None)     # reproduce paper
    return f"{top} {target}" if isinstance(target, str) else top


#: the studies known by a second name: {alias: name}
ALIASES = {"bench maros-meszaros": "bench qp"}


def canonical_name(name: str) -> str:
    """``bench qp`` for ``bench maros-meszaros``: the name a study's cost is filed under."""
    return ALIASES.get(name, name)


def needs(args, *modules: str) -> None:
    """Refuse before any work if a module the study needs (or Dask, when asked for) is missing; else announce
    what the run costs. Every study calls it first.

    A refusal is one line naming the command and the pip command
    (:func:`admmkit.benchmarks.runner.harness.require`).  Then a study whose default run takes more than about
    30 s says so in one line on stderr (:func:`admmkit.benchmarks.runner.costs.announce`).  ``--report-only``
    runs nothing, so it needs nothing and costs nothing.
    """
    if getattr(args, "report_only", False):
        return
    name = command_name(args)
    require(name, *modules)
    require_executor(name, args)
    announce(canonical_name(name))


def study(run):
    """A study command's function: its ``--out FILE`` checked first, and the harness's verdict at the end.

    (The study itself calls :func:`needs` before any work: the packages checked, its cost announced.)
    Some cases failed in the harness -> exit 1: the study has written its files without those cases
    (:class:`HarnessFailed` holds them); they are listed, then one line ``admmkit: error: N of M cases
    failed in the harness (...)`` on stderr.
    """
    @functools.wraps(run)
    def command(args):
        if getattr(args, "out_file", None) is not None:
            check_out_file(args.out_file)
        try:
            return run(args)
        except HarnessFailed as failed:
            return harness_exit(failed)
    return command


def add_study(targets, name: str, run, *, help: str, description: str, needs_line: str,
              modules=(), sweep: bool = True, out: str | None = None, out_file: str | None = None,
              **parser_options):
    """Make a study a command, ``admmkit bench NAME``: the one way a study becomes a command.

    A study is a module with its grid (``build_cases``), its case runner
    (``run_case``) and its summary (``run(out, ...)`` writes the files from the
    records); its folder's ``cli.py`` calls this from a registrar named in
    ``pyproject.toml`` (``"bench.NAME" = "admmkit.benchmarks.<folder>.cli:<registrar>"``).
    This gives the command

    - its description, ending with what a run costs (``typical: ...`` from
      ``admmkit.benchmarks.runner.costs``) and ``needs: NEEDS_LINE``;
    - the shared options: those of the resumable sweeps (``--out``, ``--workers``,
      ``--dask-workers``, ``--scheduler``, ``--case-timeout``, ``--chunk``,
      ``--quick``, ``-q``, ``--report-only``) if ``sweep``, else ``--out`` alone;
      ``--out`` defaults to ``out/OUT`` (``OUT``: ``name`` unless given); a study
      that writes one Markdown file takes ``--out FILE`` instead (``out_file``: its
      default, ``add_out_file``);
    - before ``run(args)``: ``modules`` (a tuple, or a function of the parsed
      options giving one) checked and the cost announced (``needs``); after
      it, the harness's verdict (``study``).

    Returns the parser, for the study's own options.
    """
    p = targets.add_parser(name, help=help, description=description + typical(f"bench {name}")
                           + f" needs: {needs_line}", **parser_options)
    if out_file is not None:
        add_out_file(p, out_file)
    else:
        (add_sweep_options if sweep else add_out)(p, out or name)

    @functools.wraps(run)
    def command(args):
        needs(args, *(modules(args) if callable(modules) else modules))
        return run(args)

    command.needs = modules          # said for the tests: this command checks and announces before its work
    p.set_defaults(func=study(command))
    return p


def harness_exit(failed: HarnessFailed) -> int:
    """List the files a study wrote, say in one line how many cases failed in the harness; EXIT_HARNESS."""
    print_files(failed.files)
    print(f"admmkit: error: {' '.join(str(failed).split())}", file=sys.stderr)
    return EXIT_HARNESS


def split_list(text):
    return [t.strip() for t in text.split(",") if t.strip()] if text else None


def print_files(files) -> None:
    """``wrote FILE``, one line per file written."""
    for f in files:
        print(f"wrote {f}")


def own_parser(name: str, module: str, help_text: str, modules: tuple[str, ...] = ()):
    """Register ``admmkit bench NAME``, handing every argument to ``module.main(argv, prog)`` unparsed.

    For the studies that define their options themselves (``admmkit bench NAME --help`` prints them).
    ``modules``: the modules the study needs (it checks them itself too), checked before its cost is
    announced, so that a refusal stays one line.
    """
    def register(targets) -> None:
        p = targets.add_parser(name, help=help_text, add_help=False, prefix_chars="\0")
        p.add_argument("argv", nargs=argparse.REMAINDER)

        def command(args):
            return run_own(module, args.argv, f"admmkit bench {name}", modules)
        command.needs = modules      # said for the tests: this command checks and announces before its work
        p.set_defaults(func=command)
    register.__doc__ = f"``admmkit bench {name}``: {help_text} ({module})."
    return register


def run_own(module: str, argv: list[str], prog: str, modules: tuple[str, ...] = ()) -> int:
    """``module.main(argv, prog)``, with its parser's exit (--help: 0, a bad option: 2) as the exit code.

    Unless asked for ``--help``: ``modules`` checked, then the study's cost announced, as :func:`needs`
    does, before the study's own parser reads the options.
    """
    if not {"-h", "--help"} & set(argv):
        require(prog.removeprefix("admmkit "), *modules)
        announce(prog.removeprefix("admmkit "))
    try:
        return int(importlib.import_module(module).main(argv, prog=prog) or 0)
    except SystemExit as exit_:
        return exit_.code if isinstance(exit_.code, int) else 2
    except HarnessFailed as failed:
        return harness_exit(failed)
