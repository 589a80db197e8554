"""The obstacle's Jacobi-CG x-step with rent-or-buy factorisation, its P1 mass without assembly, the bound's
inexact K-solves (#24: the adaptive levels' costs)."""
import numpy as np
import ngsolve as ng
import pytest
import scipy.sparse as sp

from admmkit import RelativeChange, solve
from admmkit.problems.fe import p1_mass, triangles
from admmkit.problems.obstacle import make_problem, radial, solve_with_cvxpy
from admmkit.problems.obstacle.estimate import EnergyGap
from admmkit.problems.obstacle.xstep import TOL, JacobiCG


@pytest.fixture(scope="module")
def radial16():
    return make_problem(radial(h=1 / 16))


def test_jacobi_cg_solves_the_x_step_and_factorises_only_where_cg_is_dear(radial16):
    p = radial16
    step = JacobiCG(p.K, p.F, p.m, price=50)
    rng = np.random.default_rng(0)
    z, lam = rng.standard_normal(p.n), rng.standard_normal(p.n)
    for rho in (1e4, 1.0):
        u = step(z, lam, rho, np.zeros(p.n))
        residual = (p.K + rho * sp.diags(p.m)) @ u - (p.F + p.m * (rho * z - lam))
        # solved for the correction u - z: CG's tolerance is relative to z's own residual F - K z - M lam
        assert np.linalg.norm(residual) <= 1.01 * TOL * np.linalg.norm(p.F - p.K @ z - p.m * lam)
    work = step.counters()
    # rho 1e4: K + rho M is nearly diagonal, CG within the price; rho 1: CG hits the price of 50, factorised
    assert work["solves"] == 2 and work["factorizations"] == 1 and work["factorizations_computed"] == 1
    again = step(z, lam, 1.0, np.zeros(p.n))                   # the bought factorisation serves the next solve
    assert step.counters()["cg_iterations"] == work["cg_iterations"] and np.allclose(again, u)


def test_jacobi_cg_resolves_a_correction_far_below_rho_m_z(radial16):
    """At large rho the x-step's correction x - z is tiny against rho M z; solved for the correction, CG resolves
    it (written for x, a tolerance relative to F + M (rho z - lam) left x where it started: the pyramid scene's
    runaway rho, docs/obstacle.md)."""
    p = radial16
    import scipy.sparse.linalg as sla
    rng = np.random.default_rng(1)
    lam = rng.standard_normal(p.n)
    z = sla.spsolve(p.K.tocsc(), p.F - p.m * lam)                # K z + M lam = F ...
    lam += 1e-3 * rng.standard_normal(p.n)                       # ... but for a residual far below rho M z
    rhs = p.F - p.K @ z - p.m * lam                              # z's residual, as the step computes it
    rho = 1e6 * p.rho_scale()
    assert np.linalg.norm(rhs) < 1e-10 * rho * np.linalg.norm(p.m * z)        # below the old form's tolerance
    u = JacobiCG(p.K, p.F, p.m)(z, lam, rho, z.copy())           # from x = z, as a stalled level would
    d = u - z                                                    # about 1e-12 of z: its rounding is 1e-4 of d
    assert np.linalg.norm((p.K + rho * sp.diags(p.m)) @ d - rhs) <= 1e-3 * np.linalg.norm(rhs)


def test_the_jacobi_backend_gives_the_direct_backends_solution(radial16):
    runs = {b: solve(make_problem(radial(h=1 / 16), backend=b), rho=1.0, policy="summable", order="zx",
                     stop=RelativeChange(1e-8), max_iter=5000) for b in ("superlu", "jacobi")}
    a, b = runs["jacobi"], runs["superlu"]
    assert a.status == b.status and abs(a.iterations - b.iterations) <= 2     # the same run, to CG's TOL
    assert np.max(np.abs(a.z - b.z)) <= 1e-6


def test_p1_mass_without_assembly_is_ngsolves():
    mesh = make_problem(radial(h=1 / 4)).mesh
    mesh.SetRefinementFlags([i % 3 == 0 for i in range(mesh.ne)])
    mesh.Refine()
    fes = ng.H1(mesh, order=1)
    u, v = fes.TnT()
    form = ng.BilinearForm(u * v * ng.dx).Assemble()          # kept alive while its CSR arrays are read
    vals, cols, rows = form.mat.CSR()
    M = sp.csr_matrix((np.array(vals), np.array(cols), np.array(rows)), shape=(fes.ndof, fes.ndof))
    nodes = np.array(mesh.ngmesh.Coordinates())[:, :2]
    lumped, apply = p1_mass(nodes, triangles(mesh))
    f = np.cos(nodes[:, 0]) * nodes[:, 1]
    assert np.allclose(apply(f), M @ f, rtol=0, atol=1e-14) and np.allclose(lumped, M.sum(axis=1).A1, atol=1e-14)


def test_the_bound_stays_guaranteed_with_a_loose_cg():
    """The correction e'M^{-1}e / c keeps (B) above the true algebraic error whatever CG's accuracy (one CG
    pass to 0.5, taken as it is with ``sharp`` = inf); loose, the bound is larger, tight it equals the factorised
    one, and the default (CG tightened until the correction is 1 % of the rest) is within 1 % of it."""
    problem = make_problem(radial(h=1 / 8))
    u_h, _ = solve_with_cvxpy(problem, tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12)
    res = solve(problem, rho=1.0, policy="summable", order="zx", stop=RelativeChange(1e-4), max_iter=5000)
    true = float(np.sqrt((res.z - u_h) @ (problem.K @ (res.z - u_h))))
    exact = EnergyGap(problem, solver="direct").bound(res.z, res.lam)
    tight = EnergyGap(problem, tol=1e-12).bound(res.z, res.lam)
    loose = EnergyGap(problem, tol=0.5, sharp=np.inf).bound(res.z, res.lam)
    default = EnergyGap(problem).bound(res.z, res.lam)
    assert true <= exact and tight == pytest.approx(exact, rel=1e-6)
    assert true <= loose and loose > 1.01 * tight
    assert exact <= default <= 1.01 * exact
    with pytest.raises(ValueError, match="solver"):
        EnergyGap(problem, solver="cholesky")
    with pytest.raises(ValueError, match="sharp = 0"):
        EnergyGap(problem, sharp=0)
