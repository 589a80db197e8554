"""Every study's command: ``admmkit bench STUDY`` and ``admmkit reproduce paper``.

One function per command, each registered by an entry point in
``pyproject.toml`` (group ``admmkit.commands``) and found by the host
:mod:`admmkit.cli`.  A study writes where ``--out`` says, and without it to
``./out/<study>/``; the README it writes names the command as it was typed
(``args.command_line``).  The studies themselves live in one module each and
are imported only when their command runs.
"""
from __future__ import annotations

import argparse
import importlib

from admmkit.cli import positive_float, positive_int


def _out(p, study: str) -> None:
    p.add_argument("--out", default=f"out/{study}", help=f"output folder (default out/{study})")


def _executor_options(p, workers: int = 2) -> None:
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


def _executor(args):
    """The sweep executor of the parsed options."""
    from .sweep import Executor
    return Executor(workers=args.workers, dask_workers=args.dask_workers, scheduler=args.scheduler,
                    timeout=args.case_timeout, chunk=args.chunk)


def _sweep_options(p, study: str) -> None:
    """The options of the resumable sweeps (admmkit.benchmarks.sweep)."""
    _out(p, study)
    _executor_options(p)
    p.add_argument("--quick", action="store_true", help="a tiny grid (the smoke test)")
    p.add_argument("-q", "--quiet", "--no-progress", dest="progress", action="store_false", help="no progress line")
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


def _split(text):
    return [t.strip() for t in text.split(",") if t.strip()] if text else None


def _print_files(files) -> None:
    for f in files:
        print(f"wrote {f}")


# ---------------------------------------------------------------- the paper
def reproduce(commands) -> None:
    """``admmkit reproduce paper``: the paper's Tables 1-2 and Figs 1-4 (admmkit.benchmarks.paper)."""
    r = commands.add_parser("reproduce", help="reproduce a paper's tables and figures",
                            description="Reproduce the paper's section 4: both examples x ADMM1/ADMM2/SADMM x rho x h.")
    r.add_argument("target", choices=["paper"], help="paper: Tables 1-2 and Figs 1-4 of Yuan & Zhang (2023)")
    _out(r, "paper")
    r.add_argument("--quick", action="store_true", help="h = 1/10 and 1/20 only (CI smoke test)")
    r.add_argument("--repeats", type=positive_int, default=1, help="repeats per run, the median time (default 1)")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    r.set_defaults(func=_reproduce)


def _reproduce(args) -> int:
    from .paper import PAPER_HS, run_reproduction
    hs = (1 / 10, 1 / 20) if args.quick else PAPER_HS
    run_reproduction(out=args.out, hs=hs, repeats=args.repeats, progress=not args.quiet, command=args.command_line)
    return 0


def paper_compare(targets) -> None:
    """``admmkit bench paper-compare``: our times and iterations beside the paper's tables."""
    c = targets.add_parser("paper-compare", help="our ADMM1/ADMM2/SADMM times and iterations beside the paper's tables",
                           description="The paper's Tables 1-2 beside this machine's times, with ratios.")
    _sweep_options(c, "paper-compare")
    c.add_argument("--repeats", type=positive_int, default=3, help="repeats, median time (default 3)")
    c.set_defaults(func=_paper_compare)


def _paper_compare(args) -> int:
    from . import paper_compare
    _print_files(paper_compare.run(args.out, repeats=args.repeats, workers=args.workers, quick=args.quick,
                                   progress=args.progress, command=args.command_line, report_only=args.report_only,
                                   executor=_executor(args)))
    return 0


# ---------------------------------------------------------------- sweeps over every rule
def precision(targets) -> None:
    """``admmkit bench precision``: work-precision of every rule and the peers."""
    p = targets.add_parser("precision", help="work-precision: true error against time, every method and peer",
                           description="Error against time for every ADMM method and the peers (PDAS, "
                                       "cvxpy+Clarabel, cvxpy+OSQP, OSQP) on contact, obstacle and QP problems.")
    _sweep_options(p, "precision")
    p.add_argument("--repeats", type=positive_int, default=3, help="repeats, median time (default 3)")
    p.add_argument("--scene", action="append", default=None, dest="scenes",
                   help="ex1, ex2, radial, qp:random-mixed, qp:DUAL2, ... (repeatable; default all)")
    p.add_argument("--h", type=positive_float, action="append", default=None, dest="hs",
                   help="mesh size (repeatable; default 1/20, 1/40, 1/80, 1/160)")
    p.add_argument("--methods", default=None, help="comma-separated ADMM methods (default: every policy, both orders)")
    p.add_argument("--time-limit", type=positive_float, default=60.0, help="seconds per ADMM/OSQP run (default 60)")
    p.set_defaults(func=_precision)


def _precision(args) -> int:
    from . import precision
    from .families import kind_of
    for s in args.scenes or []:
        kind_of(s)   # ValueError naming the known scenes
    _print_files(precision.run(args.out, quick=args.quick, workers=args.workers, repeats=args.repeats,
                               scenes=args.scenes, hs=tuple(args.hs) if args.hs else None,
                               methods=_methods(args.methods), progress=args.progress, command=args.command_line,
                               time_limit=args.time_limit, report_only=args.report_only, executor=_executor(args)))
    return 0


def stability(targets) -> None:
    """``admmkit bench stability``: where each rule converges and how it fails."""
    s = targets.add_parser("stability", help="rho_0 over 13 decades, mesh, nu, P1/P2: iterations and failures",
                           description="Where each method converges and how it fails on the paper's contact "
                                       "examples (rho_0/E = 1e-6..1e6; h, nu, P1/P2).")
    _sweep_options(s, "stability")
    s.add_argument("--methods", default=None, help="comma-separated ADMM methods (default: every policy, both orders)")
    s.set_defaults(func=_stability)


def _stability(args) -> int:
    from . import stability
    _print_files(stability.run(args.out, quick=args.quick, workers=args.workers, methods=_methods(args.methods),
                               progress=args.progress, command=args.command_line, report_only=args.report_only,
                               executor=_executor(args)))
    return 0


def policies_fe(targets) -> None:
    """``admmkit bench policies``: the rules on contact Ex. 1 and the radial obstacle across rho_0."""
    from .policies_fe import RULES
    b = targets.add_parser("policies", help="penalty rules on contact Ex.1 and the radial obstacle, rho_0 over 12 decades",
                           description="Iterations, factorisations and the error at the stop of the penalty rules "
                                       "on contact Example 1 (h = 1/20) and the radial obstacle (h = 1/16).")
    _sweep_options(b, "policies")
    b.add_argument("--rules", default=",".join(RULES), help=f"comma-separated rules (default {','.join(RULES)})")
    b.set_defaults(func=_policies_fe)


def _policies_fe(args) -> int:
    import admmkit

    from .policies_fe import run
    rules = _split(args.rules) or []
    unknown = [r for r in rules if r not in admmkit.policy_names()]
    if unknown or not rules:
        raise ValueError(f"--rules: unknown {unknown}; known: {', '.join(admmkit.policy_names())}")
    run(args.out, rules=rules, quick=args.quick, command=args.command_line, progress=args.progress,
        executor=_executor(args), report_only=args.report_only)
    return 0


def maros_meszaros(targets) -> None:
    """``admmkit bench qp``: every rule and OSQP on a folder of Maros-Meszaros QPs."""
    from . import maros_meszaros as mm
    b = targets.add_parser("qp", aliases=["maros-meszaros"],
                           help="every penalty rule, with and without OSQP's machinery, and OSQP on a folder of QPs",
                           description="Penalty rules (both orders) in OSQP's machinery and in the textbook loop, "
                                       "one-off ablations, and OSQP 1.x, at absolute accuracies 1e-3 and 1e-6, judged "
                                       "by the neutral criteria; writes results.csv, summary.csv, README.md and "
                                       "performance profiles (PNG, SVG) to --out.")
    b.add_argument("--data", required=True, metavar="DIR", help="folder of MAT files, e.g. ../shared/data/maros_meszaros")
    _out(b, "maros_meszaros")
    b.add_argument("--policies", default=None, help="comma-separated rules (default: every registered rule)")
    b.add_argument("--orders", default="xz,zx", help="comma-separated orders (default xz,zx)")
    b.add_argument("--variants", default=None, help=f"comma-separated settings variants (default {','.join(mm.VARIANTS)})")
    b.add_argument("--eps", type=positive_float, action="append", default=None,
                   help="absolute accuracy (repeatable; default 1e-3 and 1e-6)")
    b.add_argument("--max-iter", type=positive_int, default=mm.MAX_ITER, help=f"iteration cap (default {mm.MAX_ITER})")
    b.add_argument("--time-limit", type=positive_float, default=mm.TIME_LIMIT,
                   help=f"CPU seconds per run (default {mm.TIME_LIMIT:g})")
    _executor_options(b, workers=1)
    b.add_argument("--problems", default=None, help="comma-separated problem names (default: all)")
    b.add_argument("--no-osqp", action="store_true", help="do not run OSQP itself")
    b.add_argument("--resume", action="store_true",
                   help="keep the cases already in OUT/results.jsonl (without it the sweep starts afresh)")
    b.add_argument("-q", "--quiet", "--no-progress", dest="quiet", action="store_true", help="no progress lines")
    b.set_defaults(func=_maros_meszaros)


def _maros_meszaros(args) -> int:
    from .maros_meszaros import EPS, run_benchmark
    run_benchmark(args.data, args.out, policy_names=_split(args.policies), orders=_split(args.orders) or (),
                  eps=tuple(args.eps) if args.eps else EPS, max_iter=args.max_iter, time_limit=args.time_limit,
                  workers=args.workers, only=_split(args.problems), osqp_direct=not args.no_osqp,
                  resume=args.resume, command=args.command_line, progress=not args.quiet, executor=_executor(args),
                  variants=_split(args.variants))
    return 0


def executors(targets) -> None:
    """``admmkit bench executors``: the same sweep on local processes and on a Dask LocalCluster."""
    e = targets.add_parser("executors", help="the bench-policies sweep on 2 local processes and a 2-worker Dask "
                                             "LocalCluster: iterations identical?, wall-time ratio",
                           description="Runs the cases of `admmkit bench policies` on both executors, one after "
                                       "the other, and compares iteration counts and wall times (needs dask).")
    _out(e, "executors")
    e.add_argument("--quick", action="store_true", help="the coarse smoke grid of bench policies")
    e.add_argument("--rounds", type=positive_int, default=2,
                   help="rounds of the three executors, the order reversed every second round (default 2)")
    e.add_argument("-q", "--quiet", "--no-progress", dest="progress", action="store_false", help="no progress line")
    e.set_defaults(func=_executors)


def _executors(args) -> int:
    from .executors import run
    _print_files(run(args.out, quick=args.quick, rounds=args.rounds, progress=args.progress,
                     command=args.command_line))
    return 0


# ---------------------------------------------------------------- speed and scale
def contact_speed(targets) -> None:
    """``admmkit bench contact``: SADMM time against one factorisation + solve of K."""
    b = targets.add_parser("contact", help="SADMM time / (one factorisation + solve of K), Ex. 1-2",
                           description="SADMM time against one sparse factorisation + solve of K.")
    b.add_argument("--out", default="out/contact/contact_speed.md",
                   help="Markdown file to write (default out/contact/contact_speed.md)")
    b.add_argument("--h", type=positive_float, action="append", default=None, dest="hs",
                   help="mesh size (repeatable; default 1/40 and 1/200)")
    b.add_argument("--repeats", type=positive_int, default=3, help="repeats, median reported (default 3)")
    b.set_defaults(func=_contact_speed)


def _contact_speed(args) -> int:
    from .contact_speed import DEFAULT_HS, run_bench
    run_bench(out=args.out, hs=tuple(args.hs) if args.hs else DEFAULT_HS, repeats=args.repeats,
              command=args.command_line)
    return 0


def hertz(targets) -> None:
    """``admmkit bench hertz``: contact half-width and peak pressure against Hertz."""
    h = targets.add_parser("hertz", help="Hertz validation: half-cylinder on a rigid plane, a and p0 vs Hertz",
                           description="Contact half-width and peak pressure against Hertz on meshes refined near "
                                       "the contact (problems/contact/hertz.py).")
    _out(h, "scale")
    h.add_argument("--k", type=positive_int, action="append", default=None, dest="ks",
                   help="refinement a_target/h_c (repeatable; default 10 20 40 80)")
    h.set_defaults(func=_hertz)


def _hertz(args) -> int:
    from .hertz import DEFAULT_KS, run_hertz_study
    run_hertz_study(out=args.out, ks=tuple(args.ks) if args.ks else DEFAULT_KS, command=args.command_line)
    return 0


def scale(targets) -> None:
    """``admmkit bench scale``: Example 1 with the iterative x-step from 1e3 to 1e6 unknowns."""
    s = targets.add_parser("scale", help="Example 1 with the iterative x-step from 1e3 to 1e6 unknowns: time, memory",
                           description="SADMM on Example 1 with the AMG-CG x-step at growing sizes, each in its own "
                                       "process: wall time, iterations, peak memory, the 60 s / 8 GB target at 1e6.")
    _out(s, "scale")
    s.add_argument("--h", type=positive_float, action="append", default=None, dest="hs",
                   help="mesh size (repeatable; default 1/20 1/40 1/80 1/160 1/320 1/500)")
    s.add_argument("--mode", choices=["iterative", "condensed", "full"], default="iterative",
                   help="x-step mode (default iterative)")
    s.add_argument("--quick", action="store_true", help="h = 1/10 and 1/20 only (smoke test)")
    s.add_argument("--timeout", type=positive_float, default=1800.0, help="seconds per size (default 1800)")
    s.set_defaults(func=_scale)


def _scale(args) -> int:
    from .scale import DEFAULT_HS, QUICK_HS, run_scale_bench
    hs = tuple(args.hs) if args.hs else (QUICK_HS if args.quick else DEFAULT_HS)
    rows = run_scale_bench(out=args.out, hs=hs, mode=args.mode, command=args.command_line, timeout=args.timeout)
    return 0 if all(r.get("status") == "converged" for r in rows) else 1


def amg_crossover(targets) -> None:
    """``admmkit bench amg-crossover``: direct against AMG x-steps by size; AMG reuse across rho."""
    c = targets.add_parser("amg-crossover", help="full / condensed / iterative x-steps against size; AMG reuse across rho",
                           description="When the iterative x-step beats the direct ones (Example 1), and when reusing "
                                       "the AMG hierarchy of an earlier rho is cheaper than rebuilding it.")
    _out(c, "scale")
    c.add_argument("--h", type=positive_float, action="append", default=None, dest="hs",
                   help="mesh size (repeatable; default 1/20 ... 1/500)")
    c.add_argument("--reuse-h", type=positive_float, default=1 / 160, help="mesh size of the reuse table (default 1/160)")
    c.add_argument("--quick", action="store_true", help="h = 1/10 only, reuse table at h = 1/10 (smoke test)")
    c.add_argument("--timeout", type=positive_float, default=1800.0, help="seconds per run (default 1800)")
    c.set_defaults(func=_amg_crossover)


def _amg_crossover(args) -> int:
    from .amg_crossover import DEFAULT_HS, run_crossover
    hs = tuple(args.hs) if args.hs else ((1 / 10,) if args.quick else DEFAULT_HS)
    run_crossover(out=args.out, hs=hs, reuse_h=1 / 10 if args.quick else args.reuse_h, command=args.command_line,
                  timeout=args.timeout)
    return 0


def contact3d(targets) -> None:
    """``admmkit bench contact3d``: the 3D block on a curved foundation, direct against AMG."""
    d = targets.add_parser("contact3d", help="3D block on a curved foundation with the AMG x-step; direct vs AMG",
                           description="The 3D analogue of Example 2: direct factorisation vs AMG by size, then SADMM "
                                       "with the iterative x-step, a figure and VTK output.")
    _out(d, "scale")
    d.add_argument("--h", type=positive_float, default=1 / 32, help="mesh size of the SADMM run (default 1/32)")
    d.add_argument("--probe-h", type=positive_float, action="append", default=None, dest="probe_hs",
                   help="mesh sizes of the direct-vs-AMG probe (repeatable; default 1/8 1/12 1/16 1/24 1/32)")
    d.add_argument("--quick", action="store_true", help="h = 1/4 everywhere (smoke test)")
    d.add_argument("--timeout", type=positive_float, default=600.0, help="seconds per probe (default 600)")
    d.add_argument("--vtk", default="out/contact3d/contact3d", metavar="BASENAME",
                   help="VTK file of the SADMM run, .vtu added (default out/contact3d/contact3d)")
    d.set_defaults(func=_contact3d)


def _contact3d(args) -> int:
    from .contact3d import PROBE_HS, SADMM_HS, run_contact3d
    run_contact3d(out=args.out, h=1 / 4 if args.quick else args.h,
                  probe_hs=tuple(args.probe_hs) if args.probe_hs else ((1 / 4,) if args.quick else PROBE_HS),
                  timeout=args.timeout, command=args.command_line, sadmm_hs=(1 / 4,) if args.quick else SADMM_HS,
                  vtk=args.vtk)
    return 0


def obstacle_rates(targets) -> None:
    """``admmkit bench obstacle``: convergence rates against the radial exact solution, and a policy sweep."""
    o = targets.add_parser("obstacle", help="obstacle problem: convergence rates against the exact solution, rho sweep",
                           description="Errors against the radial exact solution under refinement and the "
                                       "iterations of every rule across rho_0 (benchmarks/obstacle_rates.py).")
    _sweep_options(o, "obstacle")
    o.set_defaults(func=_obstacle_rates)


def _obstacle_rates(args) -> int:
    from .obstacle_rates import run
    return run(args.out, quick=args.quick, command=args.command_line, executor=_executor(args), progress=args.progress,
               report_only=args.report_only)


# ---------------------------------------------------------------- studies with a parser of their own
def _own_parser(name: str, module: str, help_text: str):
    """Register ``admmkit bench NAME``, handing every argument to ``module.main(argv, prog)`` unparsed.

    For the studies that define their options themselves (``admmkit bench NAME --help`` prints them).
    """
    def register(targets) -> None:
        p = targets.add_parser(name, help=help_text, add_help=False, prefix_chars="\0")
        p.add_argument("argv", nargs=argparse.REMAINDER)
        p.set_defaults(func=lambda args: _run_own(module, args.argv, f"admmkit bench {name}"))
    register.__doc__ = f"``admmkit bench {name}``: {help_text} ({module})."
    return register


def _run_own(module: str, argv: list[str], prog: str) -> int:
    """``module.main(argv, prog)``, with its parser's exit (--help: 0, a bad option: 2) as the exit code."""
    try:
        return int(importlib.import_module(module).main(argv, prog=prog) or 0)
    except SystemExit as exit_:
        return exit_.code if isinstance(exit_.code, int) else 2


loop_overhead = _own_parser("loop-overhead", "admmkit.benchmarks.loop_overhead",
                            "the loop's cost per iteration against a bare numpy loop of the same updates")
four_problems = _own_parser("four-problems", "admmkit.benchmarks.four_problems",
                            "LASSO, weighted box LS, consensus and 2-D TV with the building blocks, against cvxpy")
qp_fidelity = _own_parser("qp-fidelity", "admmkit.benchmarks.qp_fidelity",
                          "admmkit's OSQP preset against OSQP 1.x, problem by problem (Maros-Meszaros)")
qp_agreement = _own_parser("qp-agreement", "admmkit.benchmarks.qp_agreement",
                           "random feasible QPs against cvxpy + Clarabel")
friction = _own_parser("friction", "admmkit.benchmarks.friction_validation",
                       "Cattaneo-Mindlin partial slip under refinement, and every rule on frictional contact")
linsolve = _own_parser("linsolve", "admmkit.benchmarks.linsolve_backends",
                       "sparse direct backends from 1e3 to 1e6 unknowns, 1 and 2 threads")
