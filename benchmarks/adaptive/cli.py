"""``admmkit bench adaptive`` and ``admmkit bench estimators``, registered by entry points in ``pyproject.toml``
(the studies: ``study.py`` and ``estimators.py``)."""
from __future__ import annotations

from pathlib import Path

from admmkit.benchmarks.runner.options import add_study, print_files


def adaptive(targets) -> None:
    """``admmkit bench adaptive``: adaptive against uniform refinement at the same true error."""
    from admmkit.benchmarks.adaptive.study import SCENES
    b = add_study(targets, "adaptive", _adaptive, sweep=False, out="adaptive_study",
                  help="adaptive against uniform refinement at the same true error "
                       "(contact Examples 1 and 2, Hertz, radial obstacle)",
                  description="Unknowns, wall time, rates, effectivity and iterations of adaptive and "
                              "uniform refinement (benchmarks/adaptive/study.py).",
                  needs_line="ngsolve, matplotlib")
    b.add_argument("--quick", action="store_true", help="coarse targets and the three coarsest uniform meshes")
    b.add_argument("--scenes", nargs="+", choices=SCENES, default=list(SCENES),
                   help="the scenes to run (default all; the report holds only these)")


def _adaptive(args) -> int:
    from admmkit.benchmarks.adaptive.study import run
    print_files(run(Path(args.out), args.command_line, quick=args.quick, scenes=args.scenes))   # command as typed
    return 0


def estimators(targets) -> None:
    """``admmkit bench estimators``: the ZZ and the residual estimators against the true error."""
    b = add_study(targets, "estimators", _estimators, sweep=False,
                  help="ZZ and residual error estimators against the true error (obstacle, contact Example 1)",
                  description="Effectivity and convergence of both estimators under uniform refinement "
                              "(benchmarks/adaptive/estimators.py).",
                  needs_line="ngsolve, matplotlib", modules=("cvxpy", "clarabel"))      # the obstacle's u_h
    b.add_argument("--quick", action="store_true", help="the three coarsest meshes only")


def _estimators(args) -> int:
    from admmkit.benchmarks.adaptive.estimators import run
    print_files(run(Path(args.out), args.command_line, quick=args.quick))     # the command as typed, for the report
    return 0
