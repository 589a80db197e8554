"""``admmkit bench obstacle``, registered by an entry point in ``pyproject.toml`` (the study: ``study.py``)."""
from __future__ import annotations

from admmkit.benchmarks.runner.options import add_study, executor_of


def obstacle(targets) -> None:
    """``admmkit bench obstacle``: convergence rates against the radial exact solution, and a policy sweep."""
    add_study(targets, "obstacle", _obstacle,
              help="obstacle problem: convergence rates against the exact solution, rho sweep",
              description="Errors against the radial exact solution under refinement and the "
                          "iterations of every rule across rho_0 (benchmarks/obstacle/study.py).",
              needs_line="ngsolve", modules=("cvxpy", "clarabel"))              # the references


def _obstacle(args) -> int:
    from admmkit.benchmarks.obstacle.study import run
    return run(args.out, quick=args.quick, command=args.command_line, executor=executor_of(args),
               progress=args.progress, report_only=args.report_only)
