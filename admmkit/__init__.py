"""admmkit: ADMM with adaptive penalty parameters.

The framework core: the problem protocol (:class:`Problem`), one loop
(:func:`solve`) for both orders, the penalty-policy protocol (:class:`Policy`),
composable stopping rules, the per-iteration history and the result; and
building blocks for new problems: :class:`LinearMap` (A, M and the derived
adjoint), :class:`QuadraticXStep` (the x-step of a quadratic f, cached per
rho), ``admmkit.prox`` (:mod:`admmkit.blocks.prox`: z-steps from proximal operators) and
:class:`SplitProblem` (a problem assembled from them).  Penalty rules live in
:mod:`admmkit.policies`, plug-ins in ``admmkit.problems`` and the studies in
:mod:`admmkit.benchmarks`; the core imports none of them (a rule named by a
string is found through the entry-point group ``admmkit.policies``).
"""
from ._layout import map_source_tree

map_source_tree(__path__[0])   # a source checkout resolves admmkit.policies etc. as the installed package does

#: every public name, imported on first use (PEP 562): ``import admmkit`` costs nothing beyond this file, so the
#: command line's help and a plug-in's entry point load no numpy; ``from admmkit import solve`` loads the loop
#: (numpy), ``admmkit.LinearMap`` and the other building blocks scipy.sparse as well (issue #49)
_ON_DEMAND = {"History": ("loop.history", "History"), "Policy": ("policy", "Policy"),
              "RowPenalties": ("policy", "RowPenalties"), "make_policy": ("policy", "make_policy"),
              "policy_names": ("policy", "policy_names"), "register_policy": ("policy", "register_policy"),
              "Problem": ("problem", "Problem"), "IterationRecord": ("loop.record", "IterationRecord"),
              "Result": ("loop.result", "Result"), "Status": ("loop.result", "Status"),
              "solve": ("loop.solver", "solve"), "BalancedStop": ("fe.balanced_stop", "BalancedStop"),
              "AllOf": ("loop.stopping", "AllOf"), "AnyOf": ("loop.stopping", "AnyOf"),
              "RelativeChange": ("loop.stopping", "RelativeChange"),
              "ResidualTolerance": ("loop.stopping", "ResidualTolerance"), "Stop": ("loop.stopping", "Stop"),
              "StoppingRule": ("loop.stopping", "StoppingRule"), "default_stop": ("loop.stopping", "default_stop"),
              "LinearMap": ("blocks.operators", "LinearMap"), "QuadraticXStep": ("blocks.xstep", "QuadraticXStep"),
              "SplitProblem": ("blocks.split", "SplitProblem"), "prox": ("blocks.prox", None)}


def __getattr__(name: str):
    """A public name (``admmkit.solve``, ``admmkit.Status``, ``admmkit.LinearMap``, ``admmkit.prox``, ...): its module
    imported on first use."""
    if name not in _ON_DEMAND:
        raise AttributeError(f"module 'admmkit' has no attribute {name!r}")
    import importlib
    module_name, attr = _ON_DEMAND[name]
    module = importlib.import_module(f"{__name__}.{module_name}")
    value = module if attr is None else getattr(module, attr)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """The module's names, the on-demand ones included."""
    return sorted({*globals(), *_ON_DEMAND})


__version__ = "0.1.0"

__all__ = [
    "solve", "Problem", "Policy", "RowPenalties", "IterationRecord", "Result", "Status", "History",
    "StoppingRule", "Stop", "RelativeChange", "ResidualTolerance", "BalancedStop", "AnyOf", "AllOf", "default_stop",
    "register_policy", "make_policy", "policy_names", "__version__",
    "LinearMap", "QuadraticXStep", "SplitProblem",
]
