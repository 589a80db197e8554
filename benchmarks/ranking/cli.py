"""The command of the ranking (``admmkit bench rules``), registered by an entry point in ``pyproject.toml``."""
from __future__ import annotations

from admmkit.benchmarks.runner.options import add_sweep_options, executor_of, needs, print_files, split_list, study
from admmkit.benchmarks.runner.costs import typical


def rules(targets) -> None:
    """``admmkit bench rules``: every rule (and one of yours) through every family, ranked."""
    from admmkit.benchmarks.ranking.study import FAMILIES
    r = targets.add_parser("rules", help="rank the penalty rules (and yours) on every family, with acceleration",
                           description="Runs the rules through the QP (Maros-Meszaros under OSQP's machinery), "
                                       "contact, obstacle, friction, framework and stability families and ranks "
                                       "them by performance profiles (benchmarks/ranking/study.py)."
                                       + typical("bench rules") + " needs: ngsolve; the qp family the Maros-Meszaros MAT files (--data)")
    add_sweep_options(r, "rules")
    r.add_argument("--rules", default=None,
                   help="comma-separated rules: names, module:Class or path/to/file.py:Class (default: all registered)")
    r.add_argument("--acceleration", default="none,anderson",
                   help="comma-separated: none, anderson, fast (default none,anderson)")
    r.add_argument("--presets", default="osqp",
                   help="qp family: comma-separated QP settings presets to run each rule in: osqp (OSQP's, cap 4000), "
                        "admmkit (admmkit_settings, its own cap; ranked as rule@admmkit) (default osqp)")
    r.add_argument("--families", default=",".join(FAMILIES), help=f"comma-separated (default {','.join(FAMILIES)})")
    r.add_argument("--data", default=None, metavar="DIR",
                   help="Maros-Meszaros MAT files for the qp family (default ../shared/data/maros_meszaros if there)")
    r.set_defaults(func=study(_rules))


#: the families whose references are cvxpy + Clarabel solves
CVXPY_FAMILIES = ("contact", "obstacle", "friction", "framework", "stability")


def _rules(args) -> int:
    needs(args, *(["cvxpy", "clarabel"] if set(split_list(args.families) or []) & set(CVXPY_FAMILIES) else []))
    from admmkit.benchmarks.ranking.study import run
    print_files(run(args.out, rules=split_list(args.rules), acceleration=split_list(args.acceleration) or [],
                    families=split_list(args.families) or [], presets=split_list(args.presets) or [],
                    quick=args.quick, data=args.data,
                    command=args.command_line, progress=args.progress, report_only=args.report_only,
                    executor=executor_of(args)))
    return 0
