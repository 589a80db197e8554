"""3D contact: the block mesh, the assembly, the AMG x-step against the direct one and cvxpy, bad input."""
import math

import ngsolve as ng
import numpy as np
import pytest
from ngsolve.meshes import MakeStructured3DMesh

from admmkit import RelativeChange
from admmkit.cli import main
from admmkit.problems.contact import solve_scene
from admmkit.problems.contact.model.memory import memory_need3d
from admmkit.problems.contact.model.assembly3d import assemble3d
from admmkit.problems.contact.model.scene3d import FACES_3D, Scene3D, block_mesh, example2_3d


def test_block_mesh_is_makestructured3dmesh_with_outward_faces():
    mesh = block_mesh(3.0, 1.0, 1.0, 1 / 3)
    ref = MakeStructured3DMesh(hexes=False, nx=9, ny=3, nz=3, mapping=lambda x, y, z: (3 * x, y, z))
    assert np.abs(np.array(mesh.ngmesh.Coordinates()) - np.array(ref.ngmesh.Coordinates())).max() <= 1e-15
    assert [[v.nr for v in e.vertices] for e in mesh.Elements(ng.VOL)] == \
           [[v.nr for v in e.vertices] for e in ref.Elements(ng.VOL)]
    normal = ng.specialcf.normal(3)
    expected = {"back": (-1, 0, 0), "front": (1, 0, 0), "left": (0, -1, 0), "right": (0, 1, 0),
                "bottom": (0, 0, -1), "top": (0, 0, 1)}
    for face in FACES_3D:
        area = ng.Integrate(ng.CF(1) * ng.ds(face), mesh)
        n = [ng.Integrate(normal[i] * ng.ds(face), mesh) / area for i in range(3)]
        assert np.allclose(n, expected[face], atol=1e-12)
    assert ng.Integrate(ng.CF(1) * ng.dx, mesh) == pytest.approx(3.0)


@pytest.fixture(scope="module")
def small():
    return assemble3d(example2_3d(h=1 / 4))


def test_assembly_of_the_contact_face(small):
    ops = small
    assert ops.xc.shape[1] == 3 and np.all(ops.xc[:, 2] == 0.0)
    assert np.all(ops.xc[:, 0] > 0)                                  # the clamped edge x = 0 is not a contact node
    assert 3.0 - 1 / 4 <= ops.mc.sum() <= 3.0                          # the face's area less the clamped strip
    assert np.allclose(ops.g, 0.003 * (ops.xc[:, 0] - 1.5) ** 2 + 0.003 * (ops.xc[:, 1] - 0.5) ** 2 + 0.001)
    assert np.all(np.abs(ops.B.sum(axis=1)) == 1.0) and ops.B.nnz == ops.n_c   # B u = -u_z at each node
    # traction (0, 0, -2) on the unit face x = 3: the load vector sums to -2 in z
    n_scalar = ops.fes.ndof // 3
    z_dofs = ops.free >= 2 * n_scalar
    assert ops.f[z_dofs].sum() == pytest.approx(-2.0)
    assert ops.f[~z_dofs].sum() == pytest.approx(0.0, abs=1e-12)


def test_iterative_and_full_modes_agree_and_solve_the_qp(small):
    """3D SADMM: the AMG x-step ends at the direct solver's answer, and both at cvxpy's (Clarabel) QP solution."""
    import cvxpy as cp
    ops = small
    stop = RelativeChange(1e-10)
    full = solve_scene(ops, "sadmm", rho=1e3, mode="full", stop=stop)
    it = solve_scene(ops, "sadmm", rho=1e3, mode="iterative", stop=stop)
    assert full.result.converged and it.result.converged
    K = ops.K
    energy = lambda u: math.sqrt(u @ (K @ u))  # noqa: E731
    assert energy(it.u - full.u) <= 1e-7 * energy(full.u)
    u = cp.Variable(ops.n_free)
    cons = [ops.B @ u <= ops.g]
    cp.Problem(cp.Minimize(0.5 * cp.quad_form(u, cp.psd_wrap(K)) - ops.f @ u), cons).solve(
        solver="CLARABEL", tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12, tol_ktratio=1e-10)
    assert energy(it.u - u.value) <= 1e-7 * energy(u.value)
    lam_ref = cons[0].dual_value / ops.mc                              # B'M lam = B' mu
    assert np.abs(it.pressure - lam_ref).max() <= 1e-4 * np.abs(lam_ref).max()
    assert it.result.kkt["active_nodes"] > 0


def test_memory_need_grows_and_the_iterative_need_is_the_smaller():
    small, big = example2_3d(h=1 / 8), example2_3d(h=1 / 16)
    assert memory_need3d(big, "iterative") > memory_need3d(small, "iterative")
    assert memory_need3d(big, "iterative") < min(memory_need3d(big, "full"), memory_need3d(big, "condensed"))
    # the direct need grows like n^(4/3) times the cached factorisations, the iterative one like n
    growth = lambda mode: memory_need3d(big, mode) / memory_need3d(small, mode)  # noqa: E731
    assert growth("full") > growth("iterative")


@pytest.mark.parametrize("bad, match", [
    (dict(h=1e-3), "GiB"), (dict(nu=0.5), "nu"), (dict(dirichlet=("side",)), "unknown face"),
    (dict(contact="top"), "contact"), (dict(tractions={"front": (0.0, -2.0)}), "triple"),
    (dict(h=2.0), "larger than the block"), (dict(E=-1.0), "E"),
])
def test_bad_3d_scenes_are_refused_before_any_work(bad, match):
    with pytest.raises(ValueError, match=match):
        example2_3d(**bad)


def test_the_memory_refusal_names_both_estimates():
    with pytest.raises(ValueError, match=r"iterative x-step .* sparse factorisation"):
        Scene3D(h=2e-3)


def test_bench_contact3d_writes_figure_vtk_and_table(tmp_path, monkeypatch, capsys):
    from admmkit.benchmarks.contact import contact3d as contact3d_bench
    from admmkit.benchmarks.contact import scale_runs as scale
    monkeypatch.setattr(contact3d_bench, "probe_in_subprocess",            # in-process: keeps the test fast
                        lambda h, which, timeout: contact3d_bench.probe(h) | {"status": "ok"})
    monkeypatch.setattr(scale, "run_in_subprocess",
                        lambda example, h, mode, timeout=0, rho=1e3: scale.run_case(example, h, mode) | {"wall_s": 0.0})
    assert main(["bench", "contact3d", "--quick", "--out", str(tmp_path), "--vtk", str(tmp_path / "c3d")]) == 0
    for name in ("contact3d.md", "contact3d.png", "contact3d.svg", "c3d.vtu"):
        assert (tmp_path / name).exists()
    text = (tmp_path / "contact3d.md").read_text()
    assert "| 1/4 |" in text and "converged" in text and "## SADMM by x-step mode" in text
    for name in ("contact3d_growth.md", "contact3d_growth.csv", "contact3d_growth.png", "contact3d_growth.svg"):
        assert (tmp_path / name).exists()
    growth = (tmp_path / "contact3d_growth.md").read_text()
    assert "| 1/4 | 900 | converged |" in growth and "| 1/6 |" in growth and "Growth exponents" in growth


def test_growth_exponent_is_the_log_log_slope_of_the_large_runs():
    from admmkit.benchmarks.contact.contact3d import growth_exponent
    rows = [{"n_free": n, "status": "converged", "cpu_s": 2e-6 * n ** 1.25} for n in (1e3, 5e4, 3e5, 1e6)]
    rows[0]["cpu_s"] = 5.0                                   # start-up dominated: below 4e4, left out
    rows.append({"n_free": 2e6, "status": "timeout", "cpu_s": 1.0})
    assert growth_exponent(rows, "cpu_s") == pytest.approx(1.25)
    assert math.isnan(growth_exponent(rows[:2], "cpu_s"))


def test_the_named_scene_block3d_is_the_frictionless_block_of_bench_contact3d():
    from admmkit.problems.contact.cli import scene_names
    from admmkit.problems.contact.model.scene_file import load_scene
    assert scene_names()["block3d"] == "3-D, frictionless"
    scene, reference = load_scene("block3d", h=1 / 4), example2_3d(h=1 / 4)
    for key in ("Lx", "Ly", "Lz", "h", "E", "nu", "dirichlet", "contact", "tangential", "order"):
        assert getattr(scene, key) == getattr(reference, key), key
    assert dict(scene.tractions) == dict(reference.tractions) == {"front": (0.0, 0.0, -2.0)}
    for x, y in ((0.0, 0.0), (1.5, 0.5), (3.0, 1.0), (0.7, 0.2)):
        assert scene.gap_at(x, y) == reference.gap_at(x, y)


@pytest.mark.parametrize("order", [1, 2])
def test_the_compiled_stiffness_is_ngsolves_to_round_off(order):
    scene = example2_3d(h=1 / 4, order=order, tangential="stick") if order == 1 else example2_3d(h=1 / 2, order=2)
    fast, slow = assemble3d(scene), assemble3d(scene, stiffness="ngsolve")
    assert np.array_equal(fast.K.indptr, slow.K.indptr) and np.array_equal(fast.K.indices, slow.K.indices)
    assert abs(fast.K - slow.K).max() <= 1e-14 * abs(slow.K).max()
    if order == 1:
        assert abs(fast.K - slow.K).max() > 0          # two assemblies, not one twice
    for key in ("f", "mc", "g", "xc", "free"):
        assert np.array_equal(getattr(fast, key), getattr(slow, key)), key
    assert (fast.B != slow.B).nnz == 0


def test_stiffness_is_checked():
    with pytest.raises(ValueError, match="stiffness = 'fast'; accepted: compiled, ngsolve"):
        assemble3d(example2_3d(h=1 / 2), stiffness="fast")


@pytest.mark.parametrize("h, peak", [(1 / 8, 0.30e9), (1 / 16, 0.43e9), (1 / 24, 0.77e9), (1 / 32, 1.37e9),
                                     (1 / 48, 4.24e9)])
def test_the_iterative_memory_estimate_is_just_above_the_measured_peak(h, peak):
    # peaks (ru_maxrss of whole runs): docs/results/scale/contact3d_growth.md, and where it was higher the
    # target command's (`admmkit solve contact --scene block3d --h 1/32 or 1/48 --mode iterative`, docs/scale.md)
    assert peak <= memory_need3d(example2_3d(h=h), "iterative") <= 1.15 * peak
