"""Checks of the discrete contact model: scenes, meshes, K, f, B, mc, g."""
import math

import ngsolve as ng
import numpy as np
import pytest
import scipy.sparse.linalg as sla

from admmkit.problems.contact.model.assembly import assemble, lame
from admmkit.problems.contact.model.mesh import structured_rectangle, unstructured_rectangle
from admmkit.problems.contact.model.scene import Scene, example1, example2
from admmkit.problems.contact.model.scene_file import load_scene

H = 1 / 40


def interpolate(op, field):
    """Free part of the dof vector interpolating the vector field (a tuple of CFs)."""
    gf = ng.GridFunction(op.fes)
    gf.Set(ng.CF(field))
    return gf.vec.FV().NumPy()[op.free]


RIGID = {"x": (1, 0), "y": (0, 1), "rotation": (-ng.y, ng.x)}


@pytest.fixture(scope="module", params=[1, 2], ids=["P1", "P2"])
def ex1(request):
    return assemble(example1(h=H, order=request.param))


@pytest.fixture(scope="module", params=[1, 2], ids=["P1", "P2"])
def ex2(request):
    return assemble(example2(h=H, order=request.param))


# ------------------------------------------------------------------ K
@pytest.mark.parametrize("order", [1, 2])
def test_K_symmetric_positive_definite(order):
    op = assemble(example1(h=1 / 4, order=order))
    K = op.K.toarray()
    assert np.abs(K - K.T).max() <= 1e-12 * np.abs(K).max()
    assert np.linalg.eigvalsh(K).min() > 1e-8 * np.abs(K).max()


def test_K_annihilates_no_free_rigid_mode(ex1):
    for name, field in RIGID.items():
        r = interpolate(ex1, field)
        assert r @ (ex1.K @ r) > 1e-6 * ex1.K.diagonal().max() * (r @ r) / ex1.n_free, name


def test_K_is_linear_in_E():
    op, op2 = assemble(example1(h=1 / 10)), assemble(example1(h=1 / 10, E=4000.0))
    assert abs(op2.K - 2 * op.K).max() <= 1e-12 * abs(op.K).max()


def test_lame_plane_strain():
    mu, lam = lame(2000.0, 0.3)
    assert mu == pytest.approx(2000 / 2.6) and lam == pytest.approx(600 / (1.3 * 0.4))


# ------------------------------------------------------------------ f
def test_load_resultant_ex1(ex1):
    """The top traction (0,-10) over length 2 gives -20; the free dofs miss the share
    of the clamped corner (0,1), 10 * int(phi_corner) = 10 h/2 (for P2 too: NGSolve's
    hierarchical P2 vertex function is the P1 hat, the edge bubbles vanish at vertices)."""
    assert interpolate(ex1, (0, 1)) @ ex1.f == pytest.approx(-20 + 10 * H / 2, rel=1e-12)
    assert interpolate(ex1, (1, 0)) @ ex1.f == pytest.approx(0, abs=1e-12)


def test_load_resultant_ex2(ex2):
    assert interpolate(ex2, (0, 1)) @ ex2.f == pytest.approx(-2.0, rel=1e-12)


def test_body_force_resultant():
    """Body force (0,-3) on the area 2 gives -6; the clamped column x = 0 keeps the
    integral of its hat functions, a strip of area h/2 * 1."""
    h = 1 / 10
    op = assemble(example1(h=h, tractions={}, body_force=(0.0, -3.0)))
    assert interpolate(op, (0, 1)) @ op.f == pytest.approx(-6 + 3 * h / 2, rel=1e-12)


def test_traction_callable_and_expression(tmp_path):
    """t = (0, -10 x) on the top: resultant -10 * 2^2/2 = -20, minus the clamped corner's
    share 10 * int_0^h x (1 - x/h) dx = 10 h^2/6."""
    h = 1 / 10
    op = assemble(example1(h=h, tractions={"top": lambda x, y: (0 * x, -10 * x)}))
    assert interpolate(op, (0, 1)) @ op.f == pytest.approx(-20 + 10 * h**2 / 6, rel=1e-12)
    path = tmp_path / "t.toml"
    path.write_text(TOML + '[tractions]\ntop = [0.0, "-10*x"]\n')
    op2 = assemble(load_scene(path, h=1 / 10))
    assert np.allclose(op2.f, op.f, rtol=0, atol=1e-12)


def test_scene_is_hashable_and_replaceable():
    s = example1()
    assert hash(s) == hash(s.with_h(s.h)) and s.with_h(0.1).tractions == s.tractions


# ------------------------------------------------------------------ contact nodes, mc, normals, B, g
def test_contact_nodes_structured(ex1):
    """P1: L/h nodes (corner (0,0) clamped); P2: also the L/h edge midpoints."""
    assert ex1.n_c == round(2 / H) * ex1.scene.order
    assert np.allclose(ex1.xc[:, 1], 0) and ex1.xc[:, 0].min() > 0
    assert np.all(np.diff(ex1.xc[:, 0]) > 0)


def test_lumped_mass_sum(ex1):
    """mc sums to |Gamma_C| minus the clamped corner's weight: 2 - h/2 (trapezoid) or 2 - h/6 (Simpson)."""
    corner = H / 2 if ex1.scene.order == 1 else H / 6
    assert ex1.mc.sum() == pytest.approx(2 - corner, rel=1e-13)
    assert np.all(ex1.mc > 0)
    if ex1.scene.order == 1:
        assert np.allclose(ex1.mc[:-1], H) and ex1.mc[-1] == pytest.approx(H / 2)
    else:
        assert set(np.round(ex1.mc / H * 6, 9)) == {1.0, 2.0, 4.0}


def test_normals_point_down(ex1):
    assert np.allclose(ex1.normals, [0, -1])


def test_lumped_mass_sum_ex2(ex2):
    corner = H / 2 if ex2.scene.order == 1 else H / 6
    assert ex2.mc.sum() == pytest.approx(3 - corner, rel=1e-13)


def check_B_of_rigid_translation(op):
    """u = (0,-1) gives u.n = 1; for P2, the midpoint next to the clamped corner sees
    the corner's dof, which is 0 in the free space: (0 + 1)/2 there."""
    expected = np.ones(op.n_c)
    if op.scene.order == 2:
        expected[0] = 0.5
    assert np.allclose(op.B @ interpolate(op, (0, -1)), expected, atol=1e-12)
    assert np.allclose(op.B @ interpolate(op, (1, 0)), 0.0, atol=1e-12)


def test_B_of_rigid_translation_ex1(ex1):
    check_B_of_rigid_translation(ex1)


def test_B_of_rigid_translation_ex2(ex2):
    check_B_of_rigid_translation(ex2)


def test_B_of_quadratic_field_P2():
    """With P2, B is exact for u = (0, -x^2): u.n = x^2 also at the edge midpoints."""
    op = assemble(example1(h=1 / 8, order=2))
    assert np.allclose(op.B @ interpolate(op, (0, -ng.x * ng.x)), op.xc[:, 0] ** 2, atol=1e-12)


def test_gap_values_ex1(ex1):
    assert np.all(ex1.g == 0.01)


def test_gap_values_ex2(ex2):
    x, y = ex2.xc.T
    assert np.allclose(ex2.g, 0.003 * (x - 1.5) ** 2 + 0.001, rtol=1e-14)


def test_unstructured_mesh_operators():
    op = assemble(example1(h=0.1, mesh_kind="unstructured"))
    first = op.xc[:, 0].min()  # the first contact node; the clamped corner keeps first/2 of the length
    assert op.mc.sum() == pytest.approx(2 - first / 2, rel=1e-12)
    assert np.allclose(op.normals, [0, -1])
    assert np.allclose(op.B @ interpolate(op, (0, -1)), 1.0)


def test_slanted_contact_normals():
    from netgen.geom2d import SplineGeometry
    geo = SplineGeometry()
    pts = [geo.AppendPoint(*p) for p in [(0, 0), (2, 0.5), (2, 1.5), (0, 1)]]
    for i, bc in enumerate(["bottom", "right", "top", "left"]):
        geo.Append(["line", pts[i], pts[(i + 1) % 4]], bc=bc)
    scene = Scene(geometry=geo, mesh_kind="unstructured", h=0.2, E=1.0, dirichlet=("left",), gap=0.1)
    op = assemble(scene)
    assert np.allclose(op.normals, np.array([0.25, -1]) / math.hypot(0.25, 1))
    with pytest.raises(ValueError, match="stick"):
        assemble(Scene(geometry=geo, mesh_kind="unstructured", h=0.2, E=1.0, gap=0.1, tangential="stick"))


def test_occ_geometry_with_own_labels():
    from netgen.occ import OCCGeometry, Rectangle, X, Y
    face = Rectangle(2, 1).Face()
    face.edges.Min(Y).name, face.edges.Min(X).name, face.edges.Max(Y).name = "floor", "wall", "roof"
    geo = OCCGeometry(face, dim=2)
    scene = Scene(geometry=geo, mesh_kind="unstructured", h=0.1, E=10.0, dirichlet=("wall",),
                  contact="floor", tractions={"roof": (0, -1)}, gap="0.01*x", tangential="stick")
    op = assemble(scene)
    assert np.allclose(op.g, 0.01 * op.xc[:, 0]) and np.allclose(op.normals, [0, -1])
    with pytest.raises(ValueError, match="known labels: floor, roof, wall"):
        Scene(geometry=geo, mesh_kind="unstructured", dirichlet=("left",), contact="floor")


def test_stick_fixes_tangential_component():
    op, op_s = assemble(example1(h=H)), assemble(example1(h=H, tangential="stick"))
    assert op.n_free - op_s.n_free == op.n_c  # one x-dof per contact node
    assert np.allclose(op_s.B @ interpolate(op_s, (0, -1)), 1.0)


# ------------------------------------------------------------------ meshes
def test_structured_mesh_is_freefem_square():
    """2 nx ny triangles, every square cut along x - y = const (FreeFEM flags=0)."""
    L, Hh, h = 2.0, 1.0, 0.25
    mesh = structured_rectangle(L, Hh, h)
    nx, ny = 8, 4
    assert mesh.ne == 2 * nx * ny and mesh.nv == (nx + 1) * (ny + 1)
    for el in mesh.Elements(ng.VOL):
        p = np.array([mesh[v].point for v in el.vertices])
        d = [p[i] - p[j] for i, j in ((0, 1), (1, 2), (2, 0))]
        diag = [e for e in d if abs(e[0]) > 1e-12 and abs(e[1]) > 1e-12]
        assert len(diag) == 1 and diag[0][0] * diag[0][1] > 0  # slope +1: x - y = const
    assert set(mesh.GetBoundaries()) == {"bottom", "right", "top", "left"}


def test_unstructured_mesh_labels():
    mesh = unstructured_rectangle(2.0, 1.0, 0.2)
    assert set(mesh.GetBoundaries()) == {"bottom", "right", "top", "left"}
    area = ng.Integrate(1, mesh)
    assert area == pytest.approx(2.0)


# ------------------------------------------------------------------ validation
@pytest.mark.parametrize("changes, name", [
    (dict(h=0.0), "h"), (dict(h=-0.1), "h"), (dict(h=float("nan")), "h"), (dict(h=float("inf")), "h"),
    (dict(h=5.0), "h"), (dict(h=1e-5), "h"), (dict(h=1e-3, order=2), "h"),
    (dict(E=0.0), "E"), (dict(E=-1.0), "E"), (dict(E=float("nan")), "E"),
    (dict(nu=0.5), "nu"), (dict(nu=-1.0), "nu"), (dict(nu=0.7), "nu"),
    (dict(dirichlet=("west",)), "dirichlet"), (dict(contact="floor"), "contact"),
    (dict(tractions={"roof": (0, 1)}), "tractions"), (dict(dirichlet=()), "dirichlet"),
    (dict(contact=""), "contact"), (dict(contact="left"), "contact"),
    (dict(gap=float("nan")), "gap"), (dict(gap=float("inf")), "gap"),
    (dict(gap=lambda x, y: 1 / (x - 1)), "gap"), (dict(gap="x +"), "expression"),
    (dict(gap="sqrt(x) + os"), "unknown names"), (dict(order=3), "order"),
    (dict(mesh_kind="hex"), "mesh_kind"), (dict(tangential="coulomb"), "tangential"),
])
def test_bad_scene_raises(changes, name):
    with pytest.raises(ValueError, match=name):
        example1(**changes)


def test_unknown_label_lists_known_ones():
    with pytest.raises(ValueError, match="bottom, right, top, left"):
        example1(contact="floor")


def test_memory_message_has_estimate():
    with pytest.raises(ValueError, match="GiB"):
        example2(h=1e-5)


TOML = """name = "t"\nL = 2.0\nH = 1.0\nE = 2000.0\nnu = 0.3\ndirichlet = ["left"]\ncontact = "bottom"\ngap = 0.01\n"""


@pytest.mark.parametrize("text, key", [
    (TOML.replace("E = 2000.0\n", 'E = "stiff"\n'), "'E'"),   # #18: a missing key takes Scene's default now
    (TOML + "mue = 3.0\n", "'mue'"),                          # mu is Coulomb's coefficient now (#19)
    (TOML + "mu = 3.0\n", "'coulomb'"),                       # ... and needs tangential = 'coulomb'
    (TOML.replace("nu = 0.3", 'nu = "0.3"'), "'nu'"),
    (TOML.replace('contact = "bottom"', "contact = 3"), "'contact'"),
    (TOML + "[tractions]\ntop = [1.0]\n", "tractions.top"),
    (TOML.replace("gap = 0.01", "gap = "), "malformed"),
    (TOML.replace("nu = 0.3", "nu = 0.6"), "nu"),
])
def test_bad_toml_raises(tmp_path, text, key):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=key):
        load_scene(path)


def test_toml_missing_key_takes_the_scene_default(tmp_path):
    path = tmp_path / "noE.toml"
    path.write_text(TOML.replace("E = 2000.0\n", ""))
    assert load_scene(path).E == Scene().E


def test_toml_good_minimal(tmp_path):
    path = tmp_path / "ok.toml"
    path.write_text(TOML)
    assert load_scene(path, h=0.1).gap_at(0.5, 0) == 0.01


@pytest.mark.parametrize("name, example", [("ex1", example1), ("ex2", example2)])
def test_toml_round_trip(name, example):
    a, b = assemble(load_scene(name)), assemble(example())
    assert abs(a.K - b.K).max() == 0 and abs(a.B - b.B).max() == 0
    for attr in ("f", "mc", "g", "xc", "normals"):
        assert np.array_equal(getattr(a, attr), getattr(b, attr)), attr


def test_with_h():
    s = example2().with_h(0.1)
    assert s.h == 0.1 and s.E == 5000.0 and s.gap_at(1.5, 0) == pytest.approx(0.001)


# ------------------------------------------------------------------ elasticity without contact
def tip_deflection(h, order):
    op = assemble(example1(h=h, order=order))
    u = sla.spsolve(op.K.tocsc(), op.f)
    return op.to_gridfunction(u)(op.mesh(2.0, 0.5))[1]


def test_cantilever_converges():
    """P1 is too stiff: the tip deflection grows under refinement, about 4x less each
    time (second order), towards the P2 value (to 1%)."""
    w = [tip_deflection(h, 1) for h in (1 / 10, 1 / 20, 1 / 40)]
    assert w[0] > w[1] > w[2] and (w[1] - w[2]) < 0.5 * (w[0] - w[1])
    assert w[2] == pytest.approx(tip_deflection(1 / 20, 2), rel=0.01)
