"""Hertz in 3D (#51): the scene hertz3d, Hertz's formulas, the measure of a and p0, and the adaptive loop on it."""
import math
from types import SimpleNamespace

import numpy as np
import pytest

from admmkit.cli import main
from admmkit.problems.contact.model.scene_file import load_scene
from admmkit.problems.contact.validation.hertz3d import (CENTRE, DELTA, R_SPHERE, e_star, face_mass, hertz_load,
                                                           hertz_peak_pressure, hertz_pressure, hertz_radius, measure,
                                                           moment_radius, profile_fit)


def test_hertz_formulas_agree_with_each_other():
    """a(F(a)) = a; the pressure integrates to F (2 pi p0 a^2 / 3); with the indentation d of a half-space
    a = sqrt(R d) and F = 4/3 E* sqrt(R) d^(3/2) give the same load."""
    E, nu, R = 1.0, 0.3, 1.0
    for a in (0.01, 0.05, 0.2):
        F = hertz_load(a, R, E, nu)
        assert math.isclose(hertz_radius(F, R, E, nu), a, rel_tol=1e-12)
        p0 = hertz_peak_pressure(F, a)
        r = np.linspace(0, a, 20001)
        assert math.isclose(np.trapezoid(2 * np.pi * r * hertz_pressure(r, F, R, E, nu), r), F, rel_tol=1e-4)
        assert math.isclose(2 * math.pi * p0 * a * a / 3, F, rel_tol=1e-12)
        d = a * a / R
        assert math.isclose(4 / 3 * e_star(E, nu) * math.sqrt(R) * d ** 1.5, F, rel_tol=1e-12)
    with pytest.raises(ValueError, match="must be > 0"):
        hertz_radius(-1.0, R, E, nu)


def _nodes(h: float, a: float, F: float, jitter: float = 0.0):
    """Contact nodes on a grid of spacing h around the centre, Hertz's pressure at them, and p = g where in
    contact (a stand-in for an assembled scene's operators)."""
    rng = np.random.default_rng(1)
    k = int(0.2 / h)
    s = h * np.arange(-k, k + 1)                     # a node at the centre
    X, Y = np.meshgrid(s + CENTRE[0], s + CENTRE[1])
    xc = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    r = np.hypot(xc[:, 0] - CENTRE[0], xc[:, 1] - CENTRE[1])
    lam = hertz_pressure(r, F, R_SPHERE, 1.0, 0.3) * (1 + jitter * rng.standard_normal(r.size))
    g = np.ones(r.size)
    p = np.where(r < a, g, g - 1.0)
    ops = SimpleNamespace(xc=xc, mc=np.full(r.size, h * h), g=g, n_c=r.size, scene=SimpleNamespace(E=1.0, nu=0.3))
    return ops, lam, p


def test_measure_reads_hertz_back_from_hertz_pressures():
    """Hertz's pressure at the nodes of a fine grid: F is its quadrature, and a and p0 come back within 0.5 %
    (the grid's quadrature of F); with 3 % noise on the pressures, within 3 %; a contact set too small is refused."""
    a = 0.05
    F = hertz_load(a, R_SPHERE, 1.0, 0.3)
    ops, lam, p = _nodes(a / 20, a, F)
    m = measure(ops, lam, p)
    assert abs(m["F"] / F - 1) < 5e-3 and abs(m["a_err"]) < 5e-3 and abs(m["p0_err"]) < 5e-3
    assert m["edge_in"] < 1.005 and m["edge_out"] > 0.995 and m["edge_in"] < m["edge_out"] and m["active_nodes"] > 100
    noisy = measure(*_nodes(a / 20, a, F, jitter=0.03))
    assert abs(noisy["a_err"]) < 0.03 and abs(noisy["p0_err"]) < 0.03
    ops, lam, p = _nodes(a / 0.9, a, F)               # the centre alone in contact
    with pytest.raises(ValueError, match="too few"):
        measure(ops, lam, p)


def test_the_scene_file_is_hertz_geometry():
    """hertz3d: the quarter x, y >= 0 of a block under a sphere of radius 1 centred over (0, 0), symmetry planes
    x = 0 and y = 0, the plane raised by DELTA; a/R and a / block small (Hertz's half-space)."""
    scene = load_scene("hertz3d")
    assert (scene.Lx, scene.Ly, scene.Lz, scene.dirichlet, scene.contact) == (0.5, 0.5, 0.5, ("top",), "bottom")
    assert scene.symmetry == ("back", "left") and CENTRE == (0.0, 0.0)
    assert math.isclose(scene.gap_at(*CENTRE), -DELTA, abs_tol=1e-15)
    r = 0.3
    assert math.isclose(scene.gap_at(CENTRE[0] + r * 0.6, CENTRE[1] + r * 0.8), R_SPHERE - math.sqrt(R_SPHERE ** 2 - r * r) - DELTA)
    assert all(t == (0.0, 0.0, 0.0) for t in scene.tractions.values())
    a = math.sqrt(R_SPHERE * DELTA)                    # the half-space's radius at indentation DELTA
    assert a / R_SPHERE < 0.06 and a / scene.Lz < 0.11
    assert scene.h == min(scene.Lx, scene.Ly, scene.Lz) / 2      # --target-error's first mesh: the study's


def test_scene_help_lists_hertz3d(capsys):
    main(["solve", "contact", "--help"])
    assert "hertz3d (3-D, frictionless)" in capsys.readouterr().out.replace("\n", " ").replace("  ", " ")


def test_adaptive_loop_refines_at_the_contact_and_measures_hertz():
    """P2 from h = 0.25 to a relative estimate of 0.3 (4 levels): the smallest tetrahedra sit at the contact
    (within 5 a of the centre, at the plane), each level converged, and the contact radius of the discrete
    solution is within 5 % of Hertz's at the measured load (measured: -2.5 %; finer levels: docs/hertz3d.md)."""
    import ngsolve as ng
    from admmkit import RelativeChange
    from admmkit.problems.contact.solvers.adaptive import solve_adaptive
    from admmkit.problems.contact.solvers.methods import solve_scene
    out = solve_adaptive(load_scene("hertz3d", order=2), 0.3)
    assert out.reached and all(lvl.status == "converged" for lvl in out.levels) and len(out.levels) >= 3
    ops = out.model
    points = np.array(ops.mesh.ngmesh.Coordinates())
    tets = np.array([[v.nr for v in el.vertices] for el in ops.mesh.Elements(ng.VOL)])
    corners = points[tets]
    size = np.max(np.linalg.norm(corners[:, :, None] - corners[:, None], axis=-1), axis=(1, 2))
    centroid = corners.mean(axis=1)
    smallest = centroid[size <= 1.01 * size.min()]
    a = math.sqrt(R_SPHERE * DELTA)
    assert np.all(np.hypot(smallest[:, 0] - CENTRE[0], smallest[:, 1] - CENTRE[1]) < 5 * a)
    assert np.all(smallest[:, 2] < 5 * a)
    exact = solve_scene(ops, "sadmm", 1e3, mode="condensed", stop=RelativeChange(1e-8), max_iter=5000).result
    m = measure(ops, exact.lam, exact.z)
    assert abs(m["a_fit_err"]) < 0.05 and m["F"] > 0


def test_profile_fit_reads_pressure_through_the_nodal_forces():
    """Hertz's pressures read back by the fit (to the scan's step), and on a P2-like pattern (every fourth node
    near 0 with a small weight, the others raised to keep the force): p0 and a within 1 %, where the largest
    nodal pressure is 15 % high."""
    a, F = 0.05, hertz_load(0.05, R_SPHERE, 1.0, 0.3)
    p0 = hertz_peak_pressure(F, a)
    r = np.linspace(0, 0.075, 301)
    lam = hertz_pressure(r, F, R_SPHERE, 1.0, 0.3)
    mc = np.full(r.size, 1.0)
    a_fit, p0_fit = profile_fit(r, mc * lam, mc, r_in=r[lam > 0].max())
    assert abs(a_fit / a - 1) < 1e-3 and abs(p0_fit / p0 - 1) < 1e-3
    vertex = np.arange(r.size) % 4 == 0
    mc2 = np.where(vertex, 0.3, 0.56)
    lam2 = np.where(vertex, 0.0, lam * (0.3 + 3 * 0.56) / (3 * 0.56))
    a_fit, p0_fit = profile_fit(r, mc2 * lam2, mc2, r_in=r[lam > 0].max())
    assert abs(a_fit / a - 1) < 0.01 and abs(p0_fit / p0 - 1) < 0.01 and lam2.max() / p0 > 1.15


def _hertz_forces(r, F, mass):
    """The consistent nodal loads M I(p) of Hertz's pressure (interpolated at the nodes)."""
    return mass @ hertz_pressure(r, F, R_SPHERE, 1.0, 0.3)


def test_face_mass_is_the_gram_matrix_of_the_p2_trace():
    """face_mass on a P2 scene: 1'M1 is the face's area, 1'M r^2 = int r^2 (r^2 is a P2 function: exact), and
    the fit of Hertz's consistent loads and the second-moment radius read a and p0 back; the lumped weights
    (HRZ: the vertices nearly without force) misread p0 where the mesh is not uniform."""
    from admmkit.problems.contact.model.assembly3d import assemble3d
    scene = load_scene("hertz3d", h=0.125 / 4, order=2)            # a/h ~ 1.6: 3 P2 nodes across a
    ops = assemble3d(scene)
    M = face_mass(ops)
    one = np.ones(ops.n_c)
    assert math.isclose(one @ (M @ one), scene.Lx * scene.Ly, rel_tol=1e-12)
    r2 = ops.xc[:, 0] ** 2 + ops.xc[:, 1] ** 2
    assert math.isclose(one @ (M @ r2), (scene.Lx ** 3 * scene.Ly + scene.Lx * scene.Ly ** 3) / 3, rel_tol=1e-12)
    assert abs(M - M.T).max() < 1e-15
    a = 0.1
    F = hertz_load(a, R_SPHERE, 1.0, 0.3)
    r = np.sqrt(r2)
    f = _hertz_forces(r, F, M)
    a_fit, p0_fit = profile_fit(r, f, M, r_in=r[r < a].max())
    assert abs(a_fit / a - 1) < 2e-3 and abs(p0_fit / hertz_peak_pressure(F, a) - 1) < 2e-3
    near = r < 1.5 * a
    assert abs(moment_radius(r[near], f[near]) / a - 1) < 0.02


def test_symmetry_faces_fix_the_normal_component_only():
    """symmetry = back, left: u_x = 0 on x = 0 and u_y = 0 on y = 0, the other components free, and the contact
    nodes on those planes kept (with half weights); bad faces are refused naming the key."""
    from admmkit.problems.contact.model.assembly3d import assemble3d
    from admmkit.problems.contact.model.scene3d import Scene3D
    scene = load_scene("hertz3d", order=1)
    ops = assemble3d(scene)
    fixed = np.ones(ops.fes.ndof, dtype=bool)
    fixed[ops.free] = False
    nv = ops.mesh.nv
    points = np.array(ops.mesh.ngmesh.Coordinates())
    on_back = (points[:, 0] == 0) & (points[:, 2] < scene.Lz)
    on_left = (points[:, 1] == 0) & (points[:, 2] < scene.Lz)
    assert fixed[np.flatnonzero(on_back)].all() and not fixed[nv + np.flatnonzero(on_back & ~on_left)].any()
    assert fixed[nv + np.flatnonzero(on_left)].all() and not fixed[2 * nv + np.flatnonzero(on_left | on_back)].any()
    assert np.any(ops.xc[:, 0] == 0) and math.isclose(ops.mc.sum(), scene.Lx * scene.Ly)
    for bad, match in ((("bottom",), "symmetry: face 'bottom'"), (("side",), "symmetry: unknown face 'side'"),
                       (("top",), "symmetry: face 'top'")):
        with pytest.raises(ValueError, match=match):
            Scene3D(Lx=0.5, Ly=0.5, Lz=0.5, h=0.25, dirichlet=("top",), symmetry=bad)


def test_the_returned_iterate_meets_hertz_within_one_percent():
    """--target-error 0.15 --balance 0.01 (levels 1-5, 3,123 unknowns; the documented run continues to 0.06):
    the iterate the loop returns reads a and p0 within 1 % of Hertz (measured -0.06 %, +0.87 %); with the default
    gamma 0.3 the stop comes earlier and a moves by 1 % (the pressure is not what it bounds)."""
    from admmkit.problems.contact.solvers.adaptive import solve_adaptive
    scene = load_scene("hertz3d", order=2)
    out = solve_adaptive(scene, 0.15, gamma=0.01)
    assert out.reached and len(out.levels) == 5
    m = measure(out.model, out.result.lam, out.result.z)
    assert abs(m["a_fit_err"]) < 0.01 and abs(m["p0_fit_err"]) < 0.01 and abs(m["a_moment_err"]) < 0.01
    early = solve_adaptive(scene, 0.15)
    loose = measure(early.model, early.result.lam, early.result.z)
    assert abs(loose["a_fit_err"] - m["a_fit_err"]) > 0.005                       # measured +0.94 % against -0.06 %


def test_residual_estimator_reads_symmetry_faces_by_their_tangential_traction():
    """On a symmetry face the residual estimator tests s.t = 0 only (the normal stress there is the mirror
    half's reaction, not a residual): its Neumann term is smaller than where those faces are taken as free, by
    the normal stress under the contact."""
    from admmkit import RelativeChange
    from admmkit.problems.contact.model.assembly3d import assemble3d
    from admmkit.problems.contact.solvers.estimate_residual import ResidualEstimator, _traction_cf
    from admmkit.problems.contact.solvers.methods import solve_scene
    ops = assemble3d(load_scene("hertz3d", h=0.0625, order=1))
    res = solve_scene(ops, "sadmm", 1e3, mode="condensed", stop=RelativeChange(1e-8), max_iter=5000).result
    est = ResidualEstimator(ops)
    symmetric = est.terms(res.x, res.lam)["neumann"].sum()
    est.neumann |= {label: _traction_cf(None, 3) for label in est.symmetry}
    est.symmetry = ()
    free = est.terms(res.x, res.lam)["neumann"].sum()
    assert 0 < symmetric < 0.2 * free                       # measured 0.055
