"""Benchmarks at scale: ``admmkit bench hertz | scale | amg-crossover | contact3d``.

    admmkit bench hertz [--out docs/results/scale] [--k 10 --k 20 ...]
    admmkit bench scale [--out docs/results/scale] [--h 1/500 ...] [--quick]
    admmkit bench amg-crossover [--out docs/results/scale] [--h ...]
    admmkit bench contact3d [--out docs/results/scale] [--h 1/24]

Each prints its figures as it goes and writes Markdown, CSV and PNG/SVG files
under ``--out`` (see docs/scale.md).
"""
from __future__ import annotations

import argparse

from problems.cli import positive_float


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}")
    return value


def add_bench_parser(targets) -> None:
    """Register the scale benchmarks."""
    h = targets.add_parser("hertz", help="Hertz validation: half-cylinder on a rigid plane, a and p0 vs Hertz",
                           description="Contact half-width and peak pressure against Hertz on meshes refined near "
                                       "the contact (problems/contact/hertz.py).")
    h.add_argument("--out", default="docs/results/scale", help="output folder (default docs/results/scale)")
    h.add_argument("--k", type=_positive_int, action="append", default=None, dest="ks",
                   help="refinement a_target/h_c (repeatable; default 10 20 40 80)")
    h.set_defaults(func=_hertz)


def _hertz(args) -> int:
    from .hertz_study import DEFAULT_KS, run_hertz_study
    ks = tuple(args.ks) if args.ks else DEFAULT_KS
    command = "admmkit bench hertz" + "".join(f" --k {k}" for k in ks if args.ks) + \
        (f" --out {args.out}" if args.out != "docs/results/scale" else "")
    run_hertz_study(out=args.out, ks=ks, command=command)
    return 0
