"""Reference baselines: non-ADMM solvers that the benchmarks measure ADMM against.

They are here to answer "what would a user pick instead?", not to be used by
the ADMM framework.  ``pdas`` is the primal-dual active set method
(semismooth Newton) for min 1/2 u'Ku - f'u s.t. B u <= g, the usual
choice for contact and obstacle problems.
"""
from .pdas import PDASResult, pdas

__all__ = ["pdas", "PDASResult"]
