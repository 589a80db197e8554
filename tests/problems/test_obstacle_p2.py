"""P2 obstacle elements in nodal values (#24): the transform, the mass bound, the discrete solution against cvxpy,
convergence on the radial scene's exact solution, the ZZ estimator, adaptive levels and their warm start."""
import math

import ngsolve as ng
import numpy as np
import pytest
import scipy.linalg as la

from admmkit.fe.balanced_stop import GAMMA
import admmkit
from admmkit.cli import main
from admmkit.problems.obstacle import ObstacleProblem, ObstacleProblemP2, make_problem, radial, solve_with_cvxpy
from admmkit.problems.obstacle.adaptive import solve_adaptive
from admmkit.problems.obstacle.estimate import BalancedStop, EnergyGap, estimator_of, zz_estimate
from admmkit.problems.obstacle.p2 import MASS_RATIO, prolongation
from admmkit.problems.fe import refine_marked, refined_copy
from admmkit.problems.obstacle.problem import build_mesh


@pytest.fixture(scope="module")
def refined():
    """A P2 problem on a locally refined mesh (edges that lost their dofs to the refinement included)."""
    mesh = build_mesh(radial(h=1 / 2))
    mesh.SetRefinementFlags([i % 3 == 0 for i in range(mesh.ne)])
    mesh.Refine()
    return ObstacleProblemP2(radial(h=1 / 2), mesh=mesh)


def test_nodes_are_the_vertices_and_the_edge_midpoints(refined):
    p = refined
    mesh = p.mesh
    nv = mesh.nv
    expected = {}
    for edge in mesh.edges:
        dofs = p.fes.GetDofNrs(edge)
        if dofs:
            a, b = (v.nr for v in edge.vertices)
            expected[dofs[0]] = p.nodes[[a, b]].mean(axis=0)
    assert len(expected) == p.fes.ndof - nv
    for dof, point in expected.items():
        assert np.allclose(p.nodes[dof], point, atol=1e-14)


def test_nodal_values_reproduce_a_quadratic(refined):
    p = refined
    q = lambda x, y: 0.3 * x * x - x * y + 0.7 * y * y + x - 2.0          # noqa: E731
    values = q(*p.nodes.T)
    gf = ng.GridFunction(p.fes)
    gf.vec.FV().NumPy()[:] = p._T_inverse @ values
    error = ng.Integrate((gf - q(ng.x, ng.y)) ** 2, p.mesh)
    assert math.sqrt(error) < 1e-12
    assert np.allclose(p.T @ (p._T_inverse @ values), values)


def test_the_mass_bound_holds_and_is_sharp():
    """The consistent P2 mass >= MASS_RATIO x the HRZ-lumped one (the EnergyGap's c), with equality on some vector."""
    p = ObstacleProblemP2(radial(h=1))
    u, v = p.fes.TnT()
    from admmkit.problems.obstacle.problem import csr_of
    M = (p._T_inverse.T @ csr_of(ng.BilinearForm(u * v * ng.dx).Assemble().mat) @ p._T_inverse)
    M = M.toarray()[np.ix_(p.free, p.free)]
    low = la.eigh(M, np.diag(p.m), eigvals_only=True).min()
    assert MASS_RATIO == pytest.approx(0.2485, abs=1e-4)
    assert low >= MASS_RATIO * (1 - 1e-10)


def test_p2_solves_the_same_discrete_problem_as_cvxpy():
    p = make_problem(radial(h=1 / 2), fe_order=2)
    u_ref, lam_ref = solve_with_cvxpy(p, tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12)
    r = admmkit.solve(p, rho=10.0, policy="summable", order="zx", stop=admmkit.RelativeChange(1e-12), max_iter=20000)
    assert np.abs(r.z - u_ref).max() < 1e-6
    assert np.abs(p.m * (r.lam - lam_ref)).max() < 1e-6 * max(1.0, np.abs(p.m * lam_ref).max())


def test_the_algebraic_bound_is_guaranteed_in_p2():
    p = make_problem(radial(h=1 / 2), fe_order=2)
    u_ref, _ = solve_with_cvxpy(p, tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12)
    gap = EnergyGap(p)
    assert gap.solver == "direct"
    for its in (5, 20, 60):
        r = admmkit.solve(p, rho=10.0, policy="summable", order="zx", stop=admmkit.RelativeChange(1e-14),
                          max_iter=its)
        d = r.z - u_ref
        assert gap.bound(r.z, r.lam) >= math.sqrt(d @ (p.K @ d)) * (1 - 1e-9)


def test_the_active_set_multiplier_makes_the_p2_bound_exact_once_the_touched_set_is_right():
    """With z's touched set the solution's contact set, the active-set candidate is D's maximiser, and the bound
    is sqrt(2 (J(z) - J(u_h))) to round-off; on ADMM iterates it stays guaranteed and never looser than
    without it (``enough`` set so the candidate is tried)."""
    import scipy.sparse as sp

    from admmkit.benchmarks.fixtures.pdas import pdas

    p = make_problem(radial(h=1 / 2), fe_order=2)
    exact = pdas(p.K, p.F, -p.sign * sp.identity(p.n, format="csr"), -p.sign * p.psi, method="bounds")
    assert exact.status == "converged"
    u = exact.u
    with_a, without = EnergyGap(p, active_set=True), EnergyGap(p)
    assert with_a.active_set and not without.active_set
    z = u + 0.2 * (u - p.psi)                     # feasible, on the obstacle exactly where u is
    J = lambda v: 0.5 * v @ (p.K @ v) - p.F @ v   # noqa: E731
    d = z - u
    b0 = without.bound(z, np.zeros(p.n), enough=0.0)
    b = with_a.bound(z, np.zeros(p.n), enough=0.5 * b0)
    assert b == pytest.approx(math.sqrt(2 * (J(z) - J(u))), rel=1e-6)
    assert math.sqrt(d @ (p.K @ d)) <= b <= b0
    for its in (3, 10, 30):
        r = admmkit.solve(p, rho=10.0, policy="summable", order="zx", stop=admmkit.RelativeChange(1e-14),
                          max_iter=its)
        d = r.z - u
        enough = 0.5 * without.bound(r.z, r.lam, enough=0.0)
        b = with_a.bound(r.z, r.lam, enough=enough)
        assert math.sqrt(d @ (p.K @ d)) * (1 - 1e-9) <= b <= without.bound(r.z, r.lam, enough=enough)
    with pytest.raises(ValueError, match="active_set = 'yes' is outside the accepted range: True or False"):
        EnergyGap(p, active_set="yes")


def test_p2_converges_faster_than_p1_and_zz_follows_it():
    """Uniform meshes of the radial scene: the H1 error falls like h^1.4 or faster in P2 (h^1 in P1; the exact
    solution is C^1,1), with as many unknowns (P2 on N x N squares, P1 on 2N x 2N) P2's error is below P1's
    and the gap widens (1.6x at N = 8, 2.2x at N = 16), and ZZ's effectivity stays in [0.5, 3]."""
    errors = {}
    for N in (8, 16, 32):
        for k in (1, 2):
            p = make_problem(radial(h=4 / N), fe_order=k)
            r = admmkit.solve(p, rho=10.0, policy="summable", order="zx", stop=admmkit.RelativeChange(1e-10),
                              max_iter=20000)
            e = p.errors(r.z)["H1_semi"]
            errors[N, k] = e
            if k == 2:
                assert 0.5 <= zz_estimate(p, r.z) / e <= 3.0
    assert math.log2(errors[8, 2] / errors[32, 2]) / 2 >= 1.4
    assert errors[8, 2] < errors[16, 1] / 1.5 and errors[16, 2] < errors[32, 1] / 2


def test_the_residual_estimator_is_refused_in_p2():
    p = make_problem(radial(h=1), fe_order=2)
    with pytest.raises(ValueError, match="written for P1"):
        estimator_of(p, "residual")
    with pytest.raises(ValueError, match="written for P1"):
        solve_adaptive(radial(h=1), 0.1, fe_order=2, estimator="residual")
    with pytest.raises(ValueError, match="fe_order = 3"):
        make_problem(radial(h=1), fe_order=3)


def test_prolongation_is_exact_on_nested_meshes():
    """Three refinements in a row: from the second on, NGSolve numbers a mesh copy's edges apart from the
    refined mesh's, which once scrambled the warm start's edge values."""
    scene = radial(h=1)
    mesh = build_mesh(scene)
    q = lambda x, y: x * x - 0.5 * x * y + 0.25       # noqa: E731
    for level in range(3):
        p = ObstacleProblemP2(scene, mesh=mesh)
        u = q(*p.nodes[p.free].T)
        p.u_D[:] = q(*p.nodes.T)                      # the boundary nodes too: the field is q everywhere
        at = prolongation(p, u, np.zeros(p.n))
        mesh = refined_copy(mesh, [i % 2 == level % 2 for i in range(mesh.ne)])
        new = ObstacleProblemP2(scene, mesh=mesh)
        assert np.abs(at(new)["x0"] - q(*new.nodes.T)).max() < 1e-12, level


def test_refined_copy_leaves_the_mesh_and_refines_as_in_place():
    mesh = build_mesh(radial(h=1))
    refine_marked(mesh, [i % 3 == 0 for i in range(mesh.ne)])
    marked = [i % 2 == 0 for i in range(mesh.ne)]
    ne, copy = mesh.ne, refined_copy(mesh, marked)
    assert mesh.ne == ne and copy.ne > ne
    refine_marked(mesh, marked)
    assert np.array_equal(np.array(mesh.ngmesh.Coordinates()), np.array(copy.ngmesh.Coordinates()))
    for bad in ([True] * 3, [float("nan")] * mesh.ne, np.ones((mesh.ne, 2), dtype=bool)):
        with pytest.raises(ValueError, match="marked must hold one boolean per element"):
            refined_copy(mesh, bad)


def test_adaptive_p2_beats_adaptive_p1_and_a_warm_level_ends_where_a_cold_one_does():
    p1 = solve_adaptive(radial(h=1), 2e-2)
    p2 = solve_adaptive(radial(h=1), 2e-2, fe_order=2)
    assert p1.reached and p2.reached
    assert p2.levels[-1].unknowns * 4 < p1.levels[-1].unknowns
    last = p2.levels[-1]
    assert 0.5 <= last.estimate / last.errors["H1_semi"] <= 3.0
    model, warm = p2.model, p2.result
    cold = admmkit.solve(model, rho=1.0, policy="summable", order="zx", stop=BalancedStop(model, GAMMA),
                         max_iter=10_000)
    assert cold.status.value == "converged" and warm.status.value == "converged"
    d = warm.z - cold.z       # both within gamma x eta of u_h in the energy norm, so within 2 gamma eta of each other
    assert math.sqrt(d @ (model.K @ d)) <= 2 * GAMMA * last.estimate * 1.001


def test_every_warm_start_is_within_the_last_levels_error_of_the_new_solution():
    """The prolongated start of every P2 level is about as far from the level's solution as the last level's
    discretisation error (the meshes are nested, so the start is the last level's solution itself): below
    twice the last estimate in the energy norm on every level.  With the scrambled edge values of the
    mesh-copy bug it was 30 times it from the third level on."""
    levels = []
    solve_adaptive(radial(h=1 / 2), 3e-3, fe_order=2,
                   log=lambda level, out: levels.append((out.model, out.result.z, out.result.lam, level.estimate)))
    assert len(levels) >= 5
    for (old, z, lam, eta), (new, z_new, _, _) in zip(levels, levels[1:]):
        d = prolongation(old, z, lam)(new)["x0"][new.free] - z_new
        assert math.sqrt(d @ (new.K @ d)) <= 2 * eta, new.n


def test_cli_reaches_the_issue_target_in_p2(capsys, tmp_path):
    out = tmp_path / "levels.json"
    assert main(["solve", "obstacle", "--scene", "radial", "--target-error", "5e-3", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "P2 (--fe-order 1 for P1)" in text and "from h = 0.8, P2" in text and "target_reached" in text
    assert main(["solve", "obstacle", "--scene", "radial", "--fe-order", "2", "--h", "1/8"]) == 0
    assert "P2, " in capsys.readouterr().out
    assert isinstance(make_problem(radial(h=1)), ObstacleProblem) and make_problem(radial(h=1)).order == 1
