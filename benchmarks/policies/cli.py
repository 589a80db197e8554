"""``admmkit bench policies``, registered by an entry point in ``pyproject.toml`` (the study: ``study.py``)."""
from __future__ import annotations

from admmkit.benchmarks.runner.options import add_study, executor_of, split_list


def policies(targets) -> None:
    """``admmkit bench policies``: the rules on contact Ex. 1 and the radial obstacle across rho_0."""
    from admmkit.benchmarks.policies.study import RULES
    b = add_study(targets, "policies", _policies,
                  help="penalty rules on contact Ex.1 and the radial obstacle, rho_0 over 12 decades",
                  description="Iterations, factorisations and the error at the stop of the penalty rules "
                              "on contact Example 1 (h = 1/20) and the radial obstacle (h = 1/16).",
                  needs_line="ngsolve", modules=("cvxpy", "clarabel"))          # the references
    b.add_argument("--rules", default=",".join(RULES), help=f"comma-separated rules (default {','.join(RULES)})")


def _policies(args) -> int:
    import admmkit

    from admmkit.benchmarks.policies.study import run
    from admmkit.policy import canonical_spec, is_spec
    rules = [canonical_spec(r) if is_spec(r) else r for r in split_list(args.rules) or []]
    unknown = [r for r in rules if not is_spec(r) and r not in admmkit.policy_names()]
    if unknown or not rules:
        raise ValueError(f"--rules: unknown {unknown}; known: {', '.join(admmkit.policy_names())}, or "
                         f"module:Class or path/to/file.py:Class")
    for rule in rules:                       # a rule that does not load or breaks the protocol: before any case runs
        try:
            made = admmkit.make_policy(rule)
        except (TypeError, ValueError) as err:
            raise ValueError(f"--rules: {err}") from None
        if getattr(made, "per_row", False):
            raise ValueError(f"--rules: {rule} sets a penalty per row; the contact and obstacle problems of bench "
                             f"policies take one rho (run it with bench rules --families qp)")
    run(args.out, rules=rules, quick=args.quick, command=args.command_line, progress=args.progress,
        executor=executor_of(args), report_only=args.report_only)
    return 0
