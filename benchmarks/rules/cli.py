"""The commands of the sweeps of every penalty rule (``admmkit bench ...``), each registered by an entry point.

One function per command, found by the host :mod:`admmkit.cli` through the
entry-point group ``admmkit.commands`` in ``pyproject.toml``; the study itself
is imported only when its command runs.  The shared options live in
:mod:`admmkit.benchmarks.runner.options`.
"""
from __future__ import annotations

from admmkit.cli import positive_float, positive_int  # noqa: F401
from admmkit.benchmarks.runner.options import add_sweep_options, executor_of, needs, print_files, split_list, study
from admmkit.benchmarks.runner.costs import typical


def precision(targets) -> None:
    """``admmkit bench precision``: work-precision of every rule and the peers."""
    p = targets.add_parser("precision", help="work-precision: true error against time, every method and peer",
                           description="Error against time for every ADMM method and the peers (PDAS, "
                                       "cvxpy+Clarabel, cvxpy+OSQP, OSQP) on contact, obstacle and QP problems."
                                       + typical("bench precision") + " needs: ngsolve, cvxpy, clarabel, osqp (pip install 'admmkit[test]')")
    add_sweep_options(p, "precision")
    p.add_argument("--repeats", type=positive_int, default=3, help="repeats, median time (default 3)")
    p.add_argument("--scene", action="append", default=None, dest="scenes",
                   help="ex1, ex2, radial, qp:random-mixed, qp:DUAL2, ... (repeatable; default all)")
    p.add_argument("--h", type=positive_float, action="append", default=None, dest="hs",
                   help="mesh size (repeatable; default 1/20, 1/40, 1/80, 1/160)")
    p.add_argument("--methods", default=None, help="comma-separated ADMM methods (default: every policy, both orders)")
    p.add_argument("--time-limit", type=positive_float, default=60.0, help="seconds per ADMM/OSQP run (default 60)")
    p.set_defaults(func=study(_precision))


def _precision(args) -> int:
    needs(args, "cvxpy", "clarabel", "osqp")       # the peers: cvxpy + Clarabel, cvxpy + OSQP, OSQP
    from admmkit.benchmarks.rules import precision
    from admmkit.benchmarks.rules.families import kind_of
    for s in args.scenes or []:
        kind_of(s)   # ValueError naming the known scenes
    print_files(precision.run(args.out, quick=args.quick, workers=args.workers, repeats=args.repeats,
                               scenes=args.scenes, hs=tuple(args.hs) if args.hs else None,
                               methods=parse_methods(args.methods), progress=args.progress, command=args.command_line,
                               time_limit=args.time_limit, report_only=args.report_only, executor=executor_of(args)))
    return 0


def stability(targets) -> None:
    """``admmkit bench stability``: where each rule converges and how it fails."""
    s = targets.add_parser("stability", help="rho_0 over 13 decades, mesh, nu, P1/P2: iterations and failures",
                           description="Where each method converges and how it fails on the paper's contact "
                                       "examples (rho_0/E = 1e-6..1e6; h, nu, P1/P2)."
                                       + typical("bench stability") + " needs: ngsolve")
    add_sweep_options(s, "stability")
    s.add_argument("--methods", default=None, help="comma-separated ADMM methods (default: every policy, both orders)")
    s.set_defaults(func=study(_stability))


def _stability(args) -> int:
    needs(args, "cvxpy", "clarabel")               # the references
    from admmkit.benchmarks.rules import stability
    print_files(stability.run(args.out, quick=args.quick, workers=args.workers, methods=parse_methods(args.methods),
                               progress=args.progress, command=args.command_line, report_only=args.report_only,
                               executor=executor_of(args)))
    return 0


def policies_fe(targets) -> None:
    """``admmkit bench policies``: the rules on contact Ex. 1 and the radial obstacle across rho_0."""
    from admmkit.benchmarks.rules.policies_fe import RULES
    b = targets.add_parser("policies", help="penalty rules on contact Ex.1 and the radial obstacle, rho_0 over 12 decades",
                           description="Iterations, factorisations and the error at the stop of the penalty rules "
                                       "on contact Example 1 (h = 1/20) and the radial obstacle (h = 1/16)."
                                       + typical("bench policies") + " needs: ngsolve")
    add_sweep_options(b, "policies")
    b.add_argument("--rules", default=",".join(RULES), help=f"comma-separated rules (default {','.join(RULES)})")
    b.set_defaults(func=study(_policies_fe))


def _policies_fe(args) -> int:
    needs(args, "cvxpy", "clarabel")               # the references
    import admmkit

    from admmkit.benchmarks.rules.policies_fe import run
    from admmkit.policy import canonical_spec, is_spec
    rules = [canonical_spec(r) if is_spec(r) else r for r in split_list(args.rules) or []]
    unknown = [r for r in rules if not is_spec(r) and r not in admmkit.policy_names()]
    if unknown or not rules:
        raise ValueError(f"--rules: unknown {unknown}; known: {', '.join(admmkit.policy_names())}, or "
                         f"module:Class or path/to/file.py:Class")
    for rule in rules:                       # a rule that does not load or breaks the protocol: before any case runs
        try:
            admmkit.make_policy(rule)
        except (TypeError, ValueError) as err:
            raise ValueError(f"--rules: {err}") from None
    run(args.out, rules=rules, quick=args.quick, command=args.command_line, progress=args.progress,
        executor=executor_of(args), report_only=args.report_only)
    return 0


def obstacle_rates(targets) -> None:
    """``admmkit bench obstacle``: convergence rates against the radial exact solution, and a policy sweep."""
    o = targets.add_parser("obstacle", help="obstacle problem: convergence rates against the exact solution, rho sweep",
                           description="Errors against the radial exact solution under refinement and the "
                                       "iterations of every rule across rho_0 (benchmarks/rules/obstacle_rates.py)."
                                       + typical("bench obstacle") + " needs: ngsolve")
    add_sweep_options(o, "obstacle")
    o.set_defaults(func=study(_obstacle_rates))


def _obstacle_rates(args) -> int:
    needs(args, "cvxpy", "clarabel")               # the references
    from admmkit.benchmarks.rules.obstacle_rates import run
    return run(args.out, quick=args.quick, command=args.command_line, executor=executor_of(args), progress=args.progress,
               report_only=args.report_only)


def parse_methods(text: str | None):
    """The ADMM methods of ``--methods`` (labels such as sadmm, admm1), each checked; None: all."""
    if text is None:
        return None
    from admmkit.benchmarks.rules import methods
    labels = [t.strip() for t in text.split(",") if t.strip()]
    if not labels:
        raise ValueError("--methods: give at least one method, e.g. --methods sadmm,admm1")
    for label in labels:
        try:
            methods.resolve(label)
        except ValueError as err:
            raise ValueError(f"--methods: {err}") from None
    return labels
