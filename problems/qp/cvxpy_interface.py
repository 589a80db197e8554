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
time_limit, stalled, stopped -> user_limit; diverged -> a ``SolverError`` carrying the run's message
(which names the rule and the value it returned).

Defaults: those of cvxpy's own OSQP interface (``cvxpy/reductions/solvers/qp_solvers/osqp_qpif.py``),
eps_abs = eps_rel = 1e-5, max_iter = 10000, polishing on (``CVXPY_DEFAULTS``), so that
``solver=ADMMKIT()`` and ``solver=cp.OSQP`` ask for the same accuracy; ``settings=`` replaces them.

A constraint row whose scale makes a tolerance vacuous (``admmkit.problems.qp.termination.ScaleCheck``)
is reported with a ``ScaleWarning`` (``warnings.warn``) carrying ``QPResult.warnings``.

cvxpy is needed only to use this module (``pip install cvxpy``).
"""
from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp

try:
    import cvxpy.settings as s
    from cvxpy.error import SolverError
    from cvxpy.reductions.solution import Solution, failure_solution
    from cvxpy.reductions.solvers import utilities
    from cvxpy.reductions.solvers.qp_solvers.qp_solver import QpSolver
except ImportError:
    raise ImportError("admmkit.problems.qp.cvxpy_interface needs cvxpy: pip install cvxpy") from None

from admmkit import Status

from .problem import QP
from .settings import osqp_settings
from .solve import solve_qp
from .termination import ScaleWarning

#: the settings cvxpy's OSQP interface, osqp_qpif.py, gives OSQP (eps 1e-5, 10000 iterations, polishing)
CVXPY_DEFAULTS = {"eps_abs": 1e-5, "eps_rel": 1e-5, "max_iter": 10_000, "polish": True}

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
        Default :func:`admmkit.problems.qp.osqp_settings` with ``CVXPY_DEFAULTS`` (cvxpy's OSQP
        interface's eps 1e-5, 10000 iterations, polishing).
    **changes
        Settings to change (``eps_abs=1e-6``, ``max_iter=...``, ``polish=True``);
        keyword arguments of ``problem.solve(solver=..., ...)`` change them too (``polishing``, OSQP 1.x's
        name, is taken for ``polish``).
    """

    MIP_CAPABLE = False

    def __init__(self, policy="osqp", settings=None, **changes):
        self.policy, self.settings, self.changes = policy, settings, changes

    def name(self) -> str:
        """The solver's name in cvxpy (``problem.solver_stats.solver_name``)."""
        return "ADMMKIT"

    def import_solver(self) -> None:
        """Nothing to import: admmkit is this package."""

    def can_solve(self, problem_form) -> bool:
        """cvxpy's test; a problem it refuses gets a ``SolverError`` that names the cones it would need."""
        if super().can_solve(problem_form):
            return True
        if problem_form.is_mixed_integer():
            raise SolverError("The solver ADMMKIT cannot solve this problem: it has integer or boolean variables, "
                              "and ADMMKIT solves continuous QPs")
        from cvxpy.reductions.solvers.solver import expand_cones
        supported = frozenset(self.SUPPORTED_CONSTRAINTS)
        cones = set(problem_form.cones(quad_obj=self.supports_quad_obj()
                                       and problem_form.has_quadratic_objective()))
        expand_cones(cones, supported)
        missing = sorted(cone.__name__ for cone in cones - supported) or ["a form cvxpy cannot reduce to a QP"]
        raise SolverError(f"The solver ADMMKIT cannot solve this problem: it needs the cone(s) {', '.join(missing)}, "
                          "and ADMMKIT solves QPs (a quadratic or linear objective, equality and inequality "
                          "constraints: cvxpy's Zero and NonNeg); use a conic solver such as cp.CLARABEL")

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
        opts = {**self.changes, **solver_opts}
        if "polishing" in opts:
            opts["polish"] = opts.pop("polishing")
        settings = osqp_settings(**CVXPY_DEFAULTS) if self.settings is None else self.settings
        result = solve_qp(qp, settings, policy=self.policy, **opts)
        for text in result.warnings:
            warnings.warn(f"ADMMKIT (rows of the QP cvxpy passes: its equalities, then its inequalities): {text}",
                          ScaleWarning, stacklevel=2)
        return result

    def invert(self, solution, inverse_data):
        """cvxpy's Solution: status, objective (plus cvxpy's offset), x and the constraints' duals."""
        status = STATUS.get(solution.status, s.SOLVER_ERROR)
        if status == s.SOLVER_ERROR:                 # cvxpy's own error would only say "Solver 'ADMMKIT' failed"
            raise SolverError(f"Solver 'ADMMKIT' failed: the run ended {solution.status.value}: {solution.message}")
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
