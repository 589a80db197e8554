"""admmkit.blocks.iterative: AMG-preconditioned CG x-steps, checked against sparse direct solves."""
import math

import ngsolve as ng
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from ngsolve.meshes import MakeStructured2DMesh, MakeStructured3DMesh

import admmkit
from admmkit import policies
from admmkit import RelativeChange
from admmkit.blocks.iterative import IterativeXSolver, PencilMatrix, SolutionSpace, node_blocks
from admmkit.problems.contact.solvers.iterative import rigid_body_modes
from admmkit.problems.contact import assemble, example1, example2, solve_scene
from admmkit.problems.contact.solvers.problem import contact_problem


def _elasticity(mesh, dirichlet=""):
    """P1 elasticity stiffness (E=1, nu=0.3) on a mesh, and its free dofs."""
    fes = ng.VectorH1(mesh, order=1, dirichlet=dirichlet)
    u, v = fes.TnT()
    eps = lambda w: ng.Sym(ng.Grad(w))  # noqa: E731
    a = ng.BilinearForm(fes)
    a += (2 * 0.4 * ng.InnerProduct(eps(u), eps(v)) + 0.6 * ng.Trace(ng.Grad(u)) * ng.Trace(ng.Grad(v))) * ng.dx
    a.Assemble()
    vals, cols, rows = a.mat.CSR()
    K = sp.csr_matrix((np.array(vals), np.array(cols), np.array(rows)), shape=(fes.ndof, fes.ndof))
    d = mesh.dim
    points = np.array(mesh.ngmesh.Coordinates())[:, :d]
    comp, node = np.divmod(np.arange(fes.ndof), mesh.nv)
    return K, points[node], comp, node, np.flatnonzero(np.array(fes.FreeDofs(), dtype=bool))


@pytest.mark.parametrize("dim", [2, 3])
def test_rigid_body_modes_are_the_null_space_of_unconstrained_elasticity(dim):
    mesh = MakeStructured2DMesh(quads=False, nx=4, ny=3) if dim == 2 else MakeStructured3DMesh(hexes=False, nx=2, ny=2, nz=2)
    K, points, comp, node, _ = _elasticity(mesh)
    R = rigid_body_modes(points, comp)
    assert R.shape == (K.shape[0], 3 if dim == 2 else 6)
    assert np.linalg.matrix_rank(R) == R.shape[1]
    assert np.abs(K @ R).max() <= 1e-12 * abs(K).max() * np.abs(R).max()
    blocks = node_blocks(node, comp, dim)
    assert blocks.shape == (mesh.nv, dim) and np.all(comp[blocks] == np.arange(dim))


def test_node_blocks_refuses_a_node_with_a_missing_component():
    node, comp = np.array([0, 0, 1]), np.array([0, 1, 1])
    assert node_blocks(node, comp, 2) is None


@pytest.mark.parametrize("blocksize", [1, 2])
def test_pencil_matrix_is_k_plus_rho_d_with_explicit_zeros_kept(blocksize):
    rng = np.random.default_rng(0)
    K = sp.random(30, 30, 0.2, random_state=1, format="csr")
    K = (K + K.T).tocsr()
    K.data[::5] = 0.0                                   # explicit zeros, as NGSolve matrices hold
    D = sp.diags(rng.uniform(0, 1, 30) * (rng.uniform(size=30) < 0.3)).tocsr()
    pencil = PencilMatrix(K, D, blocksize)
    for rho in (0.5, 1e4):
        assert abs(pencil.at(rho) - (K + rho * D)).max() == 0.0


def _poisson_pair(n=40):
    """K = 2D Laplacian + small mass (SPD), D = diagonal on one edge (a Robin-like penalty)."""
    lap = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n))
    K = (sp.kron(lap, sp.eye(n)) + sp.kron(sp.eye(n), lap) + 1e-3 * sp.eye(n * n)).tocsr()
    d = np.zeros(n * n)
    d[:n] = 1.0
    return K, sp.diags(d).tocsr()


@pytest.mark.parametrize("reuse", ["auto", "keep", "galerkin", "rebuild"])
def test_solves_match_the_direct_solver_across_rho_changes(reuse):
    K, D = _poisson_pair()
    solver = IterativeXSolver(K, D, reuse=reuse, tol=1e-10)
    rng = np.random.default_rng(1)
    rhos = [1.0, 1.0, 50.0, 50.0, 2500.0, 1.0]
    for rho in rhos:
        b = rng.normal(size=K.shape[0])
        x = solver.solve(rho, b)
        exact = spla.spsolve((K + rho * D).tocsc(), b)
        A = K + rho * D
        err = math.sqrt((x - exact) @ (A @ (x - exact)) / (exact @ (A @ exact)))
        assert err <= 1e-8
    counts = solver.counters()
    changes = 3  # 1 -> 50 -> 2500 -> 1
    assert counts["solves"] == len(rhos) and counts["cg_unconverged"] == 0
    if reuse == "rebuild":
        assert counts["amg_setups"] == 1 + changes and counts["amg_refreshes"] == 0
    elif reuse == "galerkin":
        assert counts["amg_setups"] == 1 and counts["amg_refreshes"] == changes
    elif reuse == "keep":
        assert counts["amg_setups"] == 1 and counts["amg_refreshes"] == 0


def test_galerkin_refresh_recomputes_every_coarse_operator():
    K, D = _poisson_pair(30)
    solver = IterativeXSolver(K, D, reuse="galerkin", tol=1e-8)
    solver.solve(1.0, np.ones(K.shape[0]))
    solver.solve(300.0, np.ones(K.shape[0]))
    levels = solver._amg.ml.levels
    assert len(levels) >= 2
    assert abs(levels[0].A - (K + 300.0 * D)).max() <= 1e-12
    for fine, coarse in zip(levels[:-1], levels[1:]):
        assert abs(coarse.A - fine.R @ fine.A @ fine.P).max() <= 1e-10 * abs(coarse.A).max()


def test_projection_reproduces_combinations_of_earlier_solutions():
    """Fischer's projection: a right-hand side in the span of earlier ones needs no CG iteration,
    for the same rho and (through Q'KQ + rho Q'DQ) for another rho."""
    K, D = _poisson_pair(20)
    rng = np.random.default_rng(2)
    space = SolutionSpace(K, D, 4)
    for rho in (3.0, 40.0):
        A = (K + rho * D).tocsc()
        x1, x2 = rng.normal(size=K.shape[0]), rng.normal(size=K.shape[0])
        space.m = 0
        space.add(x1)
        space.add(x2)
        guess = space.guess(rho, A @ (x1 - 2 * x2))
        assert np.allclose(guess, x1 - 2 * x2, rtol=0, atol=1e-9 * np.abs(x1).max())
    solver = IterativeXSolver(K, D, tol=1e-9)
    b1, b2 = rng.normal(size=K.shape[0]), rng.normal(size=K.shape[0])
    solver.solve(5.0, b1)
    solver.solve(5.0, b2)
    solver.solve(5.0, 0.3 * b1 + b2)
    assert solver.last["iterations"] == 0


def test_adaptive_inner_tolerance_follows_the_outer_change_and_a_summable_cap():
    K, D = _poisson_pair(20)
    solver = IterativeXSolver(K, D, kappa=0.1, tol0=0.1, tol_min=1e-12)
    assert solver.inner_tolerance() == pytest.approx(0.1)                  # no history: the cap
    b = np.ones(K.shape[0])
    tols = []
    for scale in (1.0, 1.5, 1.6, 1.61, 1.611):                            # outer change shrinking
        tols.append(solver.inner_tolerance())
        solver.solve(1.0, scale * b)
    for k, tol in enumerate(tols):
        assert tol <= 0.1 / (k + 1) ** 1.1 + 1e-15
    assert tols[-1] < 1e-3 and tols[-1] >= 1e-12
    # when the outer change is large, the cap decides; when it is small, kappa * change does
    delta = np.linalg.norm(solver._x_prev - solver._x_prev2) / np.linalg.norm(solver._x_prev)
    assert solver.inner_tolerance() == pytest.approx(max(1e-12, min(0.1 * delta, 0.1 / 6 ** 1.1)))


@pytest.mark.parametrize("bad", [dict(reuse="sometimes"), dict(tol=0.0), dict(tol="loose"), dict(projection=-1),
                                 dict(maxiter=0), dict(kappa=-1.0), dict(blocks=np.zeros((2, 2), dtype=int))])
def test_bad_options_are_refused(bad):
    K, D = _poisson_pair(4)
    with pytest.raises(ValueError):
        IterativeXSolver(K, D, **bad)


def test_bad_solve_input_is_refused():
    K, D = _poisson_pair(4)
    solver = IterativeXSolver(K, D)
    with pytest.raises(ValueError, match="rho"):
        solver.solve(0.0, np.ones(16))
    with pytest.raises(ValueError, match="rhs"):
        solver.solve(1.0, np.ones(15))
    with pytest.raises(ValueError, match="finite"):
        solver.solve(1.0, np.full(16, np.nan))


# ---------------------------------------------------------------- the contact and obstacle plug-ins
@pytest.fixture(scope="module")
def ex2_ops():
    return assemble(example2(h=1 / 20))


def test_contact_iterative_mode_matches_the_direct_solver(ex2_ops):
    """SADMM with AMG-CG x-steps ends at the direct solver's answer (both run to a tight stop)."""
    stop = RelativeChange(1e-9)
    full = solve_scene(ex2_ops, "sadmm", rho=1e3, mode="full", stop=stop)
    it = solve_scene(ex2_ops, "sadmm", rho=1e3, mode="iterative", stop=stop)
    assert full.result.converged and it.result.converged and it.mode == "iterative"
    K = ex2_ops.K
    energy = lambda u: math.sqrt(u @ (K @ u))  # noqa: E731
    assert energy(it.u - full.u) <= 1e-7 * energy(full.u)
    assert np.abs(it.pressure - full.pressure).max() <= 1e-5 * np.abs(full.pressure).max()
    assert it.result.counters["cg_unconverged"] == 0
    assert it.result.counters["amg_setups"] == 1          # rho changes reuse the hierarchy


def test_contact_iterative_mode_at_the_papers_tolerance_needs_the_same_iterations(ex2_ops):
    full = solve_scene(ex2_ops, "sadmm", rho=1e3, mode="full")
    it = solve_scene(ex2_ops, "sadmm", rho=1e3, mode="iterative")
    assert abs(it.result.iterations - full.result.iterations) <= 2
    kkt = it.result.kkt
    assert kkt["penetration"] <= 1e-3 * ex2_ops.g.max() and kkt["stationarity"] <= 1e-3
    # early x-steps are cheap: on average fewer than 4 CG iterations per x-step
    assert it.result.counters["cg_iterations"] <= 4 * it.result.iterations


def test_contact_iterative_mode_in_the_loop_uses_loose_early_tolerances():
    ops = assemble(example1(h=1 / 20))
    problem = contact_problem(ops, "iterative")
    tols = []
    admmkit.solve(problem, rho=1e3, policy=policies.Summable(tau=2, c_max=100), order="zx",
                  callback=lambda rec: tols.append(problem.solver.last["tol"]))
    assert tols[0] >= 1e-2 and tols[-1] <= 1e-5
    assert tols[-1] < tols[0] / 100


def test_obstacle_iterative_backend_matches_the_direct_one():
    from admmkit.problems.obstacle import make_problem
    from admmkit.problems.obstacle.scene import scene
    stop = RelativeChange(1e-10)
    results = {}
    for backend in ("superlu", "iterative"):
        problem = make_problem(scene("radial", h=1 / 16), backend=backend)
        results[backend] = admmkit.solve(problem, rho=1.0, policy="summable", order="zx", stop=stop, max_iter=5000)
    a, b = results["superlu"], results["iterative"]
    assert a.converged and b.converged
    assert np.abs(a.x - b.x).max() <= 1e-7 * np.abs(a.x).max()
    assert "cg_iterations" in b.counters


# ---------------------------------------------------------------- the array-built structured mesh
@pytest.mark.parametrize("L, H, h", [(2.0, 1.0, 1 / 10), (3.0, 1.0, 1 / 7), (1.0, 2.0, 0.5)])
def test_structured_rectangle_is_makestructured2dmesh(L, H, h):
    """admmkit.problems.contact.model.mesh.structured_rectangle (arrays) builds MakeStructured2DMesh's mesh exactly,
    so the assembled operators of the paper's examples are bit-for-bit unchanged."""
    from admmkit.problems.contact.model.mesh import grid_counts, structured_rectangle
    nx, ny = grid_counts(L, H, h)
    ref = MakeStructured2DMesh(quads=False, nx=nx, ny=ny, flip_triangles=True, mapping=lambda x, y: (L * x, H * y))
    new = structured_rectangle(L, H, h)
    assert np.array_equal(np.array(ref.ngmesh.Coordinates()), np.array(new.ngmesh.Coordinates()))
    for kind in ("Elements2D", "Elements1D"):
        a = [(e.index, [v.nr for v in e.vertices]) for e in getattr(ref.ngmesh, kind)()]
        b = [(e.index, [v.nr for v in e.vertices]) for e in getattr(new.ngmesh, kind)()]
        assert a == b
    assert ref.GetBoundaries() == new.GetBoundaries() and ref.GetMaterials() == new.GetMaterials()
    Ka, _, _, _, _ = _elasticity(ref, "left")
    Kb, _, _, _, _ = _elasticity(new, "left")
    assert (Ka != Kb).nnz == 0


# ---------------------------------------------------------------- the scale benchmarks (smoke tests)
def test_run_case_in_a_subprocess_reports_time_memory_and_refusals():
    from admmkit.benchmarks.contact.scale_runs import run_case, run_in_subprocess
    row = run_in_subprocess("ex1", 1 / 10, "iterative", timeout=120)
    assert row["status"] == "converged" and row["n_free"] == 440
    assert row["peak_rss_bytes"] > 50e6 and row["total_s"] > 0 and row["counters"]["cg_iterations"] > 0
    refused = run_case("ex1", 1 / 1200, "full")               # about 60 GiB: refused before assembling
    assert refused["status"] == "refused" and "GiB" in refused["message"]


def test_run_case_reports_a_scene_refused_for_memory_as_refused(monkeypatch):
    # when not even the iterative mode fits in what is available now, the scene itself refuses (a
    # admmkit.problems.contact.model.memory.InsufficientMemory): the case is a refusal, not a crash of the study
    from admmkit.benchmarks.contact import scale_runs
    from admmkit.problems.contact.model import memory
    from admmkit.problems.contact.model import scene
    from admmkit.problems.contact.model.memory import InsufficientMemory
    for module in (memory, scene, scale_runs):
        monkeypatch.setattr(module, "available_memory", lambda: 2**20, raising=False)
    with pytest.raises(InsufficientMemory, match="GiB available"):
        example1(h=1 / 200)
    row = scale_runs.run_case("ex1", 1 / 200, "iterative")
    assert row["status"] == "refused" and "available" in row["message"]


@pytest.fixture
def in_process(monkeypatch):
    """Run the benchmark's cases in this process (the subprocess path is tested above)."""
    from admmkit.benchmarks.contact import scale_runs as scale
    monkeypatch.setattr(scale, "run_in_subprocess",
                        lambda example, h, mode, timeout=0, rho=1e3: scale.run_case(example, h, mode) | {"wall_s": 0.0})
    from admmkit.benchmarks.contact import amg_crossover as crossover
    from admmkit.benchmarks.contact import scale as scale_bench
    monkeypatch.setattr(scale_bench, "run_in_subprocess", scale.run_in_subprocess)
    monkeypatch.setattr(crossover, "run_in_subprocess", scale.run_in_subprocess)


def test_bench_scale_writes_table_and_growth_chart(tmp_path, in_process, capsys):
    from admmkit.cli import main
    assert main(["bench", "scale", "--quick", "--out", str(tmp_path)]) == 0
    for name in ("scale.md", "scale.csv", "scale_growth.png", "scale_growth.svg"):
        assert (tmp_path / name).exists()
    text = (tmp_path / "scale.md").read_text()
    assert "| 1/20 | 1680 |" in text and "Target (issue #8)" in text


def test_bench_amg_crossover_writes_modes_and_reuse_tables(tmp_path, in_process, capsys):
    from admmkit.cli import main
    assert main(["bench", "amg-crossover", "--quick", "--out", str(tmp_path)]) == 0
    text = (tmp_path / "amg_crossover.md").read_text()
    assert "`NUMPY_MADVISE_HUGEPAGE=0`" in text          # the child processes' environment, as run_in_subprocess sets it
    assert "| 1/10 | 440 |" in text and "Reusing the hierarchy" in text
    assert (tmp_path / "amg_crossover.png").exists() and (tmp_path / "amg_crossover.csv").exists()


def test_known_kx_is_k_times_the_returned_solution():
    K, D = _poisson_pair(20)
    solver = IterativeXSolver(K, D, tol=1e-10)
    x1 = solver.solve(2.0, np.ones(K.shape[0]))
    x2 = solver.solve(2.0, np.arange(K.shape[0], dtype=float))
    for x in (x1, x2):
        assert np.allclose(solver.known_Kx(x), K @ x, rtol=0, atol=1e-9 * np.abs(K @ x).max())
    assert solver.known_Kx(x1.copy()) is None


def test_axpy_refresh_equals_the_galerkin_product_for_the_new_rho():
    """A_l(rho) = A_l(rho_0) + (rho - rho_0) D_l with D_l = R D P, so the axpy refresh is R A(rho) P exactly."""
    from admmkit.blocks.iterative import AMGPreconditioner
    K, D = _poisson_pair(30)
    M = AMGPreconditioner(K + 2.0 * D, None, D=D, rho=2.0)
    M.refresh((K + 700.0 * D).tocsr(), 700.0)
    levels = M.ml.levels
    assert len(levels) >= 2
    for fine, coarse in zip(levels[:-1], levels[1:]):
        ref = fine.R @ fine.A @ fine.P
        assert abs(coarse.A - ref).max() <= 1e-10 * abs(ref).max()


def test_auto_mode_follows_the_measured_crossovers():
    from types import SimpleNamespace

    from admmkit.problems.contact.solvers.problem import auto_mode
    fake = lambda n, n_c, dim: SimpleNamespace(n_free=n, n_c=n_c, dim=dim, mesh=SimpleNamespace(dim=dim), scene=None,  # noqa: E731
                                               friction=None)
    assert auto_mode(fake(1_000_000, 1000, 2)) == "condensed"     # the condensed mode won at every 2D size measured
    assert auto_mode(fake(50_000, 5000, 2)) == "full"
    assert auto_mode(fake(500_000, 5000, 2)) == "iterative"
    assert auto_mode(fake(5_000, 300, 3)) == "condensed"
    assert auto_mode(fake(300_000, 3000, 3)) == "iterative"
    assert auto_mode(assemble(example1(h=1 / 10))) == "condensed"   # the paper's sizes: unchanged


def test_iterative_mode_is_bitwise_repeatable_and_leaves_numpy_random_alone():
    # pyamg starts spectral-radius estimates from np.random.rand: admmkit.linalg.amg seeds it locally (issue #16)
    ops = assemble(example1(h=1 / 20))
    np.random.seed(123)
    expected_next = np.random.rand()
    np.random.seed(123)
    a = solve_scene(ops, "sadmm", 1e3, mode="iterative").result
    assert np.random.rand() == expected_next          # the caller's random stream is untouched
    np.random.rand(7)                                 # a different global state before the second run
    b = solve_scene(ops, "sadmm", 1e3, mode="iterative").result
    assert a.iterations == b.iterations and np.array_equal(a.x, b.x) and np.array_equal(a.lam, b.lam)


def test_auto_reuse_does_not_depend_on_the_clock(monkeypatch):
    # the keep-or-refresh decision is counted in CG iterations, not seconds: a clock that jumps at random
    # (a loaded machine) gives the same iterates bit for bit
    import itertools
    import time as time_module

    import admmkit.linalg.amg
    import admmkit.blocks.iterative
    ops = assemble(example1(h=1 / 20))
    calm = solve_scene(ops, "sadmm", 1e3, mode="iterative").result
    rng = np.random.default_rng(0)
    ticks = itertools.accumulate(rng.exponential(0.05, 10**6))
    jumpy = type("Clock", (), {"perf_counter": staticmethod(lambda: next(ticks)),
                               "process_time": staticmethod(time_module.process_time)})
    monkeypatch.setattr(admmkit.blocks.iterative, "time", jumpy)
    monkeypatch.setattr(admmkit.linalg.amg, "time", jumpy)
    loaded = solve_scene(ops, "sadmm", 1e3, mode="iterative").result
    assert calm.iterations == loaded.iterations and np.array_equal(calm.x, loaded.x)
    assert np.array_equal(calm.lam, loaded.lam) and calm.counters == loaded.counters
