"""Adaptive meshes for frictionless 3D contact (#24): the loop on the 3D Example 2, its data, its gain, the CLI."""
import json

import numpy as np
import pytest

from admmkit.fe.balanced_stop import GAMMA
import admmkit
from admmkit.cli import main
from admmkit.problems.contact.model.assembly3d import assemble3d
from admmkit.problems.contact.model.scene3d import example2_3d
from admmkit.problems.contact.solvers.adaptive import solve_adaptive
from admmkit.problems.contact.solvers.adaptive3d import assemble3d_on, surface_interpolate
from admmkit.problems.contact.solvers.estimate import BalancedStop, zz_estimate
from admmkit.problems.contact.solvers.methods import method, solve_scene
from admmkit.problems.contact.solvers.problem import contact_problem

TARGET = 0.25


@pytest.fixture(scope="module")
def adapted():
    """The 3D Example 2 from h = 1/4 to a relative estimate of 0.25, and a cold start on every level's mesh."""
    cold = []

    def log(level, out):
        problem = contact_problem(out.model, mode="condensed")
        order, policy = method("sadmm")
        res = admmkit.solve(problem, rho=1e3, policy=policy, order=order, stop=BalancedStop(problem, GAMMA),
                            max_iter=20_000)
        cold.append(res.iterations)
    return solve_adaptive(example2_3d(h=1 / 4), TARGET, log=log), cold


def test_the_loop_reaches_the_target_with_fewer_unknowns_than_a_uniform_mesh(adapted):
    """Reached in a few levels, every level converged with its algebraic bound below GAMMA x its estimate, the
    estimate decreasing each level; a uniform mesh with more unknowns than the last level (h = 1/10, 10,890) is
    still far from the target by the same estimator (the error sits at the clamped edge and the contact zone)."""
    out, _ = adapted
    assert out.reached and out.status == "target_reached" and 2 <= len(out.levels) <= 4
    assert all(lvl.status == "converged" for lvl in out.levels)
    assert all(lvl.algebraic_bound <= GAMMA * lvl.estimate for lvl in out.levels)
    rel = [lvl.relative_estimate for lvl in out.levels]
    assert rel[-1] <= TARGET < min(rel[:-1]) and all(b < a for a, b in zip(rel, rel[1:]))
    assert out.model.mesh.dim == 3 and out.indicators.shape == (out.levels[-1].cells,)
    uniform = assemble3d(example2_3d(h=1 / 10))
    sol = solve_scene(uniform, "sadmm", 1e3, mode="condensed", balance=0.1)
    u = sol.result.x
    uniform_rel = zz_estimate(uniform, u) / np.sqrt(u @ (uniform.K @ u))
    assert out.levels[-1].unknowns < uniform.n_free and uniform_rel > 1.5 * TARGET


def test_warm_starts_cost_about_what_cold_starts_cost(adapted):
    """Measured: the warm start saves little here (the first mesh's contact zone, 6 active nodes of 60, moves as
    the mesh resolves it; SADMM needs 14-16 iterations from a cold start anyway), and costs at most two iterations
    more than a cold start on the same mesh (gamma 0.3, the predicted test schedule: 14, 17, 12 warm against
    14, 16, 16 cold; gamma 0.1 tested every 2 iterations gave 20, 22, 26 against 20, 22, 24)."""
    out, cold = adapted
    warm = [lvl.iterations for lvl in out.levels]
    assert warm[0] == cold[0] <= 24
    assert all(w <= c + 2 for w, c in zip(warm[1:], cold[1:]))


def test_refinement_carries_the_scene_data(adapted):
    """On the last adapted mesh: all six faces still named, the traction's total force (0, 0, -2) on the front
    face, the gap the scene's at every contact node, contact nodes on z = 0 only, the same operators as the
    structured assembly on an unrefined mesh."""
    out, _ = adapted
    ops, scene = out.model, example2_3d(h=1 / 4)
    assert set(ops.mesh.GetBoundaries()) == {"back", "front", "left", "right", "bottom", "top"}
    nv = ops.mesh.nv
    load = ops.full_vector(ops.f)
    assert np.allclose([load[:nv].sum(), load[nv:2 * nv].sum(), load[2 * nv:].sum()], [0, 0, -2])
    assert np.allclose(ops.xc[:, 2], 0) and np.allclose(ops.g, [scene.gap_at(x, y) for x, y, _ in ops.xc])
    assert ops.mc.sum() < scene.Lx * scene.Ly and ops.n_c == out.levels[-1].contact_nodes
    ref = assemble3d(scene)
    mine = assemble3d_on(scene, ref.mesh)
    assert abs(ref.K - mine.K).max() < 1e-9 * abs(ref.K).max() and np.allclose(ref.f, mine.f)
    assert (ref.B != mine.B).nnz == 0 and np.allclose(ref.mc, mine.mc) and np.allclose(ref.xc, mine.xc)


def test_surface_interpolation():
    """Linear data reproduced inside the old nodes' hull; the nearest old value outside it."""
    rng = np.random.default_rng(0)
    old = np.column_stack([rng.uniform(0.1, 1, 40), rng.uniform(0, 1, 40), np.zeros(40)])
    old = np.vstack([old, [[0.1, 0, 0], [1, 0, 0], [1, 1, 0], [0.1, 1, 0]]])
    linear = lambda p: 2 * p[:, 0] - 3 * p[:, 1] + 1  # noqa: E731
    new = np.array([[0.5, 0.5, 0.0], [0.9, 0.1, 0.0], [0.0, 0.5, 0.0]])
    got = surface_interpolate(old, linear(old), new)
    assert np.allclose(got[:2], linear(new[:2]))
    assert got[2] == linear(old)[np.argmin(np.linalg.norm(old - new[2], axis=1))]


def test_cli_target_error_3d(tmp_path, capsys):
    out = tmp_path / "levels.json"
    args = ["solve", "contact", "--scene", "block3d_coulomb", "--tangential", "frictionless", "--h", "1/4",
            "--fe-order", "1"]
    assert main(args + ["--target-error", "0.3", "--json", str(out), "--vtk", str(tmp_path / "lv.vtu")]) == 0
    assert "status       target_reached" in capsys.readouterr().out
    body = json.loads(out.read_text())
    assert body["status"] == "target_reached" and body["levels"][-1]["relative_estimate"] <= 0.3
    assert len(list(tmp_path.glob("lv_level*.vtu"))) == len(body["levels"]) >= 2
    assert main(args + ["--target-error", "0.1", "--max-levels", "1"]) == 1
    assert "level_cap" in capsys.readouterr().out
    assert main(["solve", "contact", "--scene", "block3d_coulomb", "--h", "1/4", "--fe-order", "1",
                 "--target-error", "0.3"]) == 0
    assert "coulomb" in (text := capsys.readouterr().out) and "status       target_reached" in text   # 3D Coulomb
    assert main(args + ["--target-error", "0.3", "--plot", str(tmp_path / "m.png")]) == 2
    assert "2D scenes only" in capsys.readouterr().err


def test_cli_target_error_3d_defaults_to_p2_from_two_cells_across(tmp_path, capsys):
    """Without --fe-order and --h, 3D --target-error takes P2 from h = min(Lx, Ly, Lz) / 2 (as 2D takes P2 from
    min(L, H) / 5) and says so; --fe-order and --h given are kept."""
    out = tmp_path / "levels.json"
    args = ["solve", "contact", "--scene", "block3d_coulomb", "--tangential", "frictionless", "--target-error",
            "0.3", "--max-levels", "1", "--json", str(out)]
    main(args)
    text = capsys.readouterr().out
    body = json.loads(out.read_text())
    assert body["order"] == 2 and body["h0"] == 0.5 and body["levels"][0]["cells"] == 6 * 6 * 2 * 2
    assert "the defaults of --target-error in 3D" in text and "min(Lx, Ly, Lz) / 2 = 0.5" in text
    main(args + ["--fe-order", "1", "--h", "1/4"])
    body = json.loads(out.read_text())
    assert body["order"] == 1 and body["h0"] == 0.25
    assert "defaults of --target-error" not in capsys.readouterr().out


def test_condensed_mode_holds_dense_factors_within_a_memory_budget():
    """A small boundary keeps 32 factors of M_c^-1 + rho C; a large one (a refined 3D Coulomb face) only those
    that fit DENSE_FACTORS_BYTES, at least 2."""
    from admmkit.problems.contact.solvers.problem import DENSE_FACTORS_BYTES, dense_factors_held
    assert dense_factors_held(80) == dense_factors_held(1448) == 32
    assert dense_factors_held(9000) == 2 and dense_factors_held(2048) == 16
    assert all(dense_factors_held(m) * 8 * m * m <= DENSE_FACTORS_BYTES for m in (1449, 2048, 4096, 5792))
    problem = contact_problem(assemble3d(example2_3d(h=1 / 2)), mode="condensed")
    assert problem.factors.max_cached == 32
