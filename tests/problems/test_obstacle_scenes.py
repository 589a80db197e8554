"""Obstacle scenes of one's own: errors against the scene's own exact solution, scene files (TOML), and the
command line's refusals of inputs it used to accept or misreport (issue #46 item 5)."""
import math
import pickle
import re
from pathlib import Path

import numpy as np
import ngsolve as ng
import pytest

from admmkit import ResidualTolerance, solve
from admmkit.cli import main
from admmkit.problems.obstacle import Scene, known_scenes, load_scene, make_problem, pyramid, radial
from admmkit.problems.obstacle.adaptive import solve_adaptive
from admmkit.problems.obstacle.fields import field
from admmkit.problems.obstacle.scene_file import SCENES_DIR

ROOT = Path(__file__).resolve().parents[2]
STOP = ResidualTolerance(1e-10, 1e-10)
#: the ridge scene's exact solution (problems/obstacle/scenes/ridge.toml), on numpy arrays
RIDGE = lambda x, y: np.where(np.abs(x) <= 1 / 3, 1 - 9 / 5 * x**2, 6 / 5 * (1 - np.abs(x)))   # noqa: E731
#: a manufactured solution whose obstacle never touches it: -Delta u = f, u = 0 on the unit square's boundary
SINE = dict(box=(0, 1, 0, 1), f="2*pi^2*sin(pi*x)*sin(pi*y)", psi=-1.0, u_D=0.0, exact="sin(pi*x)*sin(pi*y)",
            name="sine")


def errors_on(make, ns):
    """The errors of the tight discrete solution of make(h = 1 / N) for each N."""
    out = []
    for n in ns:
        p = make_problem(make(1 / n))
        out.append(p.errors(solve(p, rho=1.0, policy="summable", order="zx", stop=STOP).x))
    return out


def rates(values):
    return [math.log2(a / b) for a, b in zip(values, values[1:])]


# ---------------------------------------------------------------- errors against the scene's own exact solution
@pytest.mark.parametrize("make", [lambda h: load_scene("ridge", h=h), lambda h: Scene(h=h, **SINE)],
                         ids=["ridge (contact strip)", "sine (obstacle inactive)"])
def test_errors_are_against_the_scenes_own_exact_solution_and_fall_with_h(make):
    """Before, errors() integrated against the radial scene's exact solution whatever the scene: these errors
    were O(1) and did not fall."""
    errs = errors_on(make, (4, 8, 16))
    h1, l2 = [e["H1"] for e in errs], [e["L2"] for e in errs]
    assert all(0.85 < r < 1.3 for r in rates(h1)), h1
    assert all(1.6 < r < 2.5 for r in rates(l2)), l2
    assert h1[-1] < 0.22 and l2[-1] < 1e-2


def test_ridge_errors_match_a_quadrature_of_its_closed_form():
    """The L2 error of u_h against a midpoint-rule sum over a fine grid of the closed form u(x)."""
    p = make_problem(load_scene("ridge", h=1 / 8))
    u = p.gridfunction(solve(p, rho=1.0, policy="summable", order="zx", stop=STOP).x)
    X, Y = np.meshgrid(np.linspace(-1, 1, 801)[:-1] + 1 / 800, np.linspace(0, 1, 401)[:-1] + 1 / 800)
    uh = u(p.mesh(X.ravel(), Y.ravel())).ravel()
    l2 = math.sqrt(np.mean((uh - RIDGE(X, Y).ravel()) ** 2) * 2)          # the box's area is 2
    assert p.errors(u.vec.FV().NumPy()[p.free])["L2"] == pytest.approx(l2, rel=0.02)


def test_adaptive_levels_report_the_scenes_own_errors():
    out = solve_adaptive(load_scene("ridge", h=1 / 4), 5e-2)          # P1: three or four levels
    assert out.reached and len(out.levels) >= 3
    semi = [lvl.errors["H1_semi"] for lvl in out.levels]
    assert all(b < a for a, b in zip(semi, semi[1:]))
    for lvl in out.levels:                                              # ZZ is asymptotically exact here
        assert 0.7 < lvl.errors["H1_semi"] / lvl.estimate < 1.4, (lvl.errors, lvl.estimate)


def test_a_scene_without_exact_solution_has_no_errors():
    p = make_problem(pyramid(h=1 / 4))
    with pytest.raises(ValueError, match="scene 'pyramid' has no exact solution"):
        p.errors(np.zeros(p.n))
    out = solve_adaptive(pyramid(h=1 / 4), 0.5, max_levels=1)
    assert out.levels[0].errors is None


def test_the_radial_scene_keeps_its_written_out_exact_gradient():
    from admmkit.problems.obstacle.scene import radial_exact_cf
    u, grad = radial().exact_coefficients()
    mesh = make_problem(radial(h=1 / 2)).mesh
    for cf, ref in zip((u, grad), radial_exact_cf()):
        assert ng.Integrate(ng.InnerProduct(cf - ref, cf - ref) * ng.dx, mesh) == 0.0


def test_an_exact_callable_on_coefficient_functions_gets_ngsolves_gradient():
    scene = Scene(box=(0, 1, 0, 1), h=1 / 4, psi=-1.0, u_D=lambda x, y: x * x + y, exact=lambda x, y: x * x + y,
                  f=-2.0)
    mesh = make_problem(scene).mesh
    _, grad = scene.exact_coefficients()
    assert ng.Integrate((grad[0] - 2 * ng.x) ** 2 + (grad[1] - 1) ** 2, mesh) < 1e-24


def test_an_exact_callable_on_numpy_arrays_only_is_refused_when_the_scene_is_built():
    with pytest.raises(ValueError, match="exact = .* cannot be evaluated as an NGSolve coefficient function"):
        Scene(box=(0, 1, 0, 1), h=1 / 4, psi=-1.0, exact=lambda x, y: np.where(x > 0.5, x, 0.5))


# ---------------------------------------------------------------- expressions
def test_an_expression_gives_the_same_values_on_arrays_and_as_a_coefficient_function():
    g = field("sqrt(2 + x^2)*exp(-y) + max(x, y, 0.3) - abs(min(x, -y)) + atan(x)*cos(pi*y)")
    mesh = make_problem(pyramid(h=1 / 4)).mesh
    x, y = np.array([0.1, 0.45, 0.8]), np.array([0.7, 0.2, 0.55])
    on_cf = [g(ng.x, ng.y)(mesh(a, b)) for a, b in zip(x, y)]
    assert np.allclose(g(x, y), on_cf, rtol=1e-14, atol=0)
    assert repr(g) == repr(g.text)
    copy = pickle.loads(pickle.dumps(g))                  # a scene sent to a worker process
    assert copy.text == g.text and np.array_equal(copy(x, y), g(x, y))


@pytest.mark.parametrize("text, match", [("x +* 2", "not valid Python syntax"),
                                         ("__import__('os')", "unknown names"),
                                         ("x.__class__", "unknown names"),
                                         ("z + 1", r"unknown names \['z'\]")])
def test_a_bad_expression_is_refused_naming_the_field(text, match):
    with pytest.raises(ValueError, match=f"^psi: expression .*{match}"):
        Scene(psi=text)


# ---------------------------------------------------------------- scene files
PYRAMID_TOML = '''name = "pyramid"
box = [0, 1, 0, 1]
h = 0.125
f = -10
psi = "0.3 - 1.2*max(abs(x - 0.5), abs(y - 0.5))"
u_D = 0
'''


def test_a_file_scene_is_the_built_in_one_bit_for_bit(tmp_path):
    path = tmp_path / "pyramid.toml"
    path.write_text(PYRAMID_TOML)
    a, b = make_problem(pyramid(h=1 / 8)), make_problem(load_scene(path))
    assert a.n == b.n and (a.K != b.K).nnz == 0
    assert np.array_equal(a.F, b.F) and np.array_equal(a.psi, b.psi)
    ra, rb = (solve(p, rho=1.0, policy="summable", order="zx", stop=STOP) for p in (a, b))
    assert ra.iterations == rb.iterations and np.array_equal(ra.x, rb.x)


def test_the_cli_solves_a_file_as_the_built_in_scene(tmp_path, capsys):
    path = tmp_path / "pyramid.toml"
    path.write_text(PYRAMID_TOML)
    lines = []
    for scene in ("pyramid", str(path)):
        assert main(["solve", "obstacle", "--scene", scene, "--h", "1/8", "-q"]) == 0
        out = capsys.readouterr().out
        lines.append([ln for ln in out.splitlines() if ln.startswith(("problem", "iterations", "contact set"))])
    assert lines[0] == lines[1] and "49 free nodes" in lines[0][0]


def test_the_shipped_ridge_file_solves_uniform_and_adaptive(capsys):
    assert main(["solve", "obstacle", "--scene", str(SCENES_DIR / "ridge.toml"), "--h", "1/8", "-q"]) == 0
    out = capsys.readouterr().out
    assert "obstacle/ridge: h = 0.125 (16 x 8 squares)" in out and "errors       L2" in out
    assert "free bdry" not in out                                     # a* is the radial scene's
    assert main(["solve", "obstacle", "--scene", "ridge", "--h", "1/4", "--fe-order", "1", "--target-error", "0.05"]) == 0
    out = capsys.readouterr().out
    assert "status       target_reached" in out
    levels = [line.split() for line in out.splitlines() if re.match(r"\s+\d+\s+\d+\s+\d+", line)]
    errors = [float(level[5]) for level in levels]                      # the true H1-seminorm error column
    assert len(errors) >= 3 and all(b < a for a, b in zip(errors, errors[1:]))
    assert all(0.7 < float(level[5]) / float(level[3]) < 1.4 for level in levels)     # beside the estimate


def test_a_files_own_h_is_the_default_and_h_overrides_it(capsys):
    assert main(["solve", "obstacle", "--scene", "ridge", "--eps-abs", "1e-6", "-q"]) == 0
    assert "h = 0.0625 (32 x 16 squares)" in capsys.readouterr().out


def test_the_scenes_can_be_listed(capsys):
    assert main(["solve", "obstacle", "--list-scenes"]) == 0
    out = capsys.readouterr().out
    assert [line.split()[0] for line in out.splitlines()] == list(known_scenes()) == ["radial", "pyramid", "ridge"]
    assert "ridge.toml" in out


def test_the_docs_example_is_the_shipped_ridge_file():
    """docs/obstacle.md, 'Your own obstacle': its TOML block is problems/obstacle/scenes/ridge.toml's keys, so the
    documented commands (run by tests/test_doc_commands.py) solve what the page shows."""
    page = (ROOT / "docs" / "obstacle.md").read_text()
    block = re.search(r"## Your own obstacle.*?```toml\n(.*?)```", page, re.S).group(1)
    shipped = [ln for ln in (SCENES_DIR / "ridge.toml").read_text().splitlines() if ln and not ln.startswith("#")]
    assert block.splitlines() == shipped
    assert "    admmkit solve obstacle --scene ridge" in page


@pytest.mark.parametrize("text, match", [
    ("foo = 1", "unknown key 'foo'; known keys: name, box, h"),
    ('h = "small"', "key 'h' must be a number, got 'small'"),
    ("psi = true", "key 'psi' must be a number or an expression in x, y, got True"),
    ("psi = [1, 2]", "key 'psi' must be a number or an expression"),
    ('psi = "x +* 1"', "key 'psi': expression 'x \\+\\* 1' is not valid Python syntax"),
    ('exact = "open(x)"', "key 'exact': expression 'open\\(x\\)' uses unknown names \\['open'\\]"),
    ("box = [0, 1, 0]", r"key 'box' must be four numbers \[x0, x1, y0, y1\], got \[0, 1, 0\]"),
    ('box = [0, 1, 0, "1"]', "key 'box' must be four numbers"),
    ("box = [1, 0, 0, 1]", r"box = \(1.0, 0.0, 0.0, 1.0\); accepted: x0 < x1"),
    ('side = "both"', "side = 'both'; accepted: lower, upper"),
    ("h = 3", "h = 3 leaves no interior node"),
    ('psi = "log(x)"', r"psi is not finite at \(0, 0\)"),
    ('exact = "1/x"', "exact is not finite"),
    ("psi = 1", "psi: the obstacle lies above the boundary data"),
    ("scene = 1", "key 'scene' must be a table"),
    ("h = 0.1\n[scene]\nh = 0.2", "keys h outside the \\[scene\\] table"),
    ("h = = 1", "malformed TOML"),
])
def test_a_bad_file_is_one_error_naming_the_file_and_the_key(tmp_path, text, match):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=f"^{re.escape(str(path))}: .*{match}"):
        load_scene(path)


def test_a_file_that_is_not_utf8_is_refused(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_bytes(b"name = '\xff'")
    with pytest.raises(ValueError, match="not a TOML text file"):
        load_scene(path)


def test_a_scene_table_is_read_like_the_top_level(tmp_path):
    path = tmp_path / "t.toml"
    path.write_text("[scene]\n" + PYRAMID_TOML)
    assert load_scene(path).counts == (8, 8)


@pytest.mark.parametrize("scene, match", [
    ("missing.toml", "--scene missing.toml: missing.toml: no such file$"),
    ("some/dir/x.toml", "--scene some/dir/x.toml: some/dir/x.toml: no such file$"),
    ("nope", "--scene nope: scene 'nope' is unknown and there is no such file; known scenes: radial, pyramid, ridge"),
    (".", r"--scene \.: \.: not a file"),
])
def test_cli_a_missing_file_is_no_such_file_and_an_unknown_name_unknown(scene, match, capsys):
    assert main(["solve", "obstacle", "--scene", scene]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and re.match(f"admmkit: error: {match}", err), err


def test_cli_a_bad_file_names_the_file_and_the_key(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text('psi = "x +* 1"')
    assert main(["solve", "obstacle", "--scene", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"{path}: key 'psi': expression" in err


# ---------------------------------------------------------------- the command line's refusals
@pytest.mark.parametrize("args, match", [
    (["--theta", "2"], "--theta needs --target-error"),
    (["--theta", "0.3"], "--theta needs --target-error"),
    (["--max-levels", "0"], "--max-levels needs --target-error"),
    (["--max-levels", "4", "--max-unknowns", "100"], "--max-levels, --max-unknowns need --target-error"),
    (["--target-error", "0.1", "--theta", "2"], r"--theta = 2 is outside the accepted range \(0, 1\)"),
    (["--target-error", "0.1", "--max-levels", "0"], "--max-levels = 0 is outside the accepted range an integer >= 1"),
    (["--h", "3"], r"--h: h = 3 is larger than the domain allows; accepted 0 < h <= 2.66667 for the scene radial"),
    (["--h", "3", "--target-error", "0.1"], r"--h: h = 3 is larger than the domain allows; accepted 0 < h <= 2.66667"),
    (["--scene", "pyramid", "--h", "0.7"], r"--h: h = 0.7 is larger than the domain allows; accepted 0 < h <= 0.666667"),
])
def test_cli_refuses_what_it_used_to_ignore_or_misreport(args, match, capsys):
    assert main(["solve", "obstacle", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and re.match(f"admmkit: error: {match}", err), err


@pytest.mark.parametrize("h", ["0", "-1", "1/0", "abc"])
def test_cli_h_outside_the_numbers_is_argparses_error_naming_h(h, capsys):
    assert main(["solve", "obstacle", "--h", h]) == 2
    assert "--h: expected a" in capsys.readouterr().err


def test_cli_h_at_the_edge_of_the_range_solves(capsys):
    assert main(["solve", "obstacle", "--scene", "pyramid", "--h", "2/3", "--eps-abs", "1e-8", "-q"]) == 0
    assert "(2 x 2 squares), P1, 1 free nodes" in capsys.readouterr().out
