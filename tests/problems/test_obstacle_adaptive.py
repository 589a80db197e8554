"""Adaptive meshes for the obstacle (#24): Dörfler marking, the loop, its truthful statuses, the command line."""
import json
import math
import re

import numpy as np
import pytest

from admmkit.cli import main
from admmkit.problems.obstacle import radial
from admmkit.fe.adaptive import dorfler_mark
from admmkit.problems.obstacle.adaptive import WARM_RHO, solve_adaptive


def test_dorfler_marks_the_smallest_set_carrying_theta():
    eta = np.sqrt(np.array([1.0, 4.0, 2.0, 3.0]))          # eta^2 = 1, 4, 2, 3 (total 10)
    assert dorfler_mark(eta, 0.4).tolist() == [False, True, False, False]      # 4 >= 4
    assert dorfler_mark(eta, 0.5).tolist() == [False, True, False, True]       # 4 + 3 >= 5
    assert dorfler_mark(eta, 0.99).all()


@pytest.fixture(scope="module")
def adapted():
    return solve_adaptive(radial(h=1 / 4), 5e-2)


def test_the_loop_reaches_the_target_with_warm_started_levels(adapted):
    out = adapted
    assert out.reached and out.status == "target_reached"
    rel = [lvl.relative_estimate for lvl in out.levels]
    assert rel[-1] <= 5e-2 < min(rel[:-1]) and all(b < a for a, b in zip(rel, rel[1:]))
    assert all(lvl.status == "converged" for lvl in out.levels)
    assert max(lvl.iterations for lvl in out.levels[1:]) <= 40 < 2 * out.levels[0].iterations + 60
    last = out.levels[-1]
    assert last.estimate == pytest.approx(last.errors["H1_semi"], rel=0.3)    # against the exact solution


def test_adapted_meshes_beat_uniform_ones_for_the_same_unknowns(adapted):
    """Uniform h = 1/16 (3969 unknowns) has H1-seminorm error 6.82e-2, and it falls like n^(-1/2)."""
    for lvl in adapted.levels[2:]:
        uniform = 6.82e-2 * np.sqrt(3969 / lvl.unknowns)
        assert lvl.errors["H1_semi"] <= 1.05 * uniform, (lvl.unknowns, lvl.errors["H1_semi"], uniform)


def test_caps_say_the_target_was_not_reached():
    out = solve_adaptive(radial(h=1 / 4), 1e-3, max_levels=2)
    assert out.status == "level_cap" and not out.reached and len(out.levels) == 2
    assert "not reached" in out.message
    out = solve_adaptive(radial(h=1 / 4), 1e-3, max_unknowns=1000)
    assert out.status == "unknowns_cap" and not out.reached and "not reached" in out.message
    assert out.levels[-1].unknowns <= 1000


@pytest.mark.parametrize("kwargs, match", [({"target": 0.0}, "target = 0.0 is outside the accepted range (0, 1)"),
                                           ({"target": 1.0}, "target = 1.0"),
                                           ({"target": 0.1, "theta": 1.0}, "theta = 1.0"),
                                           ({"target": 0.1, "max_levels": 0}, "max_levels = 0"),
                                           ({"target": 0.1, "gamma": 2.0}, "gamma = 2.0"),
                                           ({"target": 0.1, "warm_rho": (1.0, 0.5)}, "warm_rho = (1.0, 0.5)"),
                                           ({"target": 0.1, "warm_rho": (0.0, 1.0)}, "0 < lo <= hi finite"),
                                           ({"target": 0.1, "warm_rho": "carried"}, "warm_rho = 'carried'"),
                                           ({"target": 0.1, "warm_rho": (1.0,)}, "warm_rho = (1.0,)"),
                                           ({"target": 0.1, "warm_rho": (math.nan, 1.0)}, "warm_rho = (nan, 1.0)")])
def test_bad_input_is_named(kwargs, match):
    with pytest.raises(ValueError, match=re.escape(match)):
        solve_adaptive(radial(h=1 / 4), **kwargs)


def test_cli_target_error(tmp_path, capsys, level_vtus):
    out = tmp_path / "levels.json"
    assert main(["solve", "obstacle", "--h", "1/4", "--target-error", "0.1", "--json", str(out),
                 "--plot", str(tmp_path / "mesh.png"), "--vtk", str(tmp_path / "lv")]) == 0
    text = capsys.readouterr().out
    assert "status       target_reached" in text
    body = json.loads(out.read_text())
    assert body["status"] == "target_reached" and body["levels"][-1]["relative_estimate"] <= 0.1
    assert (tmp_path / "mesh.png").stat().st_size > 1000
    level_vtus(tmp_path, "lv", body["levels"], {"u", "psi", "contact"})   # one VTU per level, with its indicators
    assert main(["solve", "obstacle", "--h", "1/4", "--target-error", "1e-3", "--max-levels", "2"]) == 1
    assert "level_cap" in capsys.readouterr().out
    assert main(["solve", "obstacle", "--target-error", "1.5"]) == 2
    assert "--target-error = 1.5 is outside the accepted range (0, 1)" in capsys.readouterr().err


def test_accelerated_levels_reach_the_target_with_fewer_iterations():
    """acceleration="fast" runs every level with restarted fast ADMM (the default in P2, "auto"; plain ADMM in
    P1); both reach the target, the accelerated run with fewer warm iterations in P2; an unknown name is refused
    before any mesh."""
    fast = solve_adaptive(radial(h=1 / 2), 2e-3, fe_order=2)
    plain = solve_adaptive(radial(h=1 / 2), 2e-3, fe_order=2, acceleration=None)
    assert solve_adaptive(radial(h=1 / 2), 5e-2).result.acceleration is None          # P1: plain by default
    aadmm = solve_adaptive(radial(h=1 / 2), 2e-2, fe_order=2, policy="aadmm")      # "auto" with another rule:
    assert aadmm.reached and aadmm.result.acceleration is None                          # plain
    assert fast.result.acceleration is not None and plain.result.acceleration is None
    assert fast.reached and plain.reached
    assert fast.levels[0].relative_estimate == pytest.approx(plain.levels[0].relative_estimate, rel=0.3)
    assert sum(lvl.iterations for lvl in fast.levels[1:]) < sum(lvl.iterations for lvl in plain.levels[1:])
    with pytest.raises(ValueError, match="acceleration must be None, 'anderson', 'fast'"):
        solve_adaptive(radial(h=1 / 4), 5e-2, acceleration="nesterov")
    with pytest.raises(ValueError, match="'auto'"):                # the error names every accepted value
        solve_adaptive(radial(h=1 / 4), 5e-2, acceleration=float("nan"))


def test_every_p1_warm_start_is_within_the_last_levels_error_of_the_new_solution(monkeypatch):
    """NGSolve's prolongation carries the last P1 level's solution to the refined mesh: the start of every warm
    level is below the last level's estimate away from the level's solution in the energy norm (measured
    0.66-0.78 of it), as the P2 levels' check in test_obstacle_p2.py."""
    import math
    import admmkit.problems.obstacle.adaptive as adaptive
    plain, starts, estimates = adaptive.solve, [], []

    def solve(problem, **kw):
        res = plain(problem, **kw)
        if "x0" in kw:
            d = kw["x0"] - res.z
            starts.append(math.sqrt(d @ (problem.K @ d)))
        return res
    monkeypatch.setattr(adaptive, "solve", solve)
    solve_adaptive(radial(h=1 / 2), 2e-2, log=lambda level, out: estimates.append(level.estimate))
    assert len(starts) >= 5 and len(starts) == len(estimates) - 1
    assert all(error <= eta for error, eta in zip(starts, estimates))


def test_p1_prolongation_on_a_refined_copy_is_ngsolves_in_place_prolongation():
    """Five refinements with closure (neighbours bisected for conformity): the copy's parent-edge means equal
    NGSolve's in-place GridFunction.Update to round-off."""
    import ngsolve as ng
    from admmkit.problems.fe import p1_prolongation, refine_marked, refined_copy, vertex_parents
    from admmkit.problems.obstacle.problem import build_mesh
    in_place = build_mesh(radial(h=1))
    copy = ng.Mesh(in_place.ngmesh.Copy())
    gf = ng.GridFunction(ng.H1(in_place, order=1))
    gf.Set(ng.sin(3 * ng.x) * ng.cos(2 * ng.y) + ng.x * ng.y)
    values, rng = gf.vec.FV().NumPy().copy(), np.random.default_rng(1)
    for _ in range(5):
        marked = rng.random(copy.ne) < 0.2
        refine_marked(in_place, marked)
        gf.space.Update()
        gf.Update()
        refined = refined_copy(copy, marked)
        parents = vertex_parents(refined, copy.nv)
        assert (parents < np.arange(copy.nv, refined.nv)[:, None]).all()      # a parent comes before its child
        copy, values = refined, p1_prolongation(parents, values)
        assert np.allclose(np.array(copy.ngmesh.Coordinates()), np.array(in_place.ngmesh.Coordinates()))
        assert np.abs(values - gf.vec.FV().NumPy()).max() < 1e-14


def test_p1_prolongation_sets_a_new_parent_before_its_children():
    """Where a parent is itself new (not seen in NGSolve's 2D bisection, but allowed), values follow in order."""
    from admmkit.problems.fe import p1_prolongation
    coarse = np.array([0.0, 4.0])
    fine = p1_prolongation(np.array([[0, 1], [0, 2], [2, 1]]), coarse)     # midpoint 2, then the quarter points
    assert np.array_equal(fine, [0.0, 4.0, 2.0, 1.0, 3.0])
    assert np.array_equal(p1_prolongation(np.array([[0, 1]]), coarse), [0.0, 4.0, 2.0])


def test_full_multiplier_puts_lam_on_the_free_nodes_and_zero_on_the_boundary():
    from admmkit.problems.obstacle.discrete import make_problem
    for order in (1, 2):
        p = make_problem(radial(h=1), fe_order=order)
        lam = np.arange(1.0, p.n + 1)
        full = p.full_multiplier(lam)
        assert full.shape == (p.fes.ndof,) and np.array_equal(full[p.free], lam)
        assert np.count_nonzero(full) == p.n


def test_rho_scale_is_the_nodal_stiffness_over_the_nodal_mass():
    """On the uniform right-triangle mesh every free node has K_ii = 4 and lumped mass h^2: the scale is 4 / h^2."""
    from admmkit.problems.obstacle import ObstacleProblem
    for h in (1 / 4, 1 / 8):
        assert ObstacleProblem(radial(h=h)).rho_scale() == pytest.approx(4 / h ** 2, rel=1e-12)


def _warm_rhos(monkeypatch, **kwargs):
    """(rho a warm level started from, that level's rho_scale, the last level's final rho) for every warm level."""
    import admmkit.problems.obstacle.adaptive as adaptive
    plain, seen, last = adaptive.solve, [], []

    def solve(problem, **kw):
        if "x0" in kw:
            seen.append((kw["rho"], problem.rho_scale(), last[-1]))
        res = plain(problem, **kw)
        last.append(res.rho)
        return res
    monkeypatch.setattr(adaptive, "solve", solve)
    assert solve_adaptive(radial(h=1 / 2), 3e-2, **kwargs).reached
    assert len(seen) >= 4
    return seen


def test_a_warm_level_starts_from_the_last_rho_clamped_to_the_window_of_its_scale(monkeypatch):
    """warm_rho=(lo, hi): every warm level starts from the last level's rho clamped to [lo, hi] x rho_scale();
    None: from the last level's rho as it is; the default in P1 keeps it within WARM_RHO[1] = (0.1, 1) x the scale."""
    for start, scale, last in _warm_rhos(monkeypatch, warm_rho=(0.2, 0.2)):
        assert start == pytest.approx(0.2 * scale, rel=1e-12)
    assert all(start == last for start, _, last in _warm_rhos(monkeypatch, warm_rho=None))
    lo, hi = WARM_RHO[1]
    assert (lo, hi) == (0.1, 1.0)
    for start, scale, last in _warm_rhos(monkeypatch):
        assert lo * scale * (1 - 1e-12) <= start <= hi * scale * (1 + 1e-12)
        assert start == last or not lo * scale <= last <= hi * scale      # moved only where it left the window
