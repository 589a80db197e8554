"""admmkit: ADMM with adaptive penalty parameters.

The framework core: the problem protocol (:class:`Problem`), one loop
(:func:`solve`) for both orders, the penalty-policy protocol (:class:`Policy`),
composable stopping rules, the per-iteration history and the result; and
building blocks for new problems: :class:`LinearMap` (A, M and the derived
adjoint), :class:`QuadraticXStep` (the x-step of a quadratic f, cached per
rho), :mod:`admmkit.prox` (z-steps from proximal operators) and
:class:`SplitProblem` (a problem assembled from them).  Penalty rules live in
:mod:`admmkit.policies`, plug-ins in ``admmkit.problems`` and the studies in
:mod:`admmkit.benchmarks`; the core imports none of them (a rule named by a
string is found through the entry-point group ``admmkit.policies``).
"""
from ._layout import map_source_tree

map_source_tree(__path__[0])   # a source checkout resolves admmkit.policies etc. as the installed package does
from . import prox
from .history import History
from .operators import LinearMap
from .policy import Policy, make_policy, policy_names, register_policy
from .problem import Problem
from .record import IterationRecord
from .result import Result, Status
from .solver import solve
from .split import SplitProblem
from .balanced_stop import BalancedStop
from .stopping import AllOf, AnyOf, RelativeChange, ResidualTolerance, Stop, StoppingRule, default_stop
from .xstep import QuadraticXStep

__version__ = "0.1.0"

__all__ = [
    "solve", "Problem", "Policy", "IterationRecord", "Result", "Status", "History",
    "StoppingRule", "Stop", "RelativeChange", "ResidualTolerance", "BalancedStop", "AnyOf", "AllOf", "default_stop",
    "register_policy", "make_policy", "policy_names", "__version__",
    "LinearMap", "QuadraticXStep", "SplitProblem",
]
