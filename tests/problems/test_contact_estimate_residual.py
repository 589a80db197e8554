"""The contact plug-in's residual estimator (Hild & Nicaise, #24) and --estimator.

The true discretisation error comes from the energy of a much finer mesh
(J(u_h) - J(u) >= ||u_h - u||_a^2 / 2), as in test_contact_estimate.py.
"""
import math

import numpy as np
import pytest

import admmkit
from admmkit.cli import main
from admmkit.problems.contact import assemble, contact_problem, example1, example2, solve_scene
from admmkit.problems.contact.model.scene3d import example2_3d
from admmkit.problems.contact.solvers.adaptive import solve_adaptive
from admmkit.problems.contact.solvers.estimate import BalancedStop, zz_estimate
from admmkit.problems.contact.solvers.estimate_residual import (ResidualEstimator, residual_estimate,
                                                               residual_estimator, residual_indicators)
from admmkit.problems.contact.validation.reference import energy, energy_norm, reference_solution


@pytest.fixture(scope="module")
def ladder(contact_tight):
    """(h, true error, residual estimate, ZZ estimate) on Example 1, P1, h = 1/5, 1/10, 1/20 (reference h = 1/80)."""
    fine = assemble(example1(h=1 / 80))
    J_fine = energy(fine, contact_tight(fine).x)
    rows = []
    for h in (1 / 5, 1 / 10, 1 / 20):
        ops = assemble(example1(h=h))
        tight = contact_tight(ops)
        u, lam = tight.x, tight.lam
        rows.append((h, math.sqrt(2 * max(energy(ops, u) - J_fine, 0.0)), residual_estimate(ops, u, lam),
                     zz_estimate(ops, u)))
    return rows


def test_the_effectivity_is_bounded_and_the_estimate_is_above_the_error(ladder):
    effectivity = [eta / err for _, err, eta, _ in ladder]
    assert all(1.0 <= e <= 6.0 for e in effectivity), effectivity
    assert max(effectivity) / min(effectivity) <= 1.5, effectivity


def test_the_estimate_converges_at_the_rate_of_zz(ladder):
    for (h0, _, eta0, zz0), (h1, _, eta1, zz1) in zip(ladder, ladder[1:]):
        rate, rate_zz = math.log(eta0 / eta1) / math.log(h0 / h1), math.log(zz0 / zz1) / math.log(h0 / h1)
        assert abs(rate - rate_zz) <= 0.15, (rate, rate_zz)


@pytest.mark.parametrize("scene", [example1(h=1 / 5, order=2), example2(h=1 / 5, order=2), example2(h=1 / 5),
                                   example2_3d(h=1 / 2)], ids=["ex1-P2", "ex2-P2", "ex2-P1", "3D-P1"])
def test_indicators_are_one_non_negative_value_per_element(scene):
    sol = solve_scene(scene, "sadmm", 1e3, mode="condensed")
    ops = sol.ops
    terms = residual_estimator(ops).terms(sol.result.x, sol.result.lam)
    for values in terms.values():
        assert values.shape == (ops.mesh.ne,) and np.all(values >= 0)
    eta_T = residual_indicators(ops, sol.result.x, sol.result.lam)
    assert eta_T.shape == (ops.mesh.ne,) and np.all(eta_T >= 0) and np.allclose(eta_T ** 2, sum(terms.values()))
    assert terms["jump"].sum() > 0 and terms["normal_stress"].sum() > 0 and terms["neumann"].sum() > 0
    assert (terms["residual"].sum() > 0) == (scene.order == 2)          # div sigma(u_h) = 0 for P1


def test_the_pressure_is_interpolated_exactly_at_the_contact_nodes():
    for order in (1, 2):
        ops = assemble(example2(h=1 / 5, order=order))
        est = residual_estimator(ops)
        lam = np.linspace(1.0, 2.0, ops.n_c)
        est.pressure.vec.FV().NumPy()[:] = est._nodes(lam)
        assert np.allclose([est.pressure(ops.mesh(x, y)) for x, y in ops.xc], lam)


def test_the_balanced_stop_with_the_residual_estimate_means_what_it_says():
    ops = assemble(example1(h=1 / 10))
    u_h = reference_solution(ops).u
    stop = BalancedStop(contact_problem(ops, mode="condensed"), gamma=0.1, estimator="residual")
    res = admmkit.solve(stop.problem, rho=ops.scene.E, policy="summable", order="zx", stop=stop)
    assert res.converged and "residual discretisation estimate" in res.stopped_by
    assert energy_norm(ops, res.x - u_h) <= stop.algebraic <= 0.1 * stop.discretisation


def test_adaptive_marking_by_the_residual_estimator_reaches_the_target():
    out = solve_adaptive(example1(h=1 / 5), 0.2, estimator="residual")
    assert out.reached and out.levels[-1].relative_estimate <= 0.2 and len(out.levels) >= 2


def test_refusals():
    with pytest.raises(ValueError, match="frictionless"):
        ResidualEstimator(assemble(example1(h=1 / 5, tangential="tresca", slip_bound=1.0)))
    with pytest.raises(ValueError, match=r"estimator = 'res' is unknown; accepted: zz, residual"):
        solve_adaptive(example1(h=1 / 5), 0.2, estimator="res")
    with pytest.raises(ValueError, match="estimator = 'x' is unknown"):
        BalancedStop(contact_problem(assemble(example1(h=1 / 5)), mode="condensed"), estimator="x")


def test_cli_estimator(capsys):
    assert main(["solve", "contact", "--h", "1/10", "--balance", "0.1", "--estimator", "residual", "-q"]) == 0
    assert "(residual estimate)" in capsys.readouterr().out
    assert main(["solve", "contact", "--h", "1/5", "--target-error", "0.2", "--estimator", "residual"]) == 0
    assert "residual estimator" in capsys.readouterr().out
    assert main(["solve", "contact", "--h", "1/5", "--estimator", "ZZ"]) == 2
    assert capsys.readouterr().err.strip() == "admmkit: error: --estimator = 'ZZ' is unknown; accepted: zz, residual"
