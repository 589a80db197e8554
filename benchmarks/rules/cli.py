"""``admmkit bench rules``, registered by an entry point in ``pyproject.toml`` (the study: ``study.py``)."""
from __future__ import annotations

from admmkit.benchmarks.runner.options import add_study, executor_of, print_files, split_list


def rules(targets) -> None:
    """``admmkit bench rules``: every rule (and one of yours) through every family, ranked."""
    from admmkit.benchmarks.rules.study import FAMILIES
    r = add_study(targets, "rules", _rules,
                  help="rank the penalty rules (and yours) on every family, with acceleration",
                  description="Runs the rules through the QP (Maros-Meszaros under OSQP's machinery), "
                              "contact, obstacle, friction, framework and stability families and ranks "
                              "them by performance profiles (benchmarks/rules/study.py).",
                  needs_line="ngsolve; the qp family the Maros-Meszaros MAT files (--data)", modules=references)
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


#: the families whose references are cvxpy + Clarabel solves
CVXPY_FAMILIES = ("contact", "obstacle", "friction", "framework", "stability")


def references(args) -> tuple[str, ...]:
    """cvxpy and Clarabel if a family asked for has its references from them."""
    return ("cvxpy", "clarabel") if set(split_list(args.families) or []) & set(CVXPY_FAMILIES) else ()


def _rules(args) -> int:
    from admmkit.benchmarks.rules.study import run
    print_files(run(args.out, rules=split_list(args.rules), acceleration=split_list(args.acceleration) or [],
                    families=split_list(args.families) or [], presets=split_list(args.presets) or [],
                    quick=args.quick, data=args.data,
                    command=args.command_line, progress=args.progress, report_only=args.report_only,
                    executor=executor_of(args)))
    return 0
