"""``admmkit solve contact`` with friction (issue #19): the options, the summary and every output read back."""
import csv
import json
import re

import meshio
import numpy as np
import pytest

from admmkit.cli import main
from admmkit.problems.contact import load_scene, solve_scene

TRESCA = ["solve", "contact", "--scene", "ex1_tresca", "--h", "1/10"]
COULOMB = ["solve", "contact", "--scene", "ex1_coulomb", "--h", "1/10"]
BLOCK = ["solve", "contact", "--scene", "block3d_coulomb"]          # its coarsest size, h = 1/8


def run(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def outputs(tmp_path):
    files = {k: tmp_path / f"r.{k}" for k in ("csv", "json", "vtu")}
    return files, ["--csv", str(files["csv"]), "--json", str(files["json"]), "--vtk", str(files["vtu"])]


def read_csv(path):
    rows = list(csv.DictReader(path.open()))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def line(out, label):
    return next(x for x in out.splitlines() if x.startswith(label))


def check_outputs(files, sol):
    """CSV, JSON and VTU against the solution of the same scene solved in Python (the same run)."""
    ops, r = sol.ops, sol.result
    q, slip, zones = sol.tangential_traction, sol.slip, sol.zones          # (d-1, n_c), (d-1, n_c), (n_c,)
    k = q.shape[0]
    table = read_csv(files["csv"])
    names = ["q"] if k == 1 else ["q_1", "q_2"]
    slips = ["slip"] if k == 1 else ["slip_1", "slip_2"]
    for j in range(k):
        assert np.allclose(table[names[j]], q[j], rtol=1e-12, atol=1e-15)
        assert np.allclose(table[slips[j]], slip[j], rtol=1e-12, atol=1e-15)
    assert np.array_equal(table["zone"], zones) and np.allclose(table["lam"], sol.pressure, rtol=1e-12, atol=1e-15)
    assert np.allclose(table["s"], ops.friction.s, rtol=1e-12, atol=1e-15)
    data = json.loads(files["json"].read_text())
    arrays, sizes = data["arrays"], data["sizes"]
    assert np.allclose(np.reshape(arrays["tangential_traction"], (ops.n_c, k)), q.T, rtol=1e-12, atol=1e-15)
    assert np.allclose(np.reshape(arrays["slip"], (ops.n_c, k)), slip.T, rtol=1e-12, atol=1e-15)
    assert arrays["stick_slip_zone"] == zones.tolist()
    assert sizes["stick_nodes"] == int(np.sum(zones == 1)) == r.kkt["stick_nodes"]
    assert sizes["slip_nodes"] == int(np.sum(zones == 2)) == r.kkt["slip_nodes"]
    assert data["result"]["friction"]["law"] == ops.friction.law
    mesh = meshio.read(files["vtu"])
    where = np.array(arrays["contact_point"])
    tangents = ops.tangents                                                  # (n_c, d-1, d)
    vectors = np.einsum("ji,ijk->ik", q, tangents)
    traction = mesh.point_data["tangential_traction"]
    assert traction.shape == (len(mesh.points), 3)
    assert np.allclose(traction[where, :tangents.shape[2]], vectors, rtol=1e-12, atol=1e-15)
    assert np.allclose(mesh.point_data["slip"][where, :tangents.shape[2]], np.einsum("ji,ijk->ik", slip, tangents),
                       rtol=1e-12, atol=1e-15)
    zone = mesh.point_data["stick_slip_zone"]
    off = np.setdiff1d(np.arange(len(mesh.points)), where)
    assert np.array_equal(zone[where], zones) and np.all(zone[off] == -1) and np.isnan(traction[off]).all()
    return data


def check_friction_law(sol, atol):
    """|q| <= s everywhere; |q| = s where a node slips (the discrete Tresca conditions)."""
    length = np.linalg.norm(sol.tangential_traction, axis=0)
    s = sol.ops.friction.s
    assert np.all(length <= s + atol)
    slipping = sol.zones == 2
    assert slipping.any() and np.allclose(length[slipping], s[slipping], atol=atol)


def test_tresca_scene_outputs(tmp_path, capsys):
    files, flags = outputs(tmp_path)
    code, out, _ = run([*TRESCA, *flags], capsys)
    sol = solve_scene(load_scene("ex1_tresca", h=0.1), "sadmm", 1e3)
    assert code == 0 and "tangential tresca" in line(out, "problem")
    zones = np.bincount(sol.zones, minlength=3)
    friction = line(out, "friction")
    assert f"stick nodes {zones[1]}   slip nodes {zones[2]}   separated {zones[0]}" in friction
    assert f"tangential force {float(sol.ops.mc @ sol.tangential_traction[0]):.6g}" in friction
    assert "coulomb " not in out                                          # no outer iteration with Tresca
    check_outputs(files, sol)
    check_friction_law(sol, atol=1e-3 * sol.ops.friction.s.max())


def test_coulomb_scene_outputs_and_the_outer_iteration(tmp_path, capsys):
    files, flags = outputs(tmp_path)
    code, out, _ = run([*COULOMB, *flags], capsys)
    sol = solve_scene(load_scene("ex1_coulomb", h=0.1), "sadmm", 1e3)
    assert code == 0 and sol.converged
    untimed = lambda text: re.sub(r"[0-9.]+ s$", "<t> s", text)         # wall time differs between two runs
    assert untimed(line(out, "coulomb ")) == untimed(f"coulomb      {sol.coulomb.summary()}")
    data = check_outputs(files, sol)
    report = data["result"]["coulomb"]
    assert report["outer_iterations"] == sol.coulomb.outer_iterations >= 2
    assert report["inner_iterations"] == sol.coulomb.inner_iterations and report["converged"] is True
    # Coulomb: the last slip bound is mu p_n of the previous step, so |q| <= mu p_n to the fixed point's change
    check_friction_law(sol, atol=1e-3 * sol.ops.friction.s.max())
    assert np.allclose(sol.ops.friction.s, 0.3 * np.maximum(sol.pressure, 0),
                       atol=10 * sol.coulomb.changes[-1] * sol.ops.friction.s.max())


def test_block3d_coulomb_outputs(tmp_path, capsys):
    files, flags = outputs(tmp_path)
    code, out, _ = run([*BLOCK, *flags], capsys)
    sol = solve_scene(load_scene("block3d_coulomb"), "sadmm", 1e3)
    assert code == 0 and "tetrahedra" in line(out, "problem")
    assert read_csv(files["csv"]).keys() >= {"x", "y", "z", "q_1", "q_2", "slip_1", "slip_2", "s", "zone"}
    force = sol.ops.mc @ sol.tangential_traction.T
    assert f"tangential force ({force[0]:.6g}, {force[1]:.6g})" in line(out, "friction")
    data = check_outputs(files, sol)
    assert np.array(data["arrays"]["tangents"]).shape == (sol.ops.n_c, 2, 3)


def test_options_override_the_scene(tmp_path, capsys):
    """--tangential/--slip-bound on the frictionless ex1 give the ex1_tresca run; --mu overrides the scene's."""
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert run(["solve", "contact", "--scene", "ex1", "--h", "1/10", "--tangential", "tresca", "--slip-bound", "2",
                "--csv", str(a)], capsys)[0] == 0
    assert run([*TRESCA, "--csv", str(b)], capsys)[0] == 0
    assert a.read_text() == b.read_text()
    code, out, _ = run([*COULOMB, "--mu", "0.1", "--csv", str(a)], capsys)
    sol = solve_scene(load_scene("ex1_coulomb", h=0.1, mu=0.1), "sadmm", 1e3)
    assert code == 0 and "coulomb (mu 0.1)" in line(out, "friction")
    assert np.allclose(read_csv(a)["q"], sol.tangential_traction[0], rtol=1e-12, atol=1e-15)
    code, out, _ = run([*COULOMB, "--tangential", "frictionless", "--csv", str(a)], capsys)
    assert code == 0 and "friction " not in out and "coulomb " not in out and "q" not in read_csv(a)
    code, out, _ = run([*TRESCA, "--tangential", "coulomb", "--mu", "0.3"], capsys)
    assert code == 0 and line(out, "coulomb ").startswith("coulomb      Coulomb fixed point")
    code, out, _ = run([*TRESCA, "--slip-bound", "1 + x"], capsys)            # an expression in x, y
    assert code == 0 and "tresca" in line(out, "friction")


def test_plot_marks_the_zones(tmp_path, capsys):
    png = tmp_path / "c.png"
    code, out, _ = run([*COULOMB, "--plot", str(png)], capsys)
    assert code == 0 and png.stat().st_size > 10_000 and f"plot         {png}" in out


BAD = [
    (COULOMB + ["--mu", "-0.1"], "--mu -0.1: expected Coulomb's friction coefficient"),
    (COULOMB + ["--mu", "nan"], "--mu nan"),
    (COULOMB + ["--mu", "abc"], "--mu abc"),
    (TRESCA + ["--mu", "0.3"], "--mu is Coulomb's friction coefficient; it needs --tangential coulomb"),
    (COULOMB + ["--slip-bound", "2"], "--slip-bound is Tresca's slip bound; it needs --tangential tresca"),
    (TRESCA + ["--slip-bound", "-2"], "--slip-bound -2: expected Tresca's slip bound"),
    (TRESCA + ["--slip-bound", "x - 5"], "--slip-bound x - 5: slip_bound: negative value"),                  # negative along Gamma_C
    (TRESCA + ["--slip-bound", "foo(x)"], "--slip-bound foo(x): expression"),
    (["solve", "contact", "--scene", "ex1", "--h", "1/10", "--tangential", "tresca"], "needs --slip-bound S"),
    (["solve", "contact", "--scene", "ex1", "--h", "1/10", "--tangential", "coulomb"], "needs --mu MU"),
    (TRESCA + ["--tangential", "stick", "--slip-bound", "1"], "needs --tangential tresca (--tangential stick)"),
    (TRESCA + ["--tangential", "glue"], "--tangential"),
    (BLOCK + ["--plot", "x.png"], "--plot draws 2D scenes only"),
]


@pytest.mark.parametrize("argv, needle", BAD)
def test_bad_friction_options_are_one_line_and_exit_2(argv, needle, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(argv, capsys)
    assert code == 2 and needle in err and "Traceback" not in err
    assert "status" not in out and not any(tmp_path.iterdir())
    if "--tangential" not in argv or "glue" not in argv:                  # (argparse adds its usage line)
        assert len(err.strip().splitlines()) == 1


def test_a_coulomb_result_describes_the_whole_fixed_point(tmp_path, capsys):
    """#27 item 2: the headline (and Result, JSON) count every Tresca solve; the last one is the detail."""
    sol = solve_scene(load_scene("ex1_coulomb", h=1 / 20), "sadmm", 1e3)
    report, whole, last = sol.coulomb, sol.result, sol.coulomb.last
    assert report.outer_iterations > 1 and whole.iterations == report.total_iterations > last.iterations
    assert whole.factorizations >= last.factorizations and whole.factorizations > 0
    assert whole.timings["total"] > last.timings["total"]
    assert np.array_equal(whole.x, last.x) and whole.converged == sol.converged
    code, out, _ = run(["solve", "contact", "--scene", "ex1_coulomb", "--h", "1/20", "-q",
                        "--json", str(tmp_path / "c.json")], capsys)
    assert code == 0
    assert f"iterations   {report.total_iterations} " in out
    assert f"last Tresca solve: converged, {last.iterations} iterations" in out
    assert json.loads((tmp_path / "c.json").read_text())["result"]["iterations"] == report.total_iterations
