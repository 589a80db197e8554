"""QP plug-in: min 1/2 x'Px + q'x + r s.t. l <= A x <= u, a MAT loader and a cvxpy reference."""
from .generate import random_qp
from .mat import list_problems, load_mat
from .problem import QP

__all__ = ["QP", "load_mat", "list_problems", "random_qp"]
