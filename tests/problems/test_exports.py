"""Exports (issue #18): every VTU read back with meshio, JSON provenance, writes whole or not at all (#16)."""
import dataclasses
import json
import os

import meshio
import numpy as np
import pytest

from admmkit.cli import main
from admmkit.cli.output import write_result_csv
from admmkit.io import write_text
from admmkit.problems.contact import example1, example2, solve_scene
from admmkit.problems.contact.output.export import boundary_fields, contact_status, write_vtu

BOUNDARY = {"contact_pressure", "gap", "initial_gap", "normal_displacement", "contact_status"}


def check_vtu(path, ops, r, n_points, cell_type):
    """Read ``path`` with meshio: point count, cells, arrays; values against the solution itself."""
    mesh = meshio.read(path)
    assert mesh.points.shape == (n_points, 3) and mesh.points.dtype == np.float64
    assert [c.type for c in mesh.cells] == [cell_type] and len(mesh.cells[0].data) == ops.mesh.ne
    assert set(mesh.point_data) == {"displacement"} | BOUNDARY
    disp = mesh.point_data["displacement"]
    assert disp.shape == (n_points, 3) and disp.dtype == np.float64
    # displacement: the finite element function at every 5th point (vertices and P2 midpoints)
    gf = ops.to_gridfunction(r.x)
    dim = ops.mesh.dim
    for i in range(0, n_points, 5):
        assert np.allclose(np.asarray(gf(ops.mesh(*mesh.points[i, :dim]))), disp[i, :dim], rtol=1e-10, atol=1e-14)
    # boundary arrays: at the contact nodes (matched by coordinates), NaN / -1 elsewhere
    on = np.flatnonzero(mesh.point_data["contact_status"] >= 0)
    assert len(on) == ops.n_c
    order = np.lexsort(tuple(mesh.points[on, :dim].T[::-1]))
    where = on[order]
    assert np.allclose(mesh.points[where, :dim], ops.xc[np.lexsort(tuple(ops.xc.T[::-1]))])
    ref_order = np.lexsort(tuple(ops.xc.T[::-1]))
    lam = r.lam[:ops.n_c][ref_order]
    un = (ops.B @ r.x)[ref_order]
    assert np.array_equal(mesh.point_data["contact_pressure"][where], lam)
    assert np.allclose(mesh.point_data["gap"][where], ops.g[ref_order] - un, rtol=0, atol=1e-15)
    off = np.setdiff1d(np.arange(n_points), on)
    assert np.isnan(mesh.point_data["contact_pressure"][off]).all()
    active = int((mesh.point_data["contact_status"] == 1).sum())
    assert active == r.kkt["active_nodes"] == int(contact_status(ops, r.z).sum())     # one definition
    return mesh


def test_solve_contact_vtu_has_shared_vertices_and_boundary_arrays(tmp_path, capsys):
    v, j = tmp_path / "u.vtu", tmp_path / "u.json"
    assert main(["solve", "contact", "--scene", "ex1", "--h", "1/10", "--vtk", str(v),
                 "--json", str(j)]) == 0
    out = capsys.readouterr().out
    sol = solve_scene(example1(1 / 10), "sadmm", 1e3)
    ops, r = sol.ops, sol.result
    check_vtu(v, ops, r, ops.mesh.nv, "triangle")
    assert f"vtk          {v}" in out and f"active nodes {r.kkt['active_nodes']}/{ops.n_c}" in out


def test_p2_vtu_has_quadratic_triangles():
    sol = solve_scene(dataclasses.replace(example2(1 / 10), order=2), "sadmm", 1e3)
    ops, r = sol.ops, sol.result
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        path = write_vtu(os.path.join(tmp, "p2"), ops, r.x, boundary_fields(ops, r.x, r.lam, r.z))
        assert path.name == "p2.vtu"
        check_vtu(path, ops, r, ops.mesh.nv + ops.mesh.nedge, "triangle6")


def test_3d_vtu_is_double_precision_and_meshio_reads_it(tmp_path):
    from admmkit.benchmarks.contact.contact3d import write_vtk
    from admmkit.problems.contact.model.assembly3d import assemble3d
    from admmkit.problems.contact.model.scene3d import example2_3d
    ops = assemble3d(example2_3d(h=1 / 4))
    sol = solve_scene(ops, "sadmm", 1e3)
    path = write_vtk(ops, sol.result.x, sol.result.lam, tmp_path / "sub" / "c3d", p=sol.result.z)
    check_vtu(path, ops, sol.result, ops.mesh.nv, "tetra")


def test_json_provenance_and_the_dof_map(tmp_path, capsys):
    j, v = tmp_path / "r.json", tmp_path / "r.vtu"
    assert main(["solve", "contact", "--scene", "ex2", "--h", "1/10", "--policy", "admm2", "--rho", "1e2",
                 "--tol", "1e-6", "--json", str(j), "--vtk", str(v)]) in (0, 1)
    capsys.readouterr()
    data = json.loads(j.read_text())
    prov = data["provenance"]
    import admmkit
    assert prov["admmkit_version"] == admmkit.__version__
    assert prov["command_line"].startswith("admmkit solve contact --scene ex2 --h 1/10 --policy admm2")
    assert prov["policy"] == "admm2" and prov["order"] == "zx" and prov["rho0"] == 100.0
    assert prov["stopping_rule"] == "relative_change(tol=1e-06)" and prov["max_iter"] == 20000
    assert "T" in prov["date"] and prov["date"].endswith("+00:00")
    scene = data["scene"]
    assert scene["name"] == "example2" and scene["h"] == 0.1 and scene["dirichlet"] == ["left"]
    assert "x" in scene["gap"]                       # the gap expression as text, not a function address
    arrays, sizes = data["arrays"], data["sizes"]
    assert len(arrays["u"]) == sizes["n_free"] == len(arrays["dof_point"]) == len(arrays["dof_component"])
    # the map rebuilds the VTU's displacement from the free dofs
    mesh = meshio.read(v)
    disp = mesh.point_data["displacement"]
    u, comp, point = (np.array(arrays[k]) for k in ("u", "dof_component", "dof_point"))
    assert np.array_equal(disp[point, comp], u)
    assert sizes["n_points"] == len(mesh.points) and sizes["active_nodes"] == int(np.sum(arrays["contact_status"]))
    assert np.array_equal(mesh.point_data["contact_pressure"][arrays["contact_point"]], arrays["contact_pressure"])


# ---------------------------------------------------------------- whole or not at all (fault injection)
def test_vtu_writer_failing_halfway_keeps_the_old_file(tmp_path, monkeypatch):
    sol = solve_scene(example1(1 / 10), "sadmm", 1e3)
    ops, r = sol.ops, sol.result
    path = write_vtu(tmp_path / "u.vtu", ops, r.x)
    good = path.read_bytes()

    def half_then_fail(filename, mesh, file_format=None, **kw):
        with open(filename, "wb") as fh:
            fh.write(good[: len(good) // 2])
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(meshio, "write", half_then_fail)
    with pytest.raises(OSError, match="No space"):
        write_vtu(path, ops, 2 * r.x)
    assert path.read_bytes() == good and sorted(p.name for p in tmp_path.iterdir()) == ["u.vtu"]


def test_history_csv_failing_halfway_keeps_the_old_file(tmp_path, monkeypatch, vector_problem):
    import admmkit
    from admmkit.loop.history import History
    hist = admmkit.solve(vector_problem, max_iter=50).history
    path = hist.to_csv(tmp_path / "h.csv")
    good = path.read_text()
    calls = {"n": 0}
    real = History._row

    def fail_late(self, row):
        calls["n"] += 1
        if calls["n"] > len(self) // 2:
            raise OSError(5, "Input/output error")
        return real(self, row)
    monkeypatch.setattr(History, "_row", fail_late)
    with pytest.raises(OSError):
        hist.to_csv(path)
    assert path.read_text() == good and [p.name for p in tmp_path.iterdir()] == ["h.csv"]


def test_csv_and_json_writers_failing_keep_the_old_file(tmp_path, monkeypatch):
    c = write_result_csv(tmp_path / "r.csv", {"a": [1, 2, 3]})
    good = c.read_text()

    class Bad:
        def __str__(self):
            raise ValueError("cannot format")
    with pytest.raises(ValueError):
        write_result_csv(c, {"a": [4, 5, Bad()]})
    assert c.read_text() == good
    j = write_text(tmp_path / "r.json", '{"ok": 1}')
    import admmkit.io as aio
    monkeypatch.setattr(aio.os, "fsync", lambda fd: (_ for _ in ()).throw(OSError(28, "No space left on device")))
    with pytest.raises(OSError):
        write_text(j, '{"ok": 2, "partial": ')
    assert j.read_text() == '{"ok": 1}' and sorted(p.name for p in tmp_path.iterdir()) == ["r.csv", "r.json"]


def test_boundary_arrays_must_match_the_contact_nodes(tmp_path):
    sol = solve_scene(example1(1 / 10), "sadmm", 1e3)
    with pytest.raises(ValueError, match="one value per contact node"):
        write_vtu(tmp_path / "u", sol.ops, sol.result.x, {"slip": np.zeros(3)})
    with pytest.raises(ValueError, match="one value per contact node"):
        contact_status(sol.ops, np.zeros(2))
