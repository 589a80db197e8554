"""The 2D contact levels' warm start from the last level's displacement on Gamma_C (``warm_trace``)."""
import numpy as np
import pytest

from admmkit.problems.contact import assemble, example1, example2
from admmkit.problems.contact.solvers.adaptive import solve_adaptive
from admmkit.problems.contact.solvers.problem import contact_problem
from admmkit.problems.contact.solvers.warm_trace import contact_trace, trace_at, trace_warm_start
from admmkit.problems.fe import refine_marked


def _field(ops, order):
    """u (free dofs) interpolating a polynomial field of the element's degree: its trace is exact in that degree."""
    import ngsolve as ng
    gf = ng.GridFunction(ops.fes)
    x, y = ng.x, ng.y
    gf.Set(ng.CF((0.3 * x + 0.1 * y, x * x - 0.4 * x * y + 0.2 * y if order == 2 else 0.7 * x - 0.2 * y)))
    return gf.vec.FV().NumPy()[ops.free].copy(), gf


@pytest.mark.parametrize("order", [1, 2])
def test_the_trace_on_a_refined_mesh_is_the_old_fields_trace(order):
    """On nested meshes the old field's trace at the new contact nodes is exact (a field of the element's degree,
    so the new mesh's interpolant is the same field): B u_new there, to round-off."""
    scene = example1(h=1 / 4, order=order)
    ops = assemble(scene)
    u, _ = _field(ops, order)
    trace = contact_trace(contact_problem(ops, mode="condensed"), u)
    mesh = ops.mesh
    refine_marked(mesh, np.arange(mesh.ne) % 3 == 0)
    new = assemble(scene, mesh=mesh)
    u_new, _ = _field(new, order)
    assert new.n_c > ops.n_c
    assert np.abs(trace_at(trace, new.xc)[0] - new.B @ u_new).max() < 1e-12


def test_the_warm_start_has_the_old_trace_and_the_given_multiplier():
    """x0's normal displacement is the old trace (w0 = C^-1 (d - d0)); lam0 is the one given."""
    scene = example2(h=1 / 4, order=2)
    ops = assemble(scene)
    u, _ = _field(ops, 2)
    trace = contact_trace(contact_problem(ops, mode="condensed"), u)
    refine_marked(ops.mesh, np.arange(ops.mesh.ne) % 2 == 0)
    problem = contact_problem(assemble(scene, mesh=ops.mesh), mode="condensed")
    lam0 = np.linspace(0.0, 1.0, problem.ops.n_c)
    start = trace_warm_start(problem, trace, lam0)
    d = trace_at(trace, problem.ops.xc)[0]
    assert np.allclose(problem.apply_A(start["x0"]), d, rtol=0, atol=1e-10 * np.abs(d).max())
    assert start["lam0"] is lam0


def test_the_trace_warm_start_takes_fewer_iterations_than_the_pressure():
    """Example 2 in P2 (nu = 0.49), to 2e-3: the warm levels' iterations against the old start from the
    interpolated pressure (measured 33 against 97 at this target); both reach it."""
    import admmkit.problems.contact.solvers.adaptive as adaptive
    trace = solve_adaptive(example2(h=1 / 5, order=2), 2e-3)
    plain = adaptive.trace_warm_start
    try:
        adaptive.trace_warm_start = lambda problem, trace, lam0: None    # the pressure path
        pressure = solve_adaptive(example2(h=1 / 5, order=2), 2e-3)
    finally:
        adaptive.trace_warm_start = plain
    assert trace.reached and pressure.reached
    warm = [sum(lvl.iterations for lvl in out.levels[1:]) for out in (trace, pressure)]
    assert 2 * warm[0] < warm[1], warm


def test_a_mesh_that_is_not_nested_falls_back_to_the_pressure():
    """A contact node on no old edge: trace_at refuses it by name, the warm start returns None (the caller then
    interpolates the pressure)."""
    ops = assemble(example1(h=1 / 4))
    problem = contact_problem(ops, mode="condensed")
    trace = contact_trace(problem, _field(ops, 1)[0])
    far = ops.xc + np.array([10.0, 0.0])
    with pytest.raises(ValueError, match="trace_at: a point of Gamma_C lies on no old contact edge"):
        trace_at(trace, far)
    with pytest.raises(ValueError, match="trace_at: a point of Gamma_C lies on no old contact edge"):
        trace_at(trace, np.full((3, 2), np.nan))                    # NaN points lie on no edge either
    with pytest.raises(ValueError, match=r"xc must hold one 2D point per row, shape \(points, 2\); got shape \(4,\)"):
        trace_at(trace, np.zeros(4))
    problem.ops = type("Shifted", (), {"xc": far})()
    assert trace_warm_start(problem, trace, np.zeros(ops.n_c)) is None


def test_start_at_makes_z0_the_admissible_part_of_a_x0():
    """z0 = min(g, A x0) (the z-step with lam 0): admissible, and A x0 itself wherever A x0 <= g."""
    from admmkit.problems.contact.solvers.warm_trace import start_at
    problem = contact_problem(assemble(example1(h=1 / 4)), mode="condensed")
    w = np.linspace(-1.0, 1.0, problem.ops.n_c)
    x0 = np.concatenate(([0.0], w * 2 * problem.g.max() / np.abs(problem.C @ w).max()))   # A x0 = C w, in +-2 g
    lam0 = np.ones(problem.ops.n_c)
    start = start_at(problem, x0, lam0)
    Ax = problem.apply_A(x0)
    assert start["x0"] is x0 and start["lam0"] is lam0
    assert np.all(start["z0"] <= problem.g) and np.array_equal(start["z0"] == Ax, Ax <= problem.g)
    assert np.any(Ax > problem.g) and np.any(Ax <= problem.g)          # both cases are exercised
