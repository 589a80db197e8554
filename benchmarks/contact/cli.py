"""The commands of the paper's reproduction and the contact studies (``admmkit bench ...``), each registered by an entry point.

One function per command, found by the host :mod:`admmkit.cli` through the
entry-point group ``admmkit.commands`` in ``pyproject.toml``; the study itself
is imported only when its command runs.  A study becomes a command through
:func:`admmkit.benchmarks.runner.options.add_study` (the shared options, its
cost and needs), or :func:`~admmkit.benchmarks.runner.options.own_parser` when
it parses its own options.
"""
from __future__ import annotations

from admmkit.cli import positive_float, positive_int
from admmkit.benchmarks.runner.options import add_out, add_study, executor_of, needs, own_parser, print_files, study
from admmkit.benchmarks.runner.costs import typical


def reproduce(commands) -> None:
    """``admmkit reproduce paper``: the paper's Tables 1-2 and Figs 1-4 (admmkit.benchmarks.contact.paper)."""
    r = commands.add_parser("reproduce", help="reproduce a paper's tables and figures",
                            description="Reproduce the paper's section 4: both examples x ADMM1/ADMM2/SADMM x rho x h."
                                       + typical("reproduce paper") + " needs: ngsolve, matplotlib (installed with admmkit)")
    r.add_argument("target", choices=["paper"], help="paper: Tables 1-2 and Figs 1-4 of Yuan & Zhang (2023)")
    add_out(r, "paper")
    r.add_argument("--quick", action="store_true", help="h = 1/10 and 1/20 only (CI smoke test)")
    r.add_argument("--repeats", type=positive_int, default=1, help="repeats per run, the median time (default 1)")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    r.set_defaults(func=study(_reproduce))


def _reproduce(args) -> int:
    needs(args, "cvxpy", "clarabel")               # the paper's reference solver: nothing weaker replaces it
    from admmkit.benchmarks.contact.paper import PAPER_HS, run_reproduction
    hs = (1 / 10, 1 / 20) if args.quick else PAPER_HS
    done = run_reproduction(out=args.out, hs=hs, repeats=args.repeats, progress=not args.quiet,
                            command=args.command_line)
    print_files(done["files"])
    return 0


def paper_compare(targets) -> None:
    """``admmkit bench paper-compare``: our times and iterations beside the paper's tables."""
    c = add_study(targets, "paper-compare", _paper_compare,
                  help="our ADMM1/ADMM2/SADMM times and iterations beside the paper's tables",
                  description="The paper's Tables 1-2 beside this machine's times, with ratios.", needs_line="ngsolve")
    c.add_argument("--repeats", type=positive_int, default=3, help="repeats, median time (default 3)")


def _paper_compare(args) -> int:
    from admmkit.benchmarks.contact import paper_compare
    print_files(paper_compare.run(args.out, repeats=args.repeats, workers=args.workers, quick=args.quick,
                                   progress=args.progress, command=args.command_line, report_only=args.report_only,
                                   executor=executor_of(args)))
    return 0


def contact_speed(targets) -> None:
    """``admmkit bench contact``: SADMM time against one factorisation + solve of K."""
    b = add_study(targets, "contact", _contact_speed, out_file="out/contact/contact_speed.md",
                  help="SADMM time / (one factorisation + solve of K), Ex. 1-2",
                  description="SADMM time against one sparse factorisation + solve of K.", needs_line="ngsolve")
    b.add_argument("--h", type=positive_float, action="append", default=None, dest="hs",
                   help="mesh size (repeatable; default 1/40 and 1/200)")
    b.add_argument("--repeats", type=positive_int, default=3, help="repeats, median reported (default 3)")


def _contact_speed(args) -> int:
    from admmkit.benchmarks.contact.contact_speed import DEFAULT_HS, run_bench
    run_bench(out=args.out_file, hs=tuple(args.hs) if args.hs else DEFAULT_HS, repeats=args.repeats,
              command=args.command_line)
    print_files([args.out_file])
    return 0


def contact_schur(targets) -> None:
    """``admmkit bench contact-schur``: the condensed set-up (Schur complement on Gamma_C) by backend."""
    b = add_study(targets, "contact-schur", _contact_schur, out_file="out/contact/contact_schur.md",
                  help="the Schur complement's set-up by backend, Ex. 1-2, and SADMM / (factor + solve)",
                  description="Time the candidate ways to build the contact-boundary Schur complement of K.",
                  needs_line="ngsolve")
    b.add_argument("--h", type=positive_float, action="append", default=None, dest="hs",
                   help="mesh size (repeatable; default 1/40, 1/100 and 1/200)")
    b.add_argument("--repeats", type=positive_int, default=3, help="repeats, the best reported (default 3)")
    b.add_argument("--block", type=positive_int, default=64, help="columns per block of the block solves (default 64)")


def _contact_schur(args) -> int:
    from admmkit.benchmarks.contact.schur_study import DEFAULT_HS, run_study
    run_study(out=args.out_file, hs=tuple(args.hs) if args.hs else DEFAULT_HS, repeats=args.repeats, block=args.block,
              command=args.command_line)
    print_files([args.out_file])
    return 0


def hertz(targets) -> None:
    """``admmkit bench hertz``: contact half-width and peak pressure against Hertz."""
    h = add_study(targets, "hertz", _hertz, sweep=False, out="scale",
                  help="Hertz validation: half-cylinder on a rigid plane, a and p0 vs Hertz",
                  description="Contact half-width and peak pressure against Hertz on meshes refined near "
                              "the contact (problems/contact/validation/hertz.py).",
                  needs_line="ngsolve (netgen meshes), matplotlib")
    h.add_argument("--k", type=positive_int, action="append", default=None, dest="ks",
                   help="refinement a_target/h_c (repeatable; default 10 20 40 80)")


def _hertz(args) -> int:
    from admmkit.benchmarks.contact.hertz import DEFAULT_KS, run_hertz_study
    run_hertz_study(out=args.out, ks=tuple(args.ks) if args.ks else DEFAULT_KS, command=args.command_line)
    return 0


def scale(targets) -> None:
    """``admmkit bench scale``: Example 1 with the iterative x-step from 1e3 to 1e6 unknowns."""
    s = add_study(targets, "scale", _scale, sweep=False,
                  help="Example 1 with the iterative x-step from 1e3 to 1e6 unknowns: time, memory",
                  description="SADMM on Example 1 with the AMG-CG x-step at growing sizes, each in its own "
                              "process: wall time, iterations, peak memory, the 60 s / 8 GB target at 1e6.",
                  needs_line="ngsolve, pyamg, cvxpy, clarabel (the reference of the accuracy column up to 2e5 "
                             "unknowns)",
                  modules=("cvxpy", "clarabel"))   # the reference of the accuracy column: no silent weaker one
    s.add_argument("--h", type=positive_float, action="append", default=None, dest="hs",
                   help="mesh size (repeatable; default 1/20 1/40 1/80 1/160 1/320 1/500)")
    s.add_argument("--mode", choices=["iterative", "condensed", "full"], default="iterative",
                   help="x-step mode (default iterative)")
    s.add_argument("--quick", action="store_true", help="h = 1/10 and 1/20 only (smoke test)")
    s.add_argument("--timeout", type=positive_float, default=1800.0, help="seconds per size (default 1800)")


def _scale(args) -> int:
    from admmkit.benchmarks.contact.scale import DEFAULT_HS, QUICK_HS, run_scale_bench
    hs = tuple(args.hs) if args.hs else (QUICK_HS if args.quick else DEFAULT_HS)
    rows = run_scale_bench(out=args.out, hs=hs, mode=args.mode, command=args.command_line, timeout=args.timeout)
    return 0 if all(r.get("status") == "converged" for r in rows) else 1


def amg_crossover(targets) -> None:
    """``admmkit bench amg-crossover``: direct against AMG x-steps by size; AMG reuse across rho."""
    c = add_study(targets, "amg-crossover", _amg_crossover, sweep=False, out="scale",
                  help="full / condensed / iterative x-steps against size; AMG reuse across rho",
                  description="When the iterative x-step beats the direct ones (Example 1), and when reusing "
                              "the AMG hierarchy of an earlier rho is cheaper than rebuilding it.",
                  needs_line="ngsolve, pyamg")
    c.add_argument("--h", type=positive_float, action="append", default=None, dest="hs",
                   help="mesh size (repeatable; default 1/20 ... 1/500)")
    c.add_argument("--reuse-h", type=positive_float, default=1 / 160, help="mesh size of the reuse table (default 1/160)")
    c.add_argument("--quick", action="store_true", help="h = 1/10 only, reuse table at h = 1/10 (smoke test)")
    c.add_argument("--timeout", type=positive_float, default=1800.0, help="seconds per run (default 1800)")


def _amg_crossover(args) -> int:
    from admmkit.benchmarks.contact.amg_crossover import DEFAULT_HS, run_crossover
    hs = tuple(args.hs) if args.hs else ((1 / 10,) if args.quick else DEFAULT_HS)
    run_crossover(out=args.out, hs=hs, reuse_h=1 / 10 if args.quick else args.reuse_h, command=args.command_line,
                  timeout=args.timeout)
    return 0


def contact3d(targets) -> None:
    """``admmkit bench contact3d``: the 3D block on a curved foundation, direct against AMG."""
    d = add_study(targets, "contact3d", _contact3d, sweep=False, out="scale",
                  help="3D block on a curved foundation with the AMG x-step; direct vs AMG",
                  description="The 3D analogue of Example 2: direct factorisation vs AMG by size, then SADMM "
                              "with the iterative x-step, a figure and VTK output.",
                  needs_line="ngsolve, pyamg, matplotlib, meshio")
    d.add_argument("--h", type=positive_float, default=1 / 32, help="mesh size of the SADMM run (default 1/32)")
    d.add_argument("--probe-h", type=positive_float, action="append", default=None, dest="probe_hs",
                   help="mesh sizes of the direct-vs-AMG probe (repeatable; default 1/8 1/12 1/16 1/24 1/32)")
    d.add_argument("--quick", action="store_true", help="h = 1/4 everywhere (smoke test)")
    d.add_argument("--timeout", type=positive_float, default=600.0, help="seconds per probe (default 600)")
    d.add_argument("--vtk", default="out/contact3d/contact3d", metavar="BASENAME",
                   help="VTK file of the SADMM run, .vtu added (default out/contact3d/contact3d)")
    d.add_argument("--growth-h", type=positive_float, action="append", default=None, dest="growth_hs",
                   help="mesh sizes of the growth chart (time and peak memory against the unknowns; repeatable; "
                        "default 1/8 1/12 1/16 1/24 1/32 1/48, up to 1.04e6 unknowns)")
    d.add_argument("--growth-only", action="store_true", help="only the growth chart (contact3d_growth.png/md/csv)")


def _contact3d(args) -> int:
    from admmkit.benchmarks.contact.contact3d import GROWTH_HS, PROBE_HS, SADMM_HS, run_contact3d
    growth_hs = tuple(args.growth_hs) if args.growth_hs else ((1 / 4, 1 / 6) if args.quick else GROWTH_HS)
    run_contact3d(out=args.out, h=1 / 4 if args.quick else args.h,
                  probe_hs=tuple(args.probe_hs) if args.probe_hs else ((1 / 4,) if args.quick else PROBE_HS),
                  timeout=args.timeout, command=args.command_line, sadmm_hs=(1 / 4,) if args.quick else SADMM_HS,
                  vtk=args.vtk, growth_hs=growth_hs, growth_only=args.growth_only)
    return 0


friction = own_parser("friction", "admmkit.benchmarks.contact.friction_validation",
                       "Cattaneo-Mindlin partial slip under refinement, and every rule on frictional contact",
                       modules=("cvxpy", "clarabel"))


linsolve = own_parser("linsolve", "admmkit.benchmarks.contact.linsolve_backends",
                       "sparse direct backends from 1e3 to 1e6 unknowns, 1 and 2 threads")
