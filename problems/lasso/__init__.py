"""LASSO plug-in: min 1/2 ||A x - b||^2 + lam ||x||_1 from the building blocks; the plug-in to copy."""
from .problem import Lasso, lam_max, solve_with_cvxpy

__all__ = ["Lasso", "lam_max", "solve_with_cvxpy"]
