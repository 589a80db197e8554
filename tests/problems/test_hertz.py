"""Hertz validation scene: formulas, geometry, the plane's normal, and a and p0 against Hertz."""
import math

import ngsolve as ng
import numpy as np
import pytest

from admmkit.cli import main
from admmkit.problems.contact import Scene, assemble, solve_scene
from admmkit.problems.contact.validation.hertz import (HertzCase, e_star, hertz_half_width, hertz_load, hertz_peak_pressure,
                                    hertz_pressure, measure)
from admmkit.problems.contact.model.scene_file import load_scene


def test_hertz_formulas_are_consistent():
    P, R, E, nu = 3e-4, 2.0, 5.0, 0.25
    a = hertz_half_width(P, R, E, nu)
    assert a == pytest.approx(math.sqrt(4 * P * R * (1 - nu**2) / (math.pi * E)))
    assert hertz_load(a, R, E, nu) == pytest.approx(P)
    p0 = hertz_peak_pressure(P, a)
    x = np.linspace(-a, a, 200_001)
    p = hertz_pressure(x, P, R, E, nu)
    assert p.max() == pytest.approx(p0)
    assert np.trapezoid(p, x) == pytest.approx(P, rel=1e-6)          # the profile carries the load
    assert e_star(E, nu) == pytest.approx(E / (1 - nu**2))


@pytest.fixture(scope="module")
def coarse():
    case = HertzCase()
    ops = assemble(case.scene(case.a_target / 10))
    return case, ops


def test_half_cylinder_mesh_is_exact_and_refined_near_the_contact(coarse):
    case, ops = coarse
    mesh = ops.mesh
    assert set(mesh.GetBoundaries()) == {"contact", "free", "top"}
    X = np.array(mesh.ngmesh.Coordinates())[:, :2]
    curved = {v.nr for el in mesh.Elements(ng.BND) if el.mat != "top" for v in el.vertices}
    r = np.hypot(X[list(curved), 0], X[list(curved), 1] - case.R)
    assert np.abs(r - case.R).max() <= 1e-12                                  # boundary vertices on the circle
    assert np.min(np.hypot(X[:, 0], X[:, 1])) <= 1e-14                        # a vertex at the origin
    assert np.abs(ops.xc[:, 0]).max() <= case.x_c + 1e-12
    # elements inside the zone r <= 2 a_target are about h_c; elements far away are much larger
    h_c = case.a_target / 10
    longest = []
    for el in mesh.Elements(ng.VOL):
        P = X[[v.nr for v in el.vertices]]
        edge = max(np.linalg.norm(P[i] - P[j]) for i, j in ((0, 1), (1, 2), (0, 2)))
        longest.append((np.linalg.norm(P.mean(axis=0)), edge))
    longest = np.array(longest)
    assert longest[longest[:, 0] <= case.a_target, 1].max() <= 1.6 * h_c
    assert longest[longest[:, 0] >= 0.5 * case.R, 1].min() >= 10 * h_c


def test_contact_is_measured_along_the_planes_normal(coarse):
    case, ops = coarse
    assert np.allclose(ops.normals, [0.0, -1.0])
    n_scalar = ops.fes.ndof // 2
    x_part = ops.B[:, np.flatnonzero(ops.free < n_scalar)]
    assert x_part.nnz == 0 or np.abs(x_part.data).max() == 0.0                # no horizontal component
    R = case.R
    delta = case.delta_guess()
    assert np.allclose(ops.g, R - np.sqrt(R * R - ops.xc[:, 0] ** 2) - delta, rtol=0, atol=1e-15)
    assert np.allclose(ops.g, ops.xc[:, 1] - delta, rtol=0, atol=1e-14)       # the nodes' height above the plane


def test_a_and_p0_match_hertz_on_the_coarse_mesh(coarse):
    """a/h_c = 10 (1.6e3 unknowns): a within 1 %, p0 within 2 %, the profile within 3 % of p0 inside 0.8 a."""
    case, ops = coarse
    sol = solve_scene(ops, "sadmm", rho=1e3)
    assert sol.result.converged
    m = measure(ops, sol.result.lam, sol.result.z, case)
    assert abs(m["a_err"]) <= 0.01 and abs(m["p0_err"]) <= 0.02
    lo, hi = m["a_bracket"]
    assert lo <= m["a_h"] <= hi + 1e-12
    x = ops.xc[:, 0]
    inner = np.abs(x) <= 0.8 * m["a_hertz"]
    exact = hertz_pressure(x[inner], m["P"], case.R, case.E, case.nu)
    assert np.abs(sol.result.lam[inner] - exact).max() <= 0.03 * m["p0_hertz"]
    assert 0.015 <= m["a_hertz"] <= 0.03                                      # a << R indeed


def test_parabolic_profile_differs_from_the_circle_by_x4_over_8R3():
    circle, parabola = HertzCase(), HertzCase(profile="parabola")
    x = np.linspace(-circle.x_c, circle.x_c, 101)
    d = circle.gap(0.0)(x, 0 * x) - parabola.gap(0.0)(x, 0 * x)
    assert np.all(d >= 0) and d.max() <= 1.01 * circle.x_c**4 / (8 * circle.R**3)


@pytest.mark.parametrize("bad", [dict(R=0.0), dict(nu=0.5), dict(a_target=0.5, contact_factor=2.5),
                                 dict(contact_factor=1.0), dict(profile="cone"), dict(zone_factor=-1.0)])
def test_bad_hertz_cases_are_refused(bad):
    with pytest.raises(ValueError):
        HertzCase(**bad)


def test_bad_contact_mesh_size_is_refused():
    with pytest.raises(ValueError, match="h_c"):
        HertzCase().scene(h_c=0.0)


@pytest.mark.parametrize("bad", [(0.0, 0.0), (1.0,), (float("nan"), 1.0), "down"])
def test_contact_normal_is_validated(bad):
    with pytest.raises(ValueError, match="contact_normal"):
        Scene(L=2, H=1, h=0.5, E=1, nu=0.3, contact_normal=bad)


def test_contact_normal_is_normalised_and_read_from_toml(tmp_path):
    assert Scene(L=2, H=1, h=0.5, contact_normal=(0, -2)).contact_normal == (0.0, -1.0)
    path = tmp_path / "s.toml"
    path.write_text('L = 2\nH = 1\nh = 0.5\nE = 1\nnu = 0.3\ndirichlet = ["left"]\ncontact = "bottom"\n'
                    'gap = 0.01\ncontact_normal = [0, -1]\n')
    assert load_scene(path).contact_normal == (0.0, -1.0)


def test_bench_hertz_writes_its_table_and_figures(tmp_path, capsys):
    assert main(["bench", "hertz", "--k", "6", "--out", str(tmp_path)]) == 0
    for name in ("hertz.md", "hertz.csv", "hertz_pressure.png", "hertz_pressure.svg", "hertz_errors.png"):
        assert (tmp_path / name).exists()
    assert "a/h_c =   6" in capsys.readouterr().out
    assert "| 6 |" in (tmp_path / "hertz.md").read_text()
