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


#: what the full run's Hertz scenes hold at their reference's finest level (P2 to 1e-4: 690,046 unknowns in the
#: condensed mode, then the study's exact solve of that level): on the machine of 29 November (23.5 GiB) the
#: level's own solve peaked at 17-21 GB and the study was killed for memory at 24.3 GB (docs/contact.md)
HERTZ_REFERENCE_BYTES = 25e9


def check_memory(quick: bool, scenes, available: float) -> None:
    """Refuse, before any work, a full run with the Hertz scenes where less than HERTZ_REFERENCE_BYTES is
    available (a ValueError: one line, exit 2), naming what runs instead."""
    if quick or "hertz" not in scenes or available >= HERTZ_REFERENCE_BYTES:
        return
    others = " ".join(s for s in scenes if s != "hertz")
    instead = f"run --scenes {others}" if others else "run it on a larger machine"
    raise ValueError(f"bench adaptive: the Hertz scenes' reference (690,046 P2 unknowns on its finest level) was "
                     f"killed for memory at 24.3 GB resident where 24.7 GB were available; this check asks for "
                     f"{HERTZ_REFERENCE_BYTES / 1e9:g} GB, {available / 1e9:.1f} GB available here; {instead}, "
                     f"or --quick")


def _adaptive(args) -> int:
    from admmkit.benchmarks.adaptive.study import run
    from admmkit.problems.contact.model.memory import available_memory
    check_memory(args.quick, args.scenes, available_memory())
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
