"""Never a false infeasibility (#26 item 5): a candidate certificate is declared only when the exact LP confirms it."""
from pathlib import Path

import numpy as np
import pytest

from admmkit import Status
from admmkit.problems.qp import load_mat, solve_qp
from admmkit.problems.qp.generate import infeasible_qp, unbounded_qp
from admmkit.problems.qp.infeasibility import check_dual_certificate, check_primal_certificate

MM = Path(__file__).resolve().parents[3] / "shared" / "data" / "maros_meszaros"
INFEASIBLE = (Status.PRIMAL_INFEASIBLE, Status.PRIMAL_INFEASIBLE_INACCURATE,
              Status.DUAL_INFEASIBLE, Status.DUAL_INFEASIBLE_INACCURATE)


@pytest.mark.skipif(not MM.is_dir(), reason="needs ../shared/data/maros_meszaros")
@pytest.mark.parametrize("name", ["PRIMALC1", "PRIMALC2", "PRIMALC5", "QPCBOEI2"])
@pytest.mark.parametrize("eps", [1e-3, 1e-6])
def test_feasible_bounded_maros_meszaros_qps_are_never_declared_infeasible(name, eps):
    """OSQP 1.1.3 (eps_dual_inf 1e-4) declares the first three unbounded; they are feasible and bounded."""
    res = solve_qp(load_mat(MM / f"{name}.mat"), eps_abs=eps, eps_rel=0.0, max_iter=4000)
    assert res.status not in INFEASIBLE


@pytest.mark.parametrize("seed", range(20))
def test_infeasible_qps_are_still_declared_with_an_exact_certificate(seed):
    qp = infeasible_qp(20, 30, seed=seed)
    res = solve_qp(qp, max_iter=4000)
    assert res.status is Status.PRIMAL_INFEASIBLE
    check = check_primal_certificate(qp, res.certificate)
    assert check["At_y"] <= 1e-8 and check["support"] < -1e-6 and not check["pushes_infinite_bound"]


@pytest.mark.parametrize("seed", range(20))
@pytest.mark.parametrize("lp", [False, True])
def test_unbounded_qps_are_still_declared_with_an_exact_certificate(seed, lp):
    qp = unbounded_qp(20, 30, seed=seed, lp=lp)
    res = solve_qp(qp, max_iter=4000)
    assert res.status is Status.DUAL_INFEASIBLE
    check = check_dual_certificate(qp, res.certificate)
    assert check["P_x"] <= 1e-8 and check["q_x"] < -1e-6 and check["cone_violation"] <= 1e-8
    assert np.isneginf(res.objective)
