"""``admmkit solve qp``: a MAT-file QP or a random one (the study is ``admmkit bench qp``, in benchmarks/).

Two presets (docs/cli.md, docs/qp.md):

- ``--preset osqp`` (default): :func:`admmkit.problems.qp.solve_qp` with OSQP 1.x's defaults (``osqp_settings``):
  Ruiz scaling, penalty per row, alpha 1.6, OSQP's termination test (R1)-(R3) every 25 iterations, the
  infeasibility tests (I1)-(I2), OSQP's rho rule; ``--eps``, ``--eps-abs``/``--eps-rel``, ``--eps-inf`` and
  ``--polish`` set its tolerances and polishing. ``--tol`` (a relative-change rule) is refused.
- ``--preset textbook``: the plain loop this command ran before (``admmkit.solve`` on the QP as built, the
  common stopping options ``--tol``/``--eps-abs``/``--eps-rel``, rho_0 = 1, ``residual_balancing``).
"""
from __future__ import annotations

from admmkit.cli import (add_common_options, add_result_outputs, positive_float, progress, resolve_policy, run_solve,
                         set_help, write_history)
from admmkit.cli.output import print_summary
from admmkit.policies.paper_methods import PAPER_METHODS

from .cli_output import certificate_summary, qp_lines, write_qp_csv, write_qp_json
from .generate import KINDS, infeasible_qp, random_qp, unbounded_qp
from .mat import load_mat
from .settings import osqp_settings

#: ``--kind`` of ``--random``: the generator's feasible kinds, and a primal infeasible and an unbounded QP
CLI_KINDS = (*KINDS, "infeasible", "unbounded")
#: what each preset uses when --policy, --rho, --max-iter are not given
PRESET_DEFAULTS = {"osqp": {"policy": "osqp", "rho": 0.1, "max_iter": 4000},
                   "textbook": {"policy": "residual_balancing", "rho": 1.0, "max_iter": 10_000}}


def register(subparsers) -> None:
    """Register ``solve qp``."""
    p = subparsers.add_parser("qp", help="min 1/2 x'Px + q'x s.t. l <= Ax <= u (OSQP's form)",
                              description="Solve a quadratic program min 1/2 x'Px + q'x s.t. l <= Ax <= u, from a MAT "
                                          "file or generated, with OSQP 1.x's defaults (--preset osqp) or the plain "
                                          "loop (--preset textbook); docs/qp.md.\n\ntypical: ~10 s for --random 200 "
                                          "300 on 2 cores, most of it start-up (imports, compiled kernels loaded from "
                                          "numba's cache; the first run after an install compiles them, ~10 s more), "
                                          "0.3 GB; a large Maros-Meszaros problem seconds to minutes. needs: numpy, "
                                          "scipy, numba (installed with admmkit); --mat a MAT file, e.g. "
                                          "../shared/data/maros_meszaros/HS21.mat")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--mat", metavar="FILE", help="a MAT file with P, q, r, A, l, u (e.g. a Maros-Meszaros problem)")
    src.add_argument("--random", nargs=2, type=int, metavar=("N", "M"), help="a random QP with N >= 1 variables and M >= 1 rows")
    p.add_argument("--kind", choices=CLI_KINDS, default="mixed",
                   help="the random QP: feasible row types, or 'infeasible' (a contradicting row added: "
                        "M + 1 rows) or 'unbounded' (default mixed)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random QP, an integer >= 0 (default 0)")
    p.add_argument("--preset", choices=("osqp", "textbook"), default="osqp",
                   help="osqp: OSQP 1.x's defaults and tests (admmkit.problems.qp.solve_qp); textbook: the plain loop "
                        "with the common stopping options (the command's behaviour before the preset)")
    p.add_argument("--eps", type=positive_float, default=None, metavar="EPS",
                   help="OSQP's eps_abs = eps_rel > 0 (osqp preset; default 1e-3)")
    p.add_argument("--eps-inf", type=positive_float, default=None, metavar="EPS",
                   help="OSQP's eps_prim_inf = eps_dual_inf > 0, the infeasibility tolerances (osqp preset; "
                        "default 1e-4)")
    p.add_argument("--polish", action="store_true", help="OSQP's polishing after a solved run (osqp preset)")
    add_common_options(p, policy="residual_balancing", order="xz", methods=PAPER_METHODS)
    add_result_outputs(p, json_help="write the run (provenance, summary, termination, neutral residuals, "
                                    "certificate, x, z = Ax, lam) as JSON",
                       csv_help="write the solution as CSV: one row per variable (x) and one per row of A (z, lam, l, "
                                "u, certificate), with status, termination and neutral residuals on every row")
    p.set_defaults(func=run, policy=None, rho=None, max_iter=None)
    helps = {"policy": "penalty rule or method (default: osqp = OSQP's rule with OSQP's normalisation in the osqp "
                       "preset, residual_balancing in the textbook preset)",
             "rho": "initial penalty rho_0 > 0 (default 0.1 osqp preset, 1 textbook)",
             "max_iter": "iteration cap, an integer >= 1 (default 4000 osqp preset, 10000 textbook)",
             "tol": "relative-change tolerance > 0 (textbook preset only; default 1e-5 unless --eps-abs is given)",
             "eps_abs": "absolute tolerance > 0: OSQP's eps_abs (osqp preset), Boyd's residual test (textbook)",
             "eps_rel": "relative tolerance >= 0 (default 0; needs --eps-abs): OSQP's eps_rel or Boyd's"}
    set_help(p, **helps)


def check_preset_options(args) -> None:
    """Refuse options that the chosen preset has no meaning for (one line, exit 2, before any work)."""
    if args.random is not None and min(args.random) < 1:
        raise ValueError(f"--random N M: both must be integers >= 1, got {args.random[0]} {args.random[1]}")
    if args.seed < 0:
        raise ValueError(f"--seed must be an integer >= 0, got {args.seed}")
    if args.preset == "osqp":
        if args.tol is not None:
            raise ValueError("--tol is the textbook loop's relative-change rule; with --preset osqp give --eps "
                             "(OSQP's eps_abs = eps_rel) or --eps-abs/--eps-rel, or use --preset textbook")
        if args.eps is not None and args.eps_abs is not None:
            raise ValueError("--eps sets eps_abs = eps_rel; give either --eps or --eps-abs [--eps-rel], not both")
    else:
        given = [flag for flag, v in (("--eps", args.eps), ("--eps-inf", args.eps_inf), ("--polish", args.polish)) if v]
        if given:
            raise ValueError(f"{', '.join(given)} belong(s) to --preset osqp; the textbook loop stops by --tol or "
                             "--eps-abs/--eps-rel and has no infeasibility test or polishing")
    for name, value in PRESET_DEFAULTS[args.preset].items():
        if getattr(args, name) is None:
            setattr(args, name, value)


def build_qp(args):
    """The QP the options ask for (a MAT file or a generated one)."""
    if args.mat:
        return load_mat(args.mat)
    n, m = args.random
    if args.kind == "infeasible":
        return infeasible_qp(n, m, seed=args.seed)
    if args.kind == "unbounded":
        return unbounded_qp(n, m, seed=args.seed)
    return random_qp(n, m, kind=args.kind, seed=args.seed)


def osqp_settings_from(args, order: str):
    """``osqp_settings`` with the options: rho_0, order, cap, eps (or eps_abs/eps_rel), eps_inf, polish."""
    changes = {"rho": args.rho, "order": order, "max_iter": args.max_iter, "polish": bool(args.polish)}
    if args.eps is not None:
        changes |= {"eps_abs": args.eps, "eps_rel": args.eps}
    elif args.eps_abs is not None:
        changes |= {"eps_abs": args.eps_abs, "eps_rel": args.eps_rel or 0.0}
    if args.eps_inf is not None:
        changes |= {"eps_prim_inf": args.eps_inf, "eps_dual_inf": args.eps_inf}
    if getattr(args, "history_every_iteration", False):
        changes["check_every"] = 1                # a complete --history row per iteration (the same iterates)
    return osqp_settings(**changes)


def run_osqp(qp, args):
    """``solve_qp`` with the osqp preset and the options; prints the common summary."""
    from .solve import OSQP_NORMALISED, default_policy, qp_for, solve_qp
    key = args.policy.strip().lower().replace("-", "_")
    if key in OSQP_NORMALISED:                    # OSQP's rule (or rowwise) on OSQP's normalisation (solve_qp)
        order, rule, name = args.order or "xz", key, key
    else:
        order, rule, name = resolve_policy(args)
    settings = osqp_settings_from(args, order)
    named = isinstance(rule, str) and rule in OSQP_NORMALISED
    shown = default_policy(qp_for(qp, settings), settings, rule) if named else rule
    with progress(args, settings.max_iter, every=settings.check_every) as show:
        result = solve_qp(qp, settings, policy=rule, callback=show)
    args.resolved = {"policy": name, "order": order, "policy_repr": repr(shown),
                     "stop": f"osqp_termination(eps_abs={settings.eps_abs:g}, eps_rel={settings.eps_rel:g}, "
                             f"eps_prim_inf={settings.eps_prim_inf:g}, eps_dual_inf={settings.eps_dual_inf:g})"}
    print_summary(result, name, settings.rho)
    write_history(result.history, args)
    return result


def run_textbook(qp, args):
    """The plain loop (``admmkit.cli.run_solve``), its result as a ``QPResult`` with the neutral criteria.

    Its status is checked against the QP's own relative KKT residuals (``QP.kkt_relative``): a relative-change
    stop far from the solution is ``converged_inaccurate``, not ``converged`` (issue #46 item 7)."""
    import dataclasses

    from admmkit import Result

    from .residuals import neutral_residuals
    from .solve import QPResult
    res = run_solve(qp, args)
    fields = {f.name: getattr(res, f.name) for f in dataclasses.fields(Result)}
    return QPResult(**fields, neutral=neutral_residuals(qp, res.x, res.lam))


def run(args) -> int:
    """Build the QP, solve it, print the summary; exit 0 only for a clean solve, 1 otherwise (docs/cli.md)."""
    check_preset_options(args)
    qp = build_qp(args)
    print(f"problem      {qp.name}: n = {qp.n}, m = {qp.m}")
    print(f"preset       {args.preset}")
    result = run_osqp(qp, args) if args.preset == "osqp" else run_textbook(qp, args)
    certificate = certificate_summary(qp, result)
    print("\n".join(qp_lines(result, certificate, args.preset)))
    problem = {"name": qp.name, "n": qp.n, "m": qp.m, "preset": args.preset, "source": args.mat or
               {"random": list(args.random), "kind": args.kind, "seed": args.seed}}
    if args.json:
        print(f"json         {write_qp_json(args.json, result, args, problem=problem, certificate=certificate, preset=args.preset)}")
    if args.csv:
        print(f"csv          {write_qp_csv(args.csv, qp, result, certificate, args.preset)}")
    return exit_code(result, args.preset)


def exit_code(result, preset: str) -> int:
    """0 for a clean solve (osqp preset: OSQP's test fired as "solved"; textbook: status converged), else 1."""
    from admmkit import Status
    clean = result.status is Status.CONVERGED and (preset == "textbook" or result.termination == "solved")
    return 0 if clean else 1
