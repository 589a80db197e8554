"""``admmkit bench precision | stability | paper-compare``: the benchmark commands.

    admmkit bench precision     [--out docs/results/bench/precision] [--quick] [--workers 2] [--repeats 3]
                                [--scene ex1 --scene radial ...] [--h 1/40 ...] [--methods sadmm,admm1,...]
    admmkit bench stability     [--out docs/results/bench/stability] [--quick] [--workers 2] [--methods ...]
    admmkit bench paper-compare [--out docs/results/bench/paper] [--repeats 3] [--workers 2] [--quick]

Every target runs a resumable sweep (``<out>/results.jsonl``: run the same
command again after an interruption and only the missing cases run) on
``--workers`` processes with a progress line, then writes CSV, Markdown and
PNG + SVG figures with the machine and versions into ``--out``.
"""
from __future__ import annotations

import shlex

from problems.cli import positive_float


def _int_at_least(low: int):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise _arg_error(f"expected an integer >= {low}, got {text!r}") from None
        if value < low:
            raise _arg_error(f"expected an integer >= {low}, got {value}")
        return value
    return parse


def _arg_error(message: str):
    import argparse
    return argparse.ArgumentTypeError(message)


def _common(p, out: str) -> None:
    p.add_argument("--out", default=out, help=f"output folder (default {out})")
    p.add_argument("--workers", type=_int_at_least(1), default=2,
                   help="worker processes, one BLAS thread each (default 2 = the cores of this machine)")
    p.add_argument("--quick", action="store_true", help="a tiny grid (the smoke test)")
    p.add_argument("--no-progress", dest="progress", action="store_false", help="no progress line")
    p.add_argument("--report-only", action="store_true",
                   help="run nothing: write the files from the cases already in <out>/results.jsonl")


def _methods(text: str | None):
    if text is None:
        return None
    from . import methods
    labels = [t.strip() for t in text.split(",") if t.strip()]
    if not labels:
        raise ValueError("--methods: give at least one method, e.g. --methods sadmm,admm1")
    for label in labels:
        try:
            methods.resolve(label)
        except ValueError as err:
            raise ValueError(f"--methods: {err}") from None
    return labels


def add_bench_parser(targets) -> None:
    """Register ``bench precision``, ``bench stability`` and ``bench paper-compare``."""
    p = targets.add_parser("precision", help="work-precision: true error against time, every method and peer",
                           description="Error against wall time for every ADMM method and the peers (PDAS, "
                                       "cvxpy+Clarabel, cvxpy+OSQP, OSQP) on contact, obstacle and QP problems.")
    _common(p, "docs/results/bench/precision")
    p.add_argument("--repeats", type=_int_at_least(1), default=3, help="repeats, median time (default 3)")
    p.add_argument("--scene", action="append", default=None, dest="scenes",
                   help="ex1, ex2, radial, qp:random-mixed, qp:DUAL2, ... (repeatable; default all)")
    p.add_argument("--h", type=positive_float, action="append", default=None, dest="hs",
                   help="mesh size (repeatable; default 1/20, 1/40, 1/80, 1/160)")
    p.add_argument("--methods", default=None, help="comma-separated ADMM methods (default: every policy, both orders)")
    p.add_argument("--time-limit", type=positive_float, default=60.0, help="wall seconds per ADMM/OSQP run (default 60)")
    p.set_defaults(func=_precision)

    s = targets.add_parser("stability", help="rho_0 over 13 decades, mesh, nu, P1/P2: iterations and failures",
                           description="Where each method converges and how it fails on the paper's contact "
                                       "examples (rho_0/E = 1e-6..1e6; h, nu, P1/P2).")
    _common(s, "docs/results/bench/stability")
    s.add_argument("--methods", default=None, help="comma-separated ADMM methods (default: every policy, both orders)")
    s.set_defaults(func=_stability)

    c = targets.add_parser("paper-compare", help="our ADMM1/ADMM2/SADMM times and iterations beside the paper's tables",
                           description="The paper's Tables 1-2 beside this machine's times, with ratios.")
    _common(c, "docs/results/bench/paper")
    c.add_argument("--repeats", type=_int_at_least(1), default=3, help="repeats, median time (default 3)")
    c.set_defaults(func=_paper)


def _rebuild(args, target: str) -> str:
    """The command line that reproduces this run (options that differ from the defaults)."""
    parts = ["admmkit", "bench", target, "--out", args.out]
    if args.quick:
        parts.append("--quick")
    if args.workers != 2:
        parts += ["--workers", str(args.workers)]
    if getattr(args, "repeats", 3) != 3:
        parts += ["--repeats", str(args.repeats)]
    for s in getattr(args, "scenes", None) or []:
        parts += ["--scene", s]
    for h in getattr(args, "hs", None) or []:
        parts += ["--h", f"{h:g}"]
    if getattr(args, "methods", None):
        parts += ["--methods", args.methods]
    if getattr(args, "time_limit", 60.0) != 60.0:
        parts += ["--time-limit", f"{args.time_limit:g}"]
    return " ".join(shlex.quote(p) for p in parts)


def _precision(args) -> int:
    from . import precision
    from .scenes import kind_of
    for s in args.scenes or []:
        kind_of(s)   # ValueError naming the known scenes
    files = precision.run(args.out, quick=args.quick, workers=args.workers, repeats=args.repeats,
                          scenes=args.scenes, hs=tuple(args.hs) if args.hs else None, methods=_methods(args.methods),
                          progress=args.progress, command=_rebuild(args, "precision"), time_limit=args.time_limit,
                          report_only=args.report_only)
    _print_files(files)
    return 0


def _stability(args) -> int:
    from . import stability
    files = stability.run(args.out, quick=args.quick, workers=args.workers, methods=_methods(args.methods),
                          progress=args.progress, command=_rebuild(args, "stability"), report_only=args.report_only)
    _print_files(files)
    return 0


def _paper(args) -> int:
    from . import paper
    files = paper.run(args.out, repeats=args.repeats, workers=args.workers, quick=args.quick,
                      progress=args.progress, command=_rebuild(args, "paper-compare"),
                      report_only=args.report_only)
    _print_files(files)
    return 0


def _print_files(files) -> None:
    for f in files:
        print(f"wrote {f}")
