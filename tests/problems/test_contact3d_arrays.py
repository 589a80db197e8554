"""The structured P1 block built from arrays (assemble3d's route "arrays") against NGSolve's route."""
import subprocess
import sys

import numpy as np
import pytest

from admmkit.problems.contact.model.assembly3d import BlockOperators3D, assemble3d
from admmkit.problems.contact.model.scene3d import Scene3D, block_arrays, block_mesh, example2_3d
from admmkit.problems.contact.solvers.iterative import near_null_space

SCENES = {
    "block3d": lambda: example2_3d(h=1 / 6),
    "stick": lambda: example2_3d(h=1 / 4, tangential="stick"),
    "symmetry, two loads": lambda: Scene3D(Lx=2.0, h=1 / 4, symmetry=("left",), gap=0.01,
                                           tractions={"top": (0.0, 0.0, -1.0), "front": (1.0, 0.5, -2.0)}),
}


@pytest.mark.parametrize("name", SCENES)
def test_the_arrays_route_gives_ngsolves_operators(name):
    scene = SCENES[name]()
    fast, slow = assemble3d(scene), assemble3d(scene, route="ngsolve")
    assert isinstance(fast, BlockOperators3D) and not isinstance(slow, BlockOperators3D)
    for key in ("free", "mc", "g", "xc", "normals", "tangents"):
        assert np.array_equal(getattr(fast, key), getattr(slow, key)), key
    for key in ("K", "B", "T"):            # the same numbering, pattern and values, bit for bit
        A, B = getattr(fast, key), getattr(slow, key)
        assert np.array_equal(A.indptr, B.indptr) and np.array_equal(A.indices, B.indices), key
        assert np.array_equal(A.data, B.data), key
    assert np.abs(fast.f - slow.f).max() <= 1e-15 * np.abs(slow.f).max()     # NGSolve sums in another order
    assert np.abs(slow.f).max() > 0
    assert (fast.dim, fast.n_cells, fast.n_free, fast.n_c) == (slow.dim, slow.n_cells, slow.n_free, slow.n_c)
    assert np.array_equal(fast.dof_coordinates(), slow.dof_coordinates())
    for a, b in zip(near_null_space(fast), near_null_space(slow)):
        assert np.array_equal(a, b)
    u = np.random.default_rng(0).standard_normal(fast.n_free)
    assert np.array_equal(fast.full_vector(u), slow.full_vector(u))


def test_the_mesh_and_space_are_made_when_asked_and_match():
    scene = example2_3d(h=1 / 4)
    ops = assemble3d(scene)
    assert ops._space is None
    assert ops.mesh.nv == ops.vertices.shape[0] and ops.mesh.ne == ops.n_cells
    assert np.array_equal(np.flatnonzero(np.array(ops.fes.FreeDofs(), dtype=bool)), ops.free)
    assert np.array_equal(np.array(ops.mesh.ngmesh.Coordinates()), ops.vertices)
    gf = ops.to_gridfunction(np.ones(ops.n_free))
    assert gf.vec.FV().NumPy()[ops.free].min() == 1.0
    ops.free = ops.free[1:]                        # arrays that no longer fit NGSolve's space: an error
    ops._space = None
    with pytest.raises(RuntimeError, match="NGSolve's space of the block"):
        ops.fes


def test_block_arrays_are_block_meshs():
    points, tets, faces = block_arrays(3.0, 1.0, 1.0, 1 / 3)
    mesh = block_mesh(3.0, 1.0, 1.0, 1 / 3)
    assert np.array_equal(np.array(mesh.ngmesh.Coordinates()), points)
    assert np.array_equal(mesh.ngmesh.Elements3D().NumPy()["nodes"][:, :4] - 1, tets)
    surface = mesh.ngmesh.Elements2D().NumPy()
    labels = np.array(mesh.GetBoundaries())[surface["index"] - 1]
    for name, tris in faces.items():
        assert np.array_equal(surface["nodes"][labels == name, :3] - 1, tris), name


def test_the_other_routes_and_bad_input():
    p2 = assemble3d(example2_3d(h=1 / 2, order=2))               # P2: NGSolve's route
    assert not isinstance(p2, BlockOperators3D)
    assert not isinstance(assemble3d(example2_3d(h=1 / 2), stiffness="ngsolve"), BlockOperators3D)
    with pytest.raises(ValueError, match="route = 'netgen'; accepted: arrays, ngsolve"):
        assemble3d(example2_3d(h=1 / 2), route="netgen")


def test_the_arrays_route_imports_no_ngsolve():
    code = ("import sys\n"
            "from admmkit.problems.contact.model.assembly3d import assemble3d\n"
            "from admmkit.problems.contact.model.scene3d import example2_3d\n"
            "from admmkit.problems.contact.solvers.problem import contact_problem\n"
            "contact_problem(assemble3d(example2_3d(h=1 / 4)), mode='iterative')\n"
            "print('ngsolve' in sys.modules, 'netgen' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]
