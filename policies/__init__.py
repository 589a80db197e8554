"""Penalty (rho) rules for admmkit, one module per rule.

Importing this package registers every rule by name, so that
``admmkit.solve(problem, policy="summable")`` and ``admmkit.make_policy`` find them.
"""
from .fixed import Fixed
from .residual_balancing import ResidualBalancing
from .summable import Summable

__all__ = ["Fixed", "ResidualBalancing", "Summable"]
