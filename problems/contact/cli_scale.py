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

    s = targets.add_parser("scale", help="Example 1 with the iterative x-step from 1e3 to 1e6 unknowns: time, memory",
                           description="SADMM on Example 1 with the AMG-CG x-step at growing sizes, each in its own "
                                       "process: wall time, iterations, peak memory, the 60 s / 8 GB target at 1e6.")
    s.add_argument("--out", default="docs/results/scale", help="output folder (default docs/results/scale)")
    s.add_argument("--h", type=positive_float, action="append", default=None, dest="hs",
                   help="mesh size (repeatable; default 1/20 1/40 1/80 1/160 1/320 1/500)")
    s.add_argument("--mode", choices=["iterative", "condensed", "full"], default="iterative",
                   help="x-step mode (default iterative)")
    s.add_argument("--quick", action="store_true", help="h = 1/10 and 1/20 only (smoke test)")
    s.add_argument("--timeout", type=positive_float, default=1800.0, help="seconds per size (default 1800)")
    s.set_defaults(func=_scale)

    c = targets.add_parser("amg-crossover", help="full / condensed / iterative x-steps against size; AMG reuse across rho",
                           description="When the iterative x-step beats the direct ones (Example 1), and when reusing "
                                       "the AMG hierarchy of an earlier rho is cheaper than rebuilding it.")
    c.add_argument("--out", default="docs/results/scale", help="output folder (default docs/results/scale)")
    c.add_argument("--h", type=positive_float, action="append", default=None, dest="hs",
                   help="mesh size (repeatable; default 1/20 ... 1/500)")
    c.add_argument("--reuse-h", type=positive_float, default=1 / 160, help="mesh size of the reuse table (default 1/160)")
    c.add_argument("--quick", action="store_true", help="h = 1/10 only, reuse table at h = 1/10 (smoke test)")
    c.add_argument("--timeout", type=positive_float, default=1800.0, help="seconds per run (default 1800)")
    c.set_defaults(func=_crossover)

    d = targets.add_parser("contact3d", help="3D block on a curved foundation with the AMG x-step; direct vs AMG",
                           description="The 3D analogue of Example 2: direct factorisation vs AMG by size, then SADMM "
                                       "with the iterative x-step, a figure and VTK output.")
    d.add_argument("--out", default="docs/results/scale", help="output folder (default docs/results/scale)")
    d.add_argument("--h", type=positive_float, default=1 / 32, help="mesh size of the SADMM run (default 1/32)")
    d.add_argument("--probe-h", type=positive_float, action="append", default=None, dest="probe_hs",
                   help="mesh sizes of the direct-vs-AMG probe (repeatable; default 1/8 1/12 1/16 1/24 1/32)")
    d.add_argument("--quick", action="store_true", help="h = 1/4 everywhere (smoke test)")
    d.add_argument("--timeout", type=positive_float, default=600.0, help="seconds per probe (default 600)")
    d.add_argument("--vtk", default="out/contact3d/contact3d", metavar="BASENAME",
                   help="VTK file of the SADMM run, .vtu added (default out/contact3d/contact3d)")
    d.set_defaults(func=_contact3d)


def _hertz(args) -> int:
    from .hertz_study import DEFAULT_KS, run_hertz_study
    ks = tuple(args.ks) if args.ks else DEFAULT_KS
    command = "admmkit bench hertz" + "".join(f" --k {k}" for k in ks if args.ks) + \
        (f" --out {args.out}" if args.out != "docs/results/scale" else "")
    run_hertz_study(out=args.out, ks=ks, command=command)
    return 0


def _command(name: str, args, defaults: dict) -> str:
    """The command line that reproduces this run (only the options that differ from the defaults)."""
    parts = [f"admmkit bench {name}"]
    for key, default in defaults.items():
        value = getattr(args, key)
        if value != default and value not in (None, False):
            flag = "--" + key.replace("_", "-").rstrip("s") if key in ("hs", "probe_hs") else "--" + key.replace("_", "-")
            if isinstance(value, (list, tuple)):
                parts += [f"{flag} {v:.6g}" for v in value]
            elif value is True:
                parts.append(flag)
            else:
                parts.append(f"{flag} {value}")
    return " ".join(parts)


def _scale(args) -> int:
    from .scale_bench import DEFAULT_HS, QUICK_HS, run_scale_bench
    hs = tuple(args.hs) if args.hs else (QUICK_HS if args.quick else DEFAULT_HS)
    command = _command("scale", args, {"hs": None, "mode": "iterative", "quick": False, "out": "docs/results/scale"})
    rows = run_scale_bench(out=args.out, hs=hs, mode=args.mode, command=command, timeout=args.timeout)
    return 0 if all(r.get("status") == "converged" for r in rows) else 1


def _crossover(args) -> int:
    from .crossover import DEFAULT_HS, run_crossover
    hs = tuple(args.hs) if args.hs else ((1 / 10,) if args.quick else DEFAULT_HS)
    reuse_h = 1 / 10 if args.quick else args.reuse_h
    command = _command("amg-crossover", args, {"hs": None, "quick": False, "out": "docs/results/scale",
                                                "reuse_h": 1 / 160})
    run_crossover(out=args.out, hs=hs, reuse_h=reuse_h, command=command, timeout=args.timeout)
    return 0


def _contact3d(args) -> int:
    from .contact3d_bench import PROBE_HS, run_contact3d
    h = 1 / 4 if args.quick else args.h
    probe_hs = tuple(args.probe_hs) if args.probe_hs else ((1 / 4,) if args.quick else PROBE_HS)
    command = _command("contact3d", args, {"h": 1 / 32, "probe_hs": None, "quick": False, "out": "docs/results/scale"})
    from .contact3d_bench import SADMM_HS
    sadmm_hs = (1 / 4,) if args.quick else SADMM_HS
    run_contact3d(out=args.out, h=h, probe_hs=probe_hs, timeout=args.timeout, command=command, sadmm_hs=sadmm_hs,
                  vtk=args.vtk)
    return 0
