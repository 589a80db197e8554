"""Penalty (rho) rules for admmkit, one module per rule.

Importing this package registers every rule by name, so that
``admmkit.solve(problem, policy="summable")`` and ``admmkit.make_policy`` find them.
"""
from .fixed import Fixed
from .osqp_rule import OSQPRule
from .osqp_kkt import OSQPKKTRule
from .priced import PricedOSQPRule
from .quantized import Quantized
from .residual_balancing import ResidualBalancing
from .spectral import Spectral
from .summable import Summable
from .summable_steps import SummableSteps
from .wohlberg import Wohlberg
from .paper_methods import PAPER_METHODS, method  # noqa: E402  (after the rules it names)

__all__ = ["Fixed", "ResidualBalancing", "Summable", "Wohlberg", "OSQPRule", "OSQPKKTRule", "PricedOSQPRule", "Spectral", "SummableSteps",
           "Quantized", "PAPER_METHODS", "method"]
