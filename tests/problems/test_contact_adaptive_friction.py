"""Adaptive contact with friction (#24): Tresca's guaranteed algebraic error bound, the loop on Tresca and Coulomb
scenes, the command line and its refusals."""
import numpy as np
import pytest

from admmkit.fe.balanced_stop import GAMMA
import admmkit
from admmkit import ResidualTolerance
from admmkit.cli import main
from admmkit.problems.contact import assemble, solve_scene
from admmkit.problems.contact.model.assembly3d import assemble3d
from admmkit.problems.contact.model.scene3d import Scene3D
from admmkit.problems.contact.model.scene_file import load_scene
from admmkit.problems.contact.solvers.adaptive import solve_adaptive
from admmkit.problems.contact.solvers.estimate import BalancedStop, CondensedGap, algebraic_gap
from admmkit.problems.contact.solvers.estimate_friction import TrescaGap
from admmkit.problems.contact.solvers.methods import method
from admmkit.problems.contact.solvers.problem import contact_problem


def _tresca(ops):
    """The condensed problem, its tight solution's x-iterate (a residual of 1e-13) and ||u_h||_a."""
    problem = contact_problem(ops, mode="condensed")
    order, policy = method("sadmm")
    tight = admmkit.solve(problem, rho=1e3, policy=policy, order=order, stop=ResidualTolerance(1e-13, 1e-13),
                          max_iter=20_000)
    assert tight.converged
    return problem, tight


def _bounds_along_a_run(problem, x_h):
    """(bound, true error ||u - u_h||_a) at every iterate of a SADMM run to a residual of 1e-10."""
    gap, rows = TrescaGap(problem), []

    def record(rec):
        w = np.array(rec.x[1:])
        e = w - x_h[1:]
        true = float(np.sqrt(max(e @ (problem.C @ e), 0.0)))            # ||u - u_h||_a
        rows.append((gap.bound(w, np.array(rec.z), np.array(rec.lam)), true))

    order, policy = method("sadmm")
    admmkit.solve(problem, rho=1e3, policy=policy, order=order, stop=ResidualTolerance(1e-10, 1e-10), max_iter=20_000,
                  callback=record)
    return np.array(rows)


#: the scene and the median of bound / true error in the middle of the run (2D: the active-set candidate is the
#: discrete solution once the zones are found; 3D: the slip directions are the iterate's, measured 2.2)
CASES = {
    "ex1 P1, s = 2": (1.1, lambda: assemble(load_scene("ex1_tresca", h=1 / 10))),
    "ex1 P2, s = 1 + x, moving foundation": (1.1, lambda: assemble(load_scene("ex1_tresca", h=1 / 5, order=2,
                                                                              slip_bound="1 + x", obstacle_slide=0.002))),
    "3D block": (3.0, lambda: assemble3d(Scene3D(Lx=2.0, h=1 / 4, E=100.0, nu=0.3, tractions={"top": (0.5, 0.2, -2.0)},
                                           gap="0.002*(x-1)**2 + 0.001*(y-0.5)**2", tangential="tresca",
                                           slip_bound="0.3 + 0.1*x", obstacle_slide=(0.001, 0.0)))),
}


@pytest.mark.parametrize("case", CASES)
def test_the_tresca_bound_is_above_the_true_error_and_tends_to_zero(case):
    """(B_t) >= ||u - u_h||_a at every iterate of a run (u_h: the same problem solved to 1e-13, checked against
    Clarabel), in 2D equal to it (within 10 %) once the contact and stick zones are found, and down to the
    round-off floor (1e-6 ||u_h||_a) at the end."""
    from admmkit.problems.contact.solvers.tresca_qp import tresca_cvxpy
    ratio, build = CASES[case]
    ops = build()
    problem, tight = _tresca(ops)
    u_qp, _, _ = tresca_cvxpy(ops)
    assert np.linalg.norm(tight.x - u_qp) <= 1e-5 * np.linalg.norm(u_qp)
    norm = problem.x_norm(tight.x_iterate)
    rows = _bounds_along_a_run(problem, tight.x_iterate)
    bound, true = rows[:, 0], rows[:, 1]
    assert np.all(bound >= true * (1 - 1e-9))
    assert bound[-1] <= 1e-6 * norm and bound[0] >= 1e-2 * norm
    middle = (true > 1e-4 * norm) & (true < 1e-2 * norm)          # the active-set candidate makes it exact
    assert middle.sum() >= 3 and np.median(bound[middle] / true[middle]) <= ratio


def test_the_gap_picks_the_bound_of_the_model():
    frictionless = contact_problem(assemble(load_scene("ex1", h=1 / 5)), mode="condensed")
    tresca = contact_problem(assemble(load_scene("ex1_tresca", h=1 / 5)), mode="condensed")
    assert isinstance(algebraic_gap(frictionless), CondensedGap) and isinstance(algebraic_gap(tresca), TrescaGap)
    with pytest.raises(ValueError, match="TrescaGap"):
        CondensedGap(tresca)
    with pytest.raises(ValueError, match="frictionless"):
        TrescaGap(frictionless)
    with pytest.raises(ValueError, match="mode 'condensed'"):
        TrescaGap(contact_problem(tresca.ops, mode="full"))
    with pytest.raises(ValueError, match="residual.*use 'zz'"):
        BalancedStop(tresca, 0.1, estimator="residual")


def test_balance_on_a_tresca_scene_stops_with_a_true_error_below_its_bound():
    ops = assemble(load_scene("ex1_tresca", h=1 / 10))
    _, tight = _tresca(ops)
    sol = solve_scene(ops, "sadmm", 1e3, mode="condensed", balance=0.1)
    e = sol.u - tight.x
    assert sol.converged and np.sqrt(e @ (ops.K @ e)) <= sol.stop.algebraic <= 0.1 * sol.stop.discretisation


@pytest.fixture(scope="module")
def tresca_adapted():
    return solve_adaptive(load_scene("ex1_tresca", h=0.2, order=2), 2e-2)


def test_adaptive_tresca_reaches_the_target_with_balanced_warm_levels(tresca_adapted):
    out = tresca_adapted
    assert out.reached and all(lvl.status == "converged" for lvl in out.levels) and len(out.levels) >= 3
    assert all(lvl.algebraic_bound <= GAMMA * lvl.estimate for lvl in out.levels)
    assert out.levels[-1].relative_estimate <= 2e-2 < min(lvl.relative_estimate for lvl in out.levels[:-1])
    assert max(lvl.iterations for lvl in out.levels[1:]) <= out.levels[0].iterations + 10
    assert all(lvl.tresca_solves == 0 for lvl in out.levels)


def test_zz_tracks_the_tresca_error(tresca_adapted):
    """ZZ's effectivity against a finer adapted solution's energy P = J + j (P(u_h) - P(u) >= ||u_h - u||_a^2 / 2;
    the reference's own error, its estimate 3e-3 relative, is added in quadrature)."""
    def energy(ops, u):
        slip = (ops.T @ u).reshape(-1, ops.n_c)
        return 0.5 * u @ (ops.K @ u) - ops.f @ u + ops.mc @ (ops.friction.s * np.linalg.norm(slip, axis=0))

    ref = solve_adaptive(load_scene("ex1_tresca", h=0.2, order=2), 3e-3, gamma=0.02)
    last = tresca_adapted.levels[-1]
    error2 = 2 * (energy(tresca_adapted.model, tresca_adapted.result.x) - energy(ref.model, ref.result.x))
    error = np.sqrt(error2 + ref.levels[-1].estimate ** 2)
    assert 0.5 <= last.estimate / error <= 1.5


def test_adaptive_coulomb_levels_end_within_their_balance_of_the_discrete_solution():
    """Each level runs the fixed point with the balanced stop inside; the last level's u is within gamma eta of
    the same mesh's Coulomb solution solved tightly (the fixed point's own error is estimated, not bounded)."""
    out = solve_adaptive(load_scene("ex1_coulomb", h=0.2, order=2), 3e-2)
    assert out.reached and all(lvl.status == "converged" and lvl.tresca_solves >= 1 for lvl in out.levels)
    assert out.levels[0].tresca_solves > min(lvl.tresca_solves for lvl in out.levels[1:])   # warm: fewer
    ops, last = out.model, out.levels[-1]
    tight = solve_scene(ops, "sadmm", 1e3, mode="condensed", stop=ResidualTolerance(1e-11, 1e-11), coulomb_tol=1e-9,
                        coulomb_max_outer=60)
    assert tight.converged
    e = out.result.x - tight.u
    assert np.sqrt(e @ (ops.K @ e)) <= GAMMA * last.estimate


def test_coulomb_fixed_point_starts_from_s0_and_ends_settled():
    from admmkit.problems.contact.solvers.coulomb import coulomb_fixed_point
    problem = contact_problem(assemble(load_scene("ex1_coulomb", h=1 / 5)), mode="condensed")
    seen = []

    def run(warm):
        seen.append(problem.friction.s.copy())
        order, policy = method("sadmm")
        return admmkit.solve(problem, rho=1e3, policy=policy, order=order, warm_start=warm, max_iter=5000)

    _, report = coulomb_fixed_point(problem, run, 0.3, s0=np.full(problem.ops.n_c, 0.5),
                                    settled=lambda previous, last: True)
    assert np.all(seen[0] == 0.5) and report.outer_iterations == 2 and report.settled and report.converged
    assert "settled" in report.summary()


def test_cli_target_error_with_friction(capsys):
    assert main(["solve", "contact", "--scene", "ex1_tresca", "--target-error", "3e-2"]) == 0
    text = capsys.readouterr().out
    assert "P2, target 0.03" in text and ", tresca" in text and "status       target_reached" in text
    assert main(["solve", "contact", "--scene", "ex1_coulomb", "--target-error", "5e-2"]) == 0
    text = capsys.readouterr().out
    assert "Tresca solves)" in text and "last Tresca problem" in text and "status       target_reached" in text
    assert main(["solve", "contact", "--scene", "ex1_tresca", "--target-error", "0.1", "--estimator", "residual"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--target-error: estimator 'residual'" in err and "use 'zz'" in err and len(err.splitlines()) == 1
