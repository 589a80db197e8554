"""QP plug-in: min 1/2 x'Px + q'x + r s.t. l <= A x <= u, OSQP's machinery, a MAT loader and a cvxpy reference."""
from .generate import random_qp
from .mat import list_problems, load_mat
from .problem import QP
from .settings import QPSettings, admmkit_settings, osqp_settings, textbook_settings
from .solve import QPResult, QPStatus, solve_qp
from .termination import QPTermination

__all__ = ["QP", "load_mat", "list_problems", "random_qp", "solve_qp", "QPResult", "QPStatus", "QPSettings",
           "osqp_settings", "admmkit_settings", "textbook_settings", "QPTermination"]
