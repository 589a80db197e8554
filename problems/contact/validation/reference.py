"""A tight reference solution of the discrete contact problem, and errors against it.

The discrete problem is the QP min 1/2 u'Ku - f'u s.t. B u <= g.  The
reference is an interior-point solve (cvxpy + Clarabel), cross-checked by an
independent SADMM run to Boyd residuals below 1e-12.  Without Clarabel (or
when it fails) the SADMM run is the reference, and says so: a
``RuntimeWarning`` naming why, and ``Reference.info``.
"""
from __future__ import annotations

import importlib.util
import math
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

import admmkit

from admmkit.problems.contact.model.assembly import ContactOperators
from admmkit.problems.contact.solvers.methods import solve_scene
from admmkit.problems.contact.solvers.problem import contact_problem


#: the solver of the fallback reference
TIGHT_SADMM = "sadmm, ResidualTolerance(1e-12, 1e-12)"


@dataclass
class Reference:
    """A tight solution of the discrete problem min 1/2 u'Ku - f'u s.t. Bu <= g.

    ``info``: ``{"solver": who made it, "fallback": why Clarabel did not (None if it did)}``.
    """

    u: np.ndarray
    lam: np.ndarray
    solver: str
    kkt: dict
    seconds: float
    cross_check: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)


def energy_norm(ops: ContactOperators, v: np.ndarray) -> float:
    """sqrt(v'Kv)."""
    return float(np.sqrt(max(v @ (ops.K @ v), 0.0)))


def energy(ops: ContactOperators, u: np.ndarray) -> float:
    """J(u) = u'Ku / 2 - f'u on the free dofs (frictionless: the contact plug-in's objective)."""
    return float(0.5 * u @ (ops.K @ u) - ops.f @ u)


def reference_solution(ops: ContactOperators, tol: float = 1e-10) -> Reference:
    """Solve the discrete QP tightly, cross-checked by a second solver.

    Primary: cvxpy + Clarabel (interior point) at gap/feasibility tolerance ``tol``;
    lam = (dual of Bu <= g) / M_c.  Cross-check: SADMM (rho = 1e3) run until Boyd's
    residuals are below 1e-12.  If cvxpy or Clarabel is missing, or Clarabel fails or does
    not report "optimal", the SADMM solution is the reference: a ``RuntimeWarning`` says
    why, and ``info`` names the solver and the reason.  ``cross_check`` holds the
    relative energy-norm and pressure differences between the two.
    """
    t0 = time.perf_counter()
    tight = solve_scene(ops, "sadmm", 1e3, stop=admmkit.ResidualTolerance(1e-12, 1e-12), max_iter=200_000)
    t_admm = time.perf_counter() - t0
    admm = (tight.result.x, tight.result.lam)
    checker = contact_problem(ops, mode="full")
    primary, why = clarabel_solution(ops, tol)
    kkt_of = lambda uu, ll: checker.kkt(uu, np.minimum(ops.g, ops.B @ uu), ll)  # noqa: E731
    if primary is None:
        warnings.warn(f"reference_solution: {why}; the reference is the tight SADMM run instead ({TIGHT_SADMM}), "
                      f"not an interior-point solve", RuntimeWarning, stacklevel=2)
        return Reference(admm[0], admm[1], TIGHT_SADMM, kkt_of(*admm), t_admm,
                         info={"solver": TIGHT_SADMM, "fallback": why})
    u_ref, lam_ref, t_ipm = primary
    lam_norm = math.sqrt(max(float(ops.mc @ lam_ref**2), 1e-300))
    cross = {
        "other": TIGHT_SADMM,
        "u_energy_rel_diff": energy_norm(ops, admm[0] - u_ref) / energy_norm(ops, u_ref),
        "lam_rel_diff": math.sqrt(float(ops.mc @ (admm[1] - lam_ref) ** 2)) / lam_norm,
    }
    solver = f"cvxpy + Clarabel, tol {tol:g}"
    return Reference(u_ref, lam_ref, solver, kkt_of(u_ref, lam_ref), t_ipm, cross,
                     info={"solver": solver, "fallback": None})


def clarabel_solution(ops: ContactOperators, tol: float):
    """((u, lam, seconds), None) from cvxpy + Clarabel, or (None, why not): a module missing, Clarabel failing or
    ending otherwise than "optimal"."""
    for module, name in (("cvxpy", "cvxpy"), ("clarabel", "Clarabel")):
        if _missing(module):
            return None, f"{name} is not installed"
    try:
        import cvxpy as cp
        t0 = time.perf_counter()
        u = cp.Variable(ops.n_free)
        constraint = ops.B @ u <= ops.g
        prob = cp.Problem(cp.Minimize(0.5 * cp.quad_form(u, cp.psd_wrap(ops.K)) - ops.f @ u), [constraint])
        prob.solve(solver=cp.CLARABEL, tol_gap_abs=tol, tol_gap_rel=tol, tol_feas=tol, max_iter=500)
        seconds = time.perf_counter() - t0
    except Exception as err:  # noqa: BLE001  (any failure of the external solver: the fallback says which)
        return None, f"Clarabel failed ({type(err).__name__}: {' '.join(str(err).split())})"
    if prob.status != "optimal":
        return None, f"Clarabel ended with status {prob.status!r}, not 'optimal'"
    return (np.asarray(u.value), np.asarray(constraint.dual_value) / ops.mc, seconds), None


def _missing(module: str) -> bool:
    """True if ``module`` cannot be imported (not installed, or blocked as ``sys.modules[name] = None``)."""
    try:
        return importlib.util.find_spec(module) is None
    except (ImportError, ValueError):
        return True


def errors_against(ops: ContactOperators, ref: Reference, u: np.ndarray, lam: np.ndarray) -> dict:
    """Relative energy-norm error of u and relative M_c-norm error of lam."""
    lam_norm = math.sqrt(max(float(ops.mc @ ref.lam**2), 1e-300))
    return {"err_u_energy": energy_norm(ops, u - ref.u) / energy_norm(ops, ref.u),
            "err_lam": math.sqrt(float(ops.mc @ (lam - ref.lam) ** 2)) / lam_norm}

