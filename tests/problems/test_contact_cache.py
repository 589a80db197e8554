"""The operator cache of ``admmkit solve contact`` (issue #49): a repeated process reads the assembled problem back
and imports no NGSolve, with the same iterates bit for bit; a damaged or stale entry is rebuilt, never used."""
import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

import admmkit
from admmkit import RelativeChange, policies
from admmkit.problems.contact import contact_problem
from admmkit.problems.contact.model import operator_cache as oc
from admmkit.problems.contact.model.scene import SCENES_DIR
from admmkit.problems.contact.model.scene_file import load_scene

ROOT = Path(__file__).resolve().parents[2]
EX1 = SCENES_DIR / "ex1.toml"


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """An empty cache folder of this test."""
    monkeypatch.setenv(oc.CACHE_DIR_ENV, str(tmp_path / "cache"))
    monkeypatch.delenv(oc.NO_CACHE_ENV, raising=False)
    return tmp_path / "cache" / "contact"


def entries(folder: Path) -> list[Path]:
    return sorted(folder.glob("*.npz")) if folder.is_dir() else []


def run(problem):
    order, rule = policies.method("sadmm")
    return admmkit.solve(problem, rho=1e3, policy=rule, order=order, stop=RelativeChange(1e-5), max_iter=2000)


def bits(a):
    return np.ascontiguousarray(a).view(np.uint8)


def test_a_warm_entry_gives_the_assemblys_arrays_and_iterates_bit_for_bit(cache):
    scene = load_scene(EX1, h=1 / 10)
    notes = []
    cold = oc.cached_operators(scene, EX1, report=notes.append)      # assembled and stored
    assert len(entries(cache)) == 1 and notes == []
    warm = oc.cached_operators(scene, EX1, report=notes.append)      # read back
    assert isinstance(warm, oc.StoredOperators) and not isinstance(cold, oc.StoredOperators) and notes == []
    for name in ("f", "mc", "g", "xc", "normals", "free"):
        assert np.array_equal(bits(getattr(cold, name)), bits(getattr(warm, name))), name
    for name in ("K", "B"):
        a, b = getattr(cold, name), getattr(warm, name)
        assert (a != b).nnz == 0 and np.array_equal(bits(a.data), bits(b.data))
    assert np.array_equal(cold.dof_coordinates(), warm.dof_coordinates())
    assert (warm.dim, warm.n_cells) == (cold.dim, cold.n_cells) == (2, cold.mesh.ne)
    a, b = run(contact_problem(cold)), run(contact_problem(warm))
    assert a.iterations == b.iterations and a.converged
    for u, v in ((a.x, b.x), (a.lam, b.lam), (a.z, b.z)):
        assert np.array_equal(bits(u), bits(v))


@pytest.mark.parametrize("name", ["ex1.toml", "ex1_tresca.toml"])
def test_a_warm_entry_holds_the_condensed_order_and_the_set_up_does_not_order_again(cache, monkeypatch, name):
    """Fails before: every warm process ordered the dofs again (nested dissection, issue #49)."""
    from admmkit.problems.contact.solvers import schur
    path = SCENES_DIR / name
    scene = load_scene(path, h=1 / 10)
    cold = oc.cached_operators(scene, path)
    assert cold.condensed_order is not None
    cold.condensed_order = None                                      # ordered here, as without the cache
    plain = run(contact_problem(cold, mode="condensed"))
    warm = oc.cached_operators(scene, path)
    assert isinstance(warm, oc.StoredOperators) and warm.condensed_order is not None

    def no_ordering(*args, **kwargs):
        raise AssertionError("the warm set-up ordered again")
    monkeypatch.setattr(schur, "contact_last_order", no_ordering)
    problem = contact_problem(warm, mode="condensed")
    assert np.array_equal(problem.schur.order, warm.condensed_order)
    result = run(problem)
    assert result.iterations == plain.iterations
    for u, v in ((result.x, plain.x), (result.z, plain.z), (result.lam, plain.lam)):
        assert np.array_equal(bits(u), bits(v))
    # an order that does not end with the contact dofs is ignored, never used
    warm.condensed_order = warm.condensed_order[::-1].copy()
    monkeypatch.undo()
    assert not np.array_equal(contact_problem(warm, mode="condensed").schur.order, warm.condensed_order)


def test_no_order_is_stored_for_a_full_mode_solve(cache):
    scene = load_scene(EX1, h=1 / 10)
    oc.cached_operators(scene, EX1, mode="full")
    assert oc.cached_operators(scene, EX1).condensed_order is None


def test_a_warm_process_imports_no_ngsolve_and_prints_what_a_cold_one_prints(tmp_path):
    """Fails before the cache: every process imported NGSolve to assemble."""
    code = ("import contextlib, io, sys, json, admmkit.cli\n"
            "out = io.StringIO()\n"
            "with contextlib.redirect_stdout(out):\n"
            "    code = admmkit.cli.main(['solve', 'contact', '--scene', 'ex1', '--h', '1/10'] + sys.argv[1:])\n"
            "print(json.dumps({'code': code, 'ngsolve': 'ngsolve' in sys.modules, 'out': out.getvalue()}))")
    env = {**os.environ, "OMP_NUM_THREADS": "1", oc.CACHE_DIR_ENV: str(tmp_path)}
    env.pop(oc.NO_CACHE_ENV, None)

    def process(*extra):
        done = subprocess.run([sys.executable, "-c", code, *extra], cwd=ROOT, capture_output=True, text=True,
                              timeout=300, env=env)
        assert done.returncode == 0, done.stderr
        return json.loads(done.stdout.strip().splitlines()[-1])
    first, second, bypass = process(), process(), process("--no-cache")
    assert (first["ngsolve"], second["ngsolve"], bypass["ngsolve"]) == (True, False, True)

    def shown(run):          # the printed summary without its timings
        return [line for line in run["out"].splitlines() if not line.startswith(("time", "size"))]
    assert first["code"] == second["code"] == 0
    assert shown(first) == shown(second) == shown(bypass)
    assert "iterations" in first["out"] and "triangles" in first["out"]


def test_no_cache_and_the_environment_variable_read_and_write_nothing(cache, monkeypatch, capsys):
    scene = load_scene(EX1, h=1 / 5)
    ops = oc.cached_operators(scene, EX1, use_cache=False)
    assert not isinstance(ops, oc.StoredOperators) and entries(cache) == []
    monkeypatch.setenv(oc.NO_CACHE_ENV, "1")
    oc.cached_operators(scene, EX1)
    assert entries(cache) == []
    monkeypatch.setenv(oc.NO_CACHE_ENV, "0")                        # "0" means: the cache is on
    oc.cached_operators(scene, EX1)
    assert len(entries(cache)) == 1
    from admmkit.cli import main
    for path in entries(cache):
        path.unlink()
    assert main(["solve", "contact", "--scene", "ex1", "--h", "1/5", "-q", "--no-cache"]) == 0
    assert entries(cache) == []


@pytest.mark.parametrize("damage", ["flip a byte of K", "truncate", "another key", "not a zip"])
def test_a_damaged_entry_is_reported_rebuilt_and_never_used(cache, damage):
    scene = load_scene(EX1, h=1 / 10)
    good = oc.cached_operators(scene, EX1)
    (path,) = entries(cache)
    raw = bytearray(path.read_bytes())
    if damage == "flip a byte of K":                # inside K's values: the zip's CRC or the digest must notice
        with zipfile.ZipFile(path) as z:
            offset = z.getinfo("K.data.npy").header_offset
        names, extra = (int.from_bytes(raw[offset + i:offset + i + 2], "little") for i in (26, 28))
        raw[offset + 30 + names + extra + 200] ^= 0x01                # a byte of the array (after its .npy header)
        path.write_bytes(bytes(raw))
    elif damage == "truncate":
        path.write_bytes(bytes(raw[: len(raw) // 2]))
    elif damage == "another key":                   # an entry written for other operators under this name
        other = oc.cached_operators(load_scene(EX1, h=1 / 5), EX1)
        (path_5,) = [p for p in entries(cache) if p != path]
        path.write_bytes(path_5.read_bytes())
        assert other.n_free != good.n_free
    else:
        path.write_bytes(b"not a zip file at all")
    notes = []
    again = oc.cached_operators(scene, EX1, report=notes.append)
    assert len(notes) == 1 and str(path) in notes[0] and "assembled again" in notes[0]
    assert not isinstance(again, oc.StoredOperators)                 # assembled, not read
    assert again.n_free == good.n_free and np.array_equal(again.f, good.f)
    healed = oc.cached_operators(scene, EX1, report=notes.append)    # the entry was rewritten whole
    assert isinstance(healed, oc.StoredOperators) and len(notes) == 1
    assert np.array_equal(bits(healed.K.data), bits(good.K.data))


def test_the_key_follows_the_scene_the_file_and_the_options(cache, tmp_path):
    scene = load_scene(EX1, h=1 / 10)
    source = EX1.read_bytes()
    key = oc.cache_key(scene, source)
    assert key == oc.cache_key(load_scene(EX1, h=1 / 10), source)
    assert key != oc.cache_key(load_scene(EX1, h=1 / 20), source)
    assert key != oc.cache_key(load_scene(EX1, h=1 / 10, order=2), source)
    assert key != oc.cache_key(scene, source + b"\n# an edit\n")
    import dataclasses
    assert key != oc.cache_key(dataclasses.replace(scene, tangential="tresca", slip_bound=0.1), source)


def test_what_cannot_be_keyed_is_not_cached(cache):
    from admmkit.problems.contact.model.scene import Scene
    assert oc.cacheable(load_scene(EX1))
    assert not oc.cacheable(Scene(h=0.25, gap=lambda x, y: 0.01 * x))      # a Python function has no text
    assert oc.cacheable(Scene(h=0.25, gap="0.01*x"))                       # an expression has
    assert not oc.cacheable(load_scene(SCENES_DIR / "block3d.toml"))       # 3D: assembled by assembly3d


def test_the_mesh_is_rebuilt_on_demand_and_checked(cache):
    """An output that needs the mesh (plot, VTU, JSON) gets it from NGSolve when it asks; the points, the
    displacement at them and the dof map are those of the assembled operators."""
    from admmkit.problems.contact.output.export import free_dof_map, mesh_points, point_displacement
    scene = load_scene(EX1, h=1 / 10, order=2)
    cold = oc.cached_operators(scene, EX1)
    warm = oc.cached_operators(scene, EX1)
    assert isinstance(warm, oc.StoredOperators) and warm._space is None
    u = np.linspace(0.0, 1.0, cold.n_free)
    for a, b in zip(mesh_points(cold), mesh_points(warm)):
        assert np.array_equal(a, b) if isinstance(a, np.ndarray) else a == b
    assert np.array_equal(point_displacement(cold, u), point_displacement(warm, u))
    assert all(np.array_equal(v, free_dof_map(warm)[k]) for k, v in free_dof_map(cold).items())
    assert warm._space is not None


def test_a_rebuilt_mesh_that_differs_is_an_error(cache):
    scene = load_scene(EX1, h=1 / 10)
    oc.cached_operators(scene, EX1)
    warm = oc.cached_operators(scene, EX1)
    warm._vertices = warm._vertices + 1e-3            # as if the mesher had moved a point since the entry was made
    with pytest.raises(oc.CacheMismatch, match="--no-cache"):
        warm.mesh


def test_an_unwritable_cache_costs_a_note_only(tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("a file where the cache folder should go")
    monkeypatch.setenv(oc.CACHE_DIR_ENV, str(blocker))
    monkeypatch.delenv(oc.NO_CACHE_ENV, raising=False)
    notes = []
    ops = oc.cached_operators(load_scene(EX1, h=1 / 5), EX1, report=notes.append)
    assert ops.n_free > 0 and len(notes) == 1 and "could not write" in notes[0]


def test_solve_contact_writes_plot_vtk_and_json_from_the_cache(cache, tmp_path, capsys):
    """The outputs that need the mesh work from a warm entry, and the JSON's u is the cold run's bit for bit."""
    from admmkit.cli import main
    args = ["solve", "contact", "--scene", "ex1", "--h", "1/10", "-q"]
    assert main(args + ["--json", str(tmp_path / "cold.json")]) == 0
    assert len(entries(cache)) == 1
    assert main(args + ["--json", str(tmp_path / "warm.json"), "--vtk", str(tmp_path / "warm.vtu"),
                        "--plot", str(tmp_path / "warm.png")]) == 0
    cold, warm = (json.loads((tmp_path / f"{n}.json").read_text()) for n in ("cold", "warm"))
    for name in ("u", "lam", "dof_point", "contact_point"):
        assert cold["arrays"][name] == warm["arrays"][name], name
    assert (tmp_path / "warm.vtu").stat().st_size > 0 and (tmp_path / "warm.png").stat().st_size > 0
