"""Property-based checks (hypothesis): inputs within the documented ranges never raise, and the status is truthful.

For QPs of every documented kind and shape, every registered rule, both
orders, rho_0 over 16 decades and any over-relaxation in (0, 2): ``solve``
raises nothing, the status is one of the documented ones, and a run that
says ``converged`` is within the tolerance of Clarabel's solution (checked by
the QP's KKT conditions, independent of the loop).  For contact scenes within
the documented ranges (size, material, mesh, gap), ``solve_scene`` raises
nothing and a ``converged`` run satisfies the contact KKT conditions.
"""
import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings, strategies as st  # noqa: E402

import admmkit  # noqa: E402
from admmkit import ResidualTolerance, Status  # noqa: E402

STATUSES = {s.value for s in Status}
RULES = [name for name in admmkit.policy_names()]


def _buildable(name):
    try:
        admmkit.make_policy(name)
        return True
    except (TypeError, ValueError):
        return False


RULES = [r for r in RULES if _buildable(r)]


@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(1, 25), m=st.integers(1, 25), kind=st.sampled_from(["inequality", "equality", "mixed"]),
       seed=st.integers(0, 2**31 - 1), rule=st.sampled_from(RULES), order=st.sampled_from(["xz", "zx"]),
       log_rho=st.floats(-8, 8), alpha=st.floats(0.05, 1.95))
def test_random_qps_never_raise_and_converged_means_kkt(n, m, kind, seed, rule, order, log_rho, alpha):
    from admmkit.problems.qp import random_qp
    qp = random_qp(n, m, kind=kind, seed=seed)
    r = admmkit.solve(qp, rho=10.0 ** log_rho, policy=rule, order=order, alpha=alpha,
                      stop=ResidualTolerance(1e-7, 1e-7), max_iter=4000)
    assert r.status.value in STATUSES
    if r.status is Status.CONVERGED:   # P is positive definite: the solution is unique; Clarabel's is independent
        from admmkit.problems.qp.reference import solve_with_cvxpy
        x_ref, _, _ = solve_with_cvxpy(qp, tol_gap_abs=1e-10, tol_gap_rel=1e-10, tol_feas=1e-10)
        assert np.abs(r.x - x_ref).max() <= 1e-3 * (1.0 + np.abs(x_ref).max())


@settings(max_examples=25, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(L=st.floats(0.5, 4.0), H=st.floats(0.5, 2.0), E=st.floats(1e-2, 1e4), nu=st.floats(0.0, 0.45),
       gap=st.floats(0.0, 0.05), cells=st.integers(4, 10), method=st.sampled_from(["admm1", "admm2", "sadmm"]),
       mesh=st.sampled_from(["structured", "unstructured"]))
def test_contact_scenes_in_range_never_raise(L, H, E, nu, gap, cells, method, mesh):
    from admmkit.problems.contact import Scene, solve_scene
    scene = Scene(L=L, H=H, h=min(L, H) / cells, E=E, nu=nu, gap=gap, mesh_kind=mesh,
                  dirichlet=("left",), contact="bottom", tractions={"top": (0.0, -0.1 * E)})
    sol = solve_scene(scene, method, rho=E, max_iter=3000)
    r = sol.result
    assert r.status.value in STATUSES
    if r.status is Status.CONVERGED:   # within 1e-3 of an independent interior-point solve of the same problem
        from admmkit.problems.contact.validation.reference import errors_against, reference_solution
        assert errors_against(sol.ops, reference_solution(sol.ops), r.x, r.lam)["err_u_energy"] < 1e-3
