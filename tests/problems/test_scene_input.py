"""Scene input (#16, #18): every documented expression function, TOML files that are wrong, TOML defaults."""
import dataclasses
import math

import ngsolve as ng
import numpy as np
import pytest

from admmkit.problems.contact import Scene, assemble, example1, load_scene
from admmkit.problems.expressions import FUNCTIONS, expression
from admmkit.problems.contact.model.scene_file import TOML_KEYS

# (expression, the same in Python) for every documented function
CASES = {
    "sqrt": ("sqrt(1 + x)", lambda x, y: math.sqrt(1 + x)),
    "sin": ("sin(x) + y", lambda x, y: math.sin(x) + y),
    "cos": ("cos(2*x)", lambda x, y: math.cos(2 * x)),
    "tan": ("tan(x/4)", lambda x, y: math.tan(x / 4)),
    "exp": ("-10*exp(-x)", lambda x, y: -10 * math.exp(-x)),
    "log": ("log(1 + x + y)", lambda x, y: math.log(1 + x + y)),
    "atan": ("atan(x - 1)", lambda x, y: math.atan(x - 1)),
    "abs": ("abs(x - 1)", lambda x, y: abs(x - 1)),
    "min": ("min(x, 1)", lambda x, y: min(x, 1)),
    "max": ("max(x - 1, 0.5*y)", lambda x, y: max(x - 1, 0.5 * y)),
    "pi": ("pi*x", lambda x, y: math.pi * x),
}


def test_every_documented_function_has_a_case():
    assert set(CASES) == set(FUNCTIONS)


@pytest.mark.parametrize("name", sorted(CASES))
def test_expression_on_floats_and_on_ngsolve_coefficients(name):
    text, exact = CASES[name]
    f = expression(text)
    mesh = ng.Mesh(ng.unit_square.GenerateMesh(maxh=0.5))
    cf = f(ng.x, ng.y)
    for x, y in [(0.1, 0.2), (0.7, 0.9), (0.95, 0.05)]:
        assert f(x, y) == pytest.approx(exact(x, y), rel=1e-14, abs=1e-14)
        assert cf(mesh(x, y)) == pytest.approx(exact(x, y), rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("name", sorted(CASES))
def test_a_traction_with_each_function_assembles_to_its_integral(name):
    """The #16 bug: tractions = {top = ["-10*exp(-x)", 0]} failed with '__import__'."""
    text, exact = CASES[name]
    ops = assemble(example1(h=1 / 8, tractions={"top": [text, 0.0]}))
    full = ops.full_vector(ops.f)
    nx = ops.fes.ndof // 2
    # the x-loads of the top edge sum to the integral of t_x over it (clamped corner x = 0 excluded)
    xs = np.linspace(0, 2, 4001)
    integral = np.trapezoid([exact(x, 1.0) for x in xs], xs)
    top_dofs = [v.nr for v in ops.mesh.vertices if abs(v.point[1] - 1) < 1e-12 and v.point[0] > 1e-12]
    # the clamped corner's hat (1 - 8x)^+ takes its share of the first edge
    xc = np.linspace(0, 1 / 8, 2001)
    corner = np.trapezoid([exact(x, 1.0) * (1 - 8 * x) for x in xc], xc)
    assert full[:nx][top_dofs].sum() == pytest.approx(integral - corner, rel=1e-4, abs=1e-5)


def test_a_python_callable_with_ngsolve_functions_assembles():
    ops = assemble(example1(h=1 / 8, body_force=lambda x, y: (0.0, -ng.exp(-x))))
    assert np.all(np.isfinite(ops.f)) and ops.f.min() < 0


def test_toml_expression_tractions(tmp_path):
    path = tmp_path / "exp.toml"
    path.write_text('L = 2.0\nH = 1.0\nh = 0.25\n[tractions]\ntop = ["-10*exp(-x)", 0]\n')
    ops = assemble(load_scene(path))
    assert ops.f.sum() < 0


# ------------------------------------------------------------------ TOML files that are wrong
BAD = {
    "scene is a string": ('scene = "ex1"\n', "'scene' must be a table"),
    "binary content": (bytes(range(256)) * 2, "not a TOML text file"),
    "h underflows": ("h = 1e-300\n", "h = 1e-300 is too small"),
    "h is zero": ("h = 0.0\n", "h = 0.0 is outside the accepted range"),
    "h is nan": ("h = nan\n", "h = nan is outside"),
    "h is inf": ("h = inf\n", "h = inf is outside"),
    "malformed": ("L = = 2\n", "malformed TOML"),
    "unknown key": ("Young = 2.0\n", "unknown key 'Young'"),
    "wrong type": ('E = "stiff"\n', "key 'E' must be a number"),
    "bool for a number": ("nu = true\n", "key 'nu' must be a number"),
    "keys beside [scene]": ("L = 2.0\n[scene]\nH = 1.0\n", "outside the [scene] table"),
    "traction not a pair": ("[tractions]\ntop = [1, 2, 3]\n", "'tractions.top' must be a pair"),
    "bad expression": ('gap = "__import__(\'os\')"\n', "unknown names"),
    "negative slip bound": ('tangential = "tresca"\nslip_bound = -1.0\n', "slip_bound: negative value"),
    "slip bound not finite": ('tangential = "tresca"\nslip_bound = "1/(x-1)"\n', "slip_bound"),
    "negative mu": ('tangential = "coulomb"\nmu = -0.1\n', "mu = -0.1 is outside"),
    "mu without coulomb": ("mu = 0.3\n", "mu is Coulomb's friction coefficient"),
    "tresca without s": ('tangential = "tresca"\n', "needs a slip bound"),
    "coulomb without mu": ('tangential = "coulomb"\n', "needs a friction coefficient"),
    "slide without friction": ("obstacle_slide = 0.1\n", "acts only with friction"),
    "unknown tangential": ('tangential = "sticky"\n', "tangential = 'sticky'"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_toml_is_a_value_error_naming_the_problem(case, tmp_path):
    content, message = BAD[case]
    path = tmp_path / "scene.toml"
    path.write_bytes(content if isinstance(content, bytes) else content.encode())
    with pytest.raises(ValueError) as err:
        load_scene(path)
    assert message in str(err.value) and str(path) in str(err.value)


def test_missing_file_and_directory_are_value_errors(tmp_path):
    with pytest.raises(ValueError, match="no such scene file"):
        load_scene(tmp_path / "nothing.toml")
    with pytest.raises(ValueError, match="no such scene file"):
        load_scene(tmp_path)


@pytest.mark.parametrize("h", [1e-300, 1e-200, 1e-160])
def test_tiny_h_in_python_is_a_value_error(h):
    with pytest.raises(ValueError, match="h = .* is too small"):
        Scene(h=h)


# ------------------------------------------------------------------ TOML defaults = Scene defaults
def test_an_empty_toml_file_is_the_default_scene(tmp_path):
    path = tmp_path / "empty.toml"
    path.write_text("# every key has Scene's default\n")
    assert load_scene(path) == Scene()


def test_every_toml_key_is_a_scene_field_and_round_trips(tmp_path):
    fields = {f.name for f in dataclasses.fields(Scene)}
    assert set(TOML_KEYS) <= fields
    assert fields - set(TOML_KEYS) == {"geometry"}   # a netgen object has no TOML form
    path = tmp_path / "scene.toml"
    path.write_text('[scene]\nname = "s"\nL = 2.0\ndirichlet = "left"\ntangential = "tresca"\n'
                    'slip_bound = "0.5 + 0.1*x"\nobstacle_slide = 0.01\nbody_force = [0, -1]\n')
    scene = load_scene(path)
    assert scene.dirichlet == ("left",) and scene.contact == "bottom" and scene.h == Scene().h
    assert scene.slip_bound(1.0, 0.0) == pytest.approx(0.6) and scene.obstacle_slide == 0.01


@pytest.mark.parametrize("method", [None, "", "sadm", 3])
def test_solve_scene_names_a_bad_method(method):
    from admmkit.problems.contact import example1, solve_scene
    with pytest.raises(ValueError, match="method must be a name|unknown method"):
        solve_scene(example1(h=1 / 10), method)


def test_caret_is_freefems_power_with_its_precedence():
    """#24: a gap written as in FreeFEM ("0.003*(x-1.5)^2 + 0.001") is a power, not Python's XOR."""
    f = expression("0.003*(x - 1.5)^2 + 0.001")
    assert f(0.5, 0.0) == pytest.approx(0.003 * 1.0 + 0.001, rel=1e-15)
    assert expression("2*x^2")(3.0, 0.0) == 18.0             # the power binds tighter than *
    assert expression("-x^2")(3.0, 0.0) == -9.0
    cf = expression("x^2 + y^3")(ng.x, ng.y)
    mesh = ng.Mesh(ng.unit_square.GenerateMesh(maxh=0.5))
    assert cf(mesh(0.5, 0.5)) == pytest.approx(0.375, rel=1e-12)
