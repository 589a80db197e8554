"""``admmkit bench stability``, registered by an entry point in ``pyproject.toml`` (the study: ``study.py``)."""
from __future__ import annotations

from admmkit.benchmarks.runner.options import add_study, executor_of, print_files


def stability(targets) -> None:
    """``admmkit bench stability``: where each rule converges and how it fails."""
    s = add_study(targets, "stability", _stability,
                  help="rho_0 over 13 decades, mesh, nu, P1/P2: iterations and failures",
                  description="Where each method converges and how it fails on the paper's contact "
                              "examples (rho_0/E = 1e-6..1e6; h, nu, P1/P2).",
                  needs_line="ngsolve", modules=("cvxpy", "clarabel"))          # the references
    s.add_argument("--methods", default=None, help="comma-separated ADMM methods (default: every policy, both orders)")


def _stability(args) -> int:
    from admmkit.benchmarks.fixtures.methods import parse_methods
    from admmkit.benchmarks.stability import study
    print_files(study.run(args.out, quick=args.quick, workers=args.workers, methods=parse_methods(args.methods),
                          progress=args.progress, command=args.command_line, report_only=args.report_only,
                          executor=executor_of(args)))
    return 0
