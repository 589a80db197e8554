"""The obstacle plug-in: exact solution, cvxpy cross-check, KKT, rates, free boundary, bad input, CLI."""
import math

import numpy as np
import pytest

from admmkit import ResidualTolerance, Status, solve
from admmkit.cli import main
from admmkit.problems.obstacle import A_STAR, Scene, make_problem, pyramid, radial, radial_exact, radial_psi, scene, solve_with_cvxpy
from admmkit.problems.obstacle.scene import A_COEF, B_COEF, pyramid_psi

TIGHT = dict(tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12)
STOP = ResidualTolerance(1e-11, 1e-11)


def rel(a, b):
    return np.linalg.norm(a - b) / max(1.0, np.linalg.norm(b))


# ---------------------------------------------------------------- the exact solution
def test_free_boundary_equation_and_coefficients():
    a = A_STAR
    assert a**2 * (1 - math.log(a / 2)) == pytest.approx(1.0, abs=1e-14)   # 1 - a^2 = a^2 ln(2/a)
    assert A_COEF == pytest.approx(a**2 / math.sqrt(1 - a**2)) and B_COEF == pytest.approx(A_COEF * math.log(2))


def test_exact_solution_is_c1_at_a_star_and_touches_psi_inside():
    a, eps = A_STAR, 1e-7
    inside, outside = math.sqrt(1 - a**2), -A_COEF * math.log(a) + B_COEF
    assert inside == pytest.approx(outside, abs=1e-14)                      # u continuous
    assert -a / math.sqrt(1 - a**2) == pytest.approx(-A_COEF / a, abs=1e-13)  # u' continuous
    d_left = (radial_exact(a, 0) - radial_exact(a - eps, 0)) / eps
    d_right = (radial_exact(a + eps, 0) - radial_exact(a, 0)) / eps
    assert d_left == pytest.approx(d_right, abs=1e-5)
    r = np.linspace(0, a, 50)
    assert np.allclose(radial_exact(r, 0 * r), radial_psi(r, 0 * r), atol=1e-15)
    r = np.linspace(a + 1e-6, 2 * math.sqrt(2), 200)
    assert np.all(radial_exact(r, 0 * r) > radial_psi(r, 0 * r))               # free outside a*
    assert radial_exact(2.0, 0.0) == pytest.approx(0.0, abs=1e-15)            # B = A ln 2
    # harmonic outside: -Delta(-A ln r) = 0, checked with a 5-point stencil at r = 1.3
    x, y, d = 1.1, 0.7, 1e-3
    lap = (radial_exact(x + d, y) + radial_exact(x - d, y) + radial_exact(x, y + d) + radial_exact(x, y - d)
           - 4 * radial_exact(x, y)) / d**2
    assert abs(lap) < 1e-5


def test_boundary_data_is_the_exact_solution():
    p = make_problem(radial(h=1 / 2))
    bnd = np.setdiff1d(np.arange(p.nodes.shape[0]), p.free)
    x, y = p.nodes[bnd].T
    assert np.allclose(p.u_D[bnd], radial_exact(x, y), atol=1e-15)
    assert np.all(p.u_D[bnd] >= -1.0)                                          # feasible: psi = -1 there


# ---------------------------------------------------------------- against cvxpy
@pytest.mark.parametrize("make", [lambda: radial(h=1 / 4), lambda: pyramid(h=1 / 16),
                                  lambda: pyramid(h=1 / 16, side="upper", f=10.0, psi=lambda x, y: -pyramid_psi(x, y))])
@pytest.mark.parametrize("policy, order, rho", [("summable", "zx", 1.0), ("residual_balancing", "xz", 1.0),
                                                ("fixed", "xz", 100.0)])
def test_admm_matches_cvxpy(make, policy, order, rho):
    p = make_problem(make())
    u_ref, lam_ref = solve_with_cvxpy(p, **TIGHT)
    res = solve(p, rho=rho, policy=policy, order=order, stop=STOP, max_iter=20_000)
    assert res.status is Status.CONVERGED
    assert rel(res.x, u_ref) < 1e-6
    assert rel(res.lam, lam_ref) < 1e-5
    assert p.contact_set(res.x).sum() > 0


def test_upper_obstacle_mirrors_the_lower_one():
    low = make_problem(pyramid(h=1 / 16))
    up = make_problem(pyramid(h=1 / 16, side="upper", f=10.0, psi=lambda x, y: -pyramid_psi(x, y)))
    a = solve(low, rho=1.0, policy="summable", order="zx", stop=STOP)
    b = solve(up, rho=1.0, policy="summable", order="zx", stop=STOP)
    assert np.allclose(a.x, -b.x, atol=1e-9) and np.all(a.lam <= 1e-12) and np.all(b.lam >= -1e-12)


@pytest.mark.parametrize("name", ["radial", "pyramid"])
def test_kkt_residuals_small_and_signs(name):
    p = make_problem(scene(name, h=1 / 4 if name == "radial" else 1 / 16))
    res = solve(p, rho=1.0, policy="summable", order="zx", stop=STOP)
    k = res.kkt
    assert k["primal"] < 1e-9 and k["infeasibility"] < 1e-9 and k["dual_density"] < 1e-9
    assert k["sign"] < 1e-9 and k["complementarity"] < 1e-8
    # lam <= 0 is the contact pressure: K u - F = M mu with mu = -lam >= 0 on the contact set
    mu = -res.lam
    assert np.allclose(p.K @ res.x - p.F, p.m * mu, atol=1e-9)
    assert np.all(mu[~p.contact_set(res.x, 1e-6)] < 1e-8) and mu.max() > 0.1


# ---------------------------------------------------------------- discretisation
def test_h1_error_decreases_at_rate_one():
    errors = []
    for n in (16, 32, 64):
        p = make_problem(radial(h=4 / n))
        res = solve(p, rho=1.0, policy="summable", order="zx", stop=ResidualTolerance(1e-10, 1e-10))
        errors.append(p.errors(res.x))
    h1 = [e["H1"] for e in errors]
    l2 = [e["L2"] for e in errors]
    rates_h1 = [math.log2(h1[i] / h1[i + 1]) for i in range(2)]
    rates_l2 = [math.log2(l2[i] / l2[i + 1]) for i in range(2)]
    assert all(0.85 < r < 1.3 for r in rates_h1), rates_h1
    assert all(r > 1.6 for r in rates_l2), rates_l2


def test_free_boundary_radius_close_to_a_star():
    p = make_problem(radial(h=4 / 64))
    res = solve(p, rho=1.0, policy="summable", order="zx", stop=ResidualTolerance(1e-10, 1e-10))
    assert abs(p.contact_radius(res.x) - A_STAR) < p.h          # within one cell
    assert abs(p.contact_radius(res.x) - A_STAR) < 0.04


def test_factorisations_equal_distinct_rho_values():
    p = make_problem(radial(h=1 / 4))
    res = solve(p, rho=1e-2, policy="summable", order="zx", stop=STOP)
    assert res.rho_changes > 0
    assert res.counters["factorizations"] == len(set(res.history["rho"]))
    assert res.counters["solves"] == res.iterations


# ---------------------------------------------------------------- bad input
@pytest.mark.parametrize("make, match", [
    (lambda: pyramid(psi=0.5), r"psi: the obstacle lies above the boundary data"),
    (lambda: radial(u_D=-2.0), r"psi: the obstacle lies above"),
    (lambda: pyramid(side="upper"), r"psi: the obstacle lies below"),
    (lambda: radial(h=0.0), r"h = 0.0 is outside the accepted range"),
    (lambda: radial(h=-1 / 16), r"h = -0.0625 is outside"),
    (lambda: radial(h=math.inf), r"h = inf is outside"),
    (lambda: radial(h=10.0), r"h = 10 leaves no interior node .*larger than the domain"),
    (lambda: scene("nope"), r"scene = 'nope' is unknown; known scenes: radial, pyramid"),
    (lambda: pyramid(psi=lambda x, y: np.where(x > 0.5, np.nan, -1.0)), r"psi is not finite"),
    (lambda: pyramid(psi=math.inf), r"psi is not finite"),
    (lambda: pyramid(f=lambda x, y: 1 / (x - x)), r"f is not finite"),
    (lambda: pyramid(f=math.nan), r"f is not finite"),
    (lambda: pyramid(f="x+"), r"f: expression 'x\+' is not valid Python syntax"),
    (lambda: pyramid(f=[1.0]), r"f must be a number, a callable g\(x, y\) or an expression string"),
    (lambda: radial(h=3.0), r"h = 3 leaves no interior node \(1 x 1 squares\): .*accepted 0 < h <= 2.66667"),
    (lambda: pyramid(side="both"), r"side = 'both'; accepted: lower, upper"),
    (lambda: Scene(box=(0, 0, 0, 1)), r"box = .*x0 < x1"),
])
def test_bad_input_raises_value_error_naming_the_parameter(make, match):
    with np.errstate(all="ignore"), pytest.raises(ValueError, match=match):
        make()


def test_make_problem_rejects_other_objects():
    with pytest.raises(ValueError, match="scene must be"):
        make_problem("radial")


# ---------------------------------------------------------------- command line
def test_cli_prints_summary_errors_and_writes_plot(capsys, tmp_path):
    plot = tmp_path / "u.png"
    assert main(["solve", "obstacle", "--scene", "radial", "--h", "1/8", "--policy", "summable", "--rho", "1",
                 "--plot", str(plot)]) == 0
    out = capsys.readouterr().out
    assert "status       converged" in out and "KKT" in out
    assert "errors       L2" in out and "exact a* = 0.697965" in out
    assert plot.stat().st_size > 1000


def test_cli_bad_scene_and_h(capsys):
    assert main(["solve", "obstacle", "--scene", "nope"]) == 2
    assert "--scene nope: scene 'nope' is unknown" in capsys.readouterr().err
    assert main(["solve", "obstacle", "--h", "0"]) == 2         # argparse's error: main() returns its code
    assert "--h" in capsys.readouterr().err
