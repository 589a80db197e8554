"""A cvxpy solver for the QP plug-in: ``problem.solve(solver=ADMMKIT(policy="summable"))``.

cvxpy reduces a QP-representable problem to min 1/2 x'Px + q'x s.t. A x = b,
F x <= g, and hands custom QP solvers that data (cvxpy's ``QpSolver``
interface, the one its own OSQP interface uses).  :class:`ADMMKIT` stacks it
into OSQP's form l <= [A; F] x <= u with l = [b; -inf], u = [b; g], solves it
with :func:`admmkit.problems.qp.solve_qp` (OSQP's machinery and any rule) and
returns cvxpy's status, the primal values and the duals (OSQP's sign
convention, which cvxpy's OSQP interface reads the same way).

Statuses: converged -> optimal; converged_inaccurate -> optimal_inaccurate;
primal_infeasible(_inaccurate) -> infeasible(_inaccurate);
dual_infeasible(_inaccurate) -> unbounded(_inaccurate); max_iter,
time_limit, stalled, stopped -> user_limit; diverged -> solver_error.
cvxpy is needed only to use this module (``pip install cvxpy``).
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import cvxpy.settings as s
from cvxpy.reductions.solution import Solution, failure_solution
from cvxpy.reductions.solvers import utilities
from cvxpy.reductions.solvers.qp_solvers.qp_solver import QpSolver

from admmkit import Status

from .problem import QP
from .solve import solve_qp

STATUS = {Status.CONVERGED: s.OPTIMAL, Status.CONVERGED_INACCURATE: s.OPTIMAL_INACCURATE,
          Status.PRIMAL_INFEASIBLE: s.INFEASIBLE, Status.PRIMAL_INFEASIBLE_INACCURATE: s.INFEASIBLE_INACCURATE,
          Status.DUAL_INFEASIBLE: s.UNBOUNDED, Status.DUAL_INFEASIBLE_INACCURATE: s.UNBOUNDED_INACCURATE,
          Status.MAX_ITER: s.USER_LIMIT, Status.TIME_LIMIT: s.USER_LIMIT, Status.STALLED: s.USER_LIMIT,
          Status.STOPPED: s.USER_LIMIT, Status.DIVERGED: s.SOLVER_ERROR}


class ADMMKIT(QpSolver):
    """admmkit's QP plug-in as a cvxpy solver.

    Parameters
    ----------
    policy : str or admmkit.Policy
        The penalty rule (default ``"osqp"``: OSQP's rule); any name, spec or
        object :func:`admmkit.problems.qp.solve_qp` accepts.
    settings : QPSettings or None
        Default :func:`admmkit.problems.qp.osqp_settings`.
    **changes
        Settings to change (``eps_abs=1e-6``, ``max_iter=...``, ``polish=True``);
        keyword arguments of ``problem.solve(solver=..., ...)`` change them too.
    """

    MIP_CAPABLE = False

    def __init__(self, policy="osqp", settings=None, **changes):
        self.policy, self.settings, self.changes = policy, settings, changes

    def name(self) -> str:
        """The solver's name in cvxpy (``problem.solver_stats.solver_name``)."""
        return "ADMMKIT"

    def import_solver(self) -> None:
        """Nothing to import: admmkit is this package."""

    def cite(self, data) -> str:
        """What to cite: OSQP's paper, whose machinery the plug-in follows."""
        return ("B. Stellato, G. Banjac, P. Goulart, A. Bemporad, S. Boyd, OSQP: an operator splitting solver "
                "for quadratic programs, Math. Program. Comput. 12:637-672, 2020")

    def solve_via_data(self, data, warm_start: bool, verbose: bool, solver_opts, solver_cache=None):
        """Solve cvxpy's QP data with :func:`admmkit.problems.qp.solve_qp`; returns the QPResult."""
        P, q = data[s.P], np.asarray(data[s.Q], dtype=float)
        n = q.size
        P = sp.csc_matrix((n, n)) if P is None else sp.csc_matrix(P)
        P = (P + P.T) / 2 if (P - P.T).nnz and abs(P - P.T).max() > 0 else P
        A = sp.vstack([data[s.A], data[s.F]]).tocsc()
        b, g = np.asarray(data[s.B], dtype=float), np.asarray(data[s.G], dtype=float)
        qp = QP(P, q, A, np.concatenate([b, np.full(g.size, -np.inf)]), np.concatenate([b, g]))
        return solve_qp(qp, self.settings, policy=self.policy, **{**self.changes, **solver_opts})

    def invert(self, solution, inverse_data):
        """cvxpy's Solution: status, objective (plus cvxpy's offset), x and the constraints' duals."""
        status = STATUS.get(solution.status, s.SOLVER_ERROR)
        attr = {s.SOLVE_TIME: solution.timings.get("total"), s.NUM_ITERS: solution.iterations,
                s.EXTRA_STATS: solution}
        n_eq = inverse_data[self.DIMS].zero

        def duals(y):
            eq = utilities.get_dual_values(y[:n_eq], utilities.extract_dual_value, inverse_data[self.EQ_CONSTR])
            ineq = utilities.get_dual_values(y[n_eq:], utilities.extract_dual_value, inverse_data[self.NEQ_CONSTR])
            return eq | ineq

        if status in s.SOLUTION_PRESENT:
            primal = {self.VAR_ID: np.asarray(solution.x)}
            return Solution(status, solution.objective + inverse_data[s.OFFSET], primal, duals(solution.y), attr)
        certificate = solution.certificate if status in (s.INFEASIBLE, s.INFEASIBLE_INACCURATE) else None
        return failure_solution(status, attr, duals(certificate) if certificate is not None else None)
