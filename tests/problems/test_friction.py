"""Friction (#19): Tresca against an independent cvxpy/Clarabel solve (2D and 3D, full and condensed
modes), Coulomb's fixed point, stick/slip zones, bad input."""
import numpy as np
import pytest

from admmkit import ResidualTolerance
from admmkit.problems.contact import Scene, assemble, example1, example2, solve_scene
from admmkit.problems.contact.solvers.coulomb import coulomb_fixed_point
from admmkit.problems.contact.solvers.friction import Friction, friction_z_step, shrink, tangent_frames
from admmkit.problems.contact.model.assembly3d import assemble3d
from admmkit.problems.contact.model.scene3d import Scene3D, example2_3d
from admmkit.problems.contact.solvers.tresca_qp import tresca_cvxpy

TIGHT = ResidualTolerance(1e-12, 1e-12)


def block3d(**changes):
    """A small 3D block with stick and slip nodes: sheared on top, curved gap, the foundation moved."""
    fields = dict(Lx=2.0, h=1 / 4, E=100.0, nu=0.3, tractions={"top": (0.5, 0.2, -2.0)},
                  gap="0.002*(x-1)**2 + 0.001*(y-0.5)**2", tangential="tresca", slip_bound="0.3 + 0.1*x",
                  obstacle_slide=(0.001, 0.0))
    return Scene3D(**(fields | changes))


CASES = {
    "ex1 P1 s=2": lambda: assemble(example1(h=1 / 10, tangential="tresca", slip_bound=2.0)),
    "ex1 P2 s(x) slide": lambda: assemble(example1(h=1 / 20, order=2, tangential="tresca", slip_bound="1 + x",
                                                   obstacle_slide=0.002)),
    "ex2 P1 s(x)": lambda: assemble(example2(h=1 / 10, tangential="tresca", slip_bound="0.2 + 0.1*x")),
    "3D block": lambda: assemble3d(block3d()),
}


@pytest.fixture(scope="module", params=sorted(CASES))
def case(request):
    ops = CASES[request.param]()
    return request.param, ops, tresca_cvxpy(ops)


@pytest.mark.parametrize("mode", ["full", "condensed"])
def test_tresca_matches_clarabel(case, mode):
    name, ops, (u_ref, p_ref, q_ref) = case
    if mode == "full" and "P2" in name:
        # admmkit.linalg.linsolve's superlu (MMD on A'+A) fills this P2 matrix to 1.3e7 nonzeros (20 s a
        # factorisation, frictionless too); the full and condensed modes' agreement is checked in 3D below
        pytest.skip("full mode on P2: superlu MMD fill (admmkit.linalg.linsolve), not a friction matter")
    sol = solve_scene(ops, "sadmm", rho=1e3, mode=mode, stop=TIGHT)
    assert sol.result.converged and sol.mode == mode
    rel = lambda a, b: np.linalg.norm(a - b) / np.linalg.norm(b)  # noqa: E731
    assert rel(sol.u, u_ref) <= 1e-6
    assert rel(sol.pressure, p_ref) <= 1e-6
    assert rel(sol.tangential_traction, q_ref) <= 1e-6
    kkt = sol.result.kkt
    assert kkt["friction_bound"] < 1e-9 and kkt["slip_complementarity"] < 1e-9 and kkt["stationarity"] < 1e-9
    assert np.all(np.linalg.norm(sol.tangential_traction, axis=0) <= ops.friction.s * (1 + 1e-9))


def test_stick_and_slip_zones_are_both_present_and_consistent():
    ops = CASES["ex1 P2 s(x) slide"]()
    sol = solve_scene(ops, "sadmm", rho=1e3, stop=TIGHT)
    zones, slip = sol.zones, np.linalg.norm(sol.slip, axis=0)
    q = np.linalg.norm(sol.tangential_traction, axis=0)
    assert (zones == 1).sum() >= 3 and (zones == 2).sum() >= 3
    assert slip[zones == 1].max() < 1e-8 * slip.max()              # stick: no slip
    assert np.allclose(q[zones == 2], ops.friction.s[zones == 2], rtol=1e-8)   # slip: |q| = s
    # q points along the slip where the node slips
    qt, st = sol.tangential_traction[0], sol.slip[0]
    assert np.all(np.sign(qt[zones == 2]) == np.sign(st[zones == 2]))


def test_full_condensed_iterative_agree_on_3d_tresca():
    ops = assemble3d(block3d())
    full = solve_scene(ops, "sadmm", rho=1e3, mode="full")
    cond = solve_scene(ops, "sadmm", rho=1e3, mode="condensed")
    it = solve_scene(ops, "sadmm", rho=1e3, mode="iterative")
    assert full.result.iterations == cond.result.iterations
    assert np.abs(full.u - cond.u).max() <= 1e-9 * np.abs(full.u).max()
    assert np.abs(full.u - it.u).max() <= 1e-4 * np.abs(full.u).max()


def test_zero_slip_bound_is_frictionless_and_huge_bound_sticks():
    free = solve_scene(example1(h=1 / 10), "sadmm", rho=1e3, stop=TIGHT)
    zero = solve_scene(example1(h=1 / 10, tangential="tresca", slip_bound=0.0), "sadmm", rho=1e3, stop=TIGHT)
    assert np.abs(free.u - zero.u).max() <= 1e-8 * np.abs(free.u).max()
    assert np.abs(zero.tangential_traction).max() <= 1e-9 * zero.pressure.max()
    stuck = solve_scene(example1(h=1 / 10, tangential="tresca", slip_bound=1e6), "sadmm", rho=1e3, stop=TIGHT)
    assert np.abs(stuck.slip).max() < 1e-9 and np.all(stuck.zones[stuck.zones > 0] == 1)


def test_coulomb_fixed_point_converges_and_is_a_tresca_solution_with_s_mu_p():
    mu = 0.3
    sol = solve_scene(example1(h=1 / 10, tangential="coulomb", mu=mu), "sadmm", rho=1e3, stop=TIGHT,
                      coulomb_tol=1e-8)
    rep = sol.coulomb
    assert rep.converged and sol.converged and rep.outer_iterations >= 3
    assert rep.changes[0] == 1.0 and all(b < a for a, b in zip(rep.changes, rep.changes[1:]))
    p, q = sol.pressure, sol.tangential_traction[0]
    assert np.all(np.abs(q) <= mu * np.maximum(p, 0) * (1 + 1e-6) + 1e-9)
    assert (sol.zones == 1).any() and (sol.zones == 2).any()
    # Coulomb's solution solves the Tresca problem with its own slip bound mu p_n
    u_ref, p_ref, q_ref = tresca_cvxpy(sol.ops, s=mu * np.maximum(p, 0))
    assert np.linalg.norm(sol.u - u_ref) <= 1e-6 * np.linalg.norm(u_ref)
    assert np.linalg.norm(q - q_ref[0]) <= 1e-5 * np.linalg.norm(q_ref)


def test_coulomb_mu_zero_is_frictionless_in_one_step():
    sol = solve_scene(example1(h=1 / 10, tangential="coulomb", mu=0.0), "sadmm", rho=1e3, stop=TIGHT)
    free = solve_scene(example1(h=1 / 10), "sadmm", rho=1e3, stop=TIGHT)
    assert sol.coulomb.outer_iterations == 1 and sol.coulomb.converged
    assert np.allclose(sol.u, free.u, rtol=0, atol=1e-9 * np.abs(free.u).max())


def test_coulomb_3d_converges():
    sol = solve_scene(block3d(tangential="coulomb", slip_bound=None, mu=0.2), "sadmm", rho=1e3,
                      stop=ResidualTolerance(1e-9, 1e-9))
    assert sol.converged and sol.coulomb.outer_iterations >= 2
    q = np.linalg.norm(sol.tangential_traction, axis=0)
    assert np.all(q <= 0.2 * np.maximum(sol.pressure, 0) * (1 + 1e-3) + 1e-6)


def test_the_z_step_is_the_weighted_prox():
    rng = np.random.default_rng(1)
    n_c = 7
    g, s, rho = rng.random(n_c) * 0.01, rng.random(n_c), 3.0
    v = rng.standard_normal(3 * n_c)
    z = friction_z_step(v, g, s, rho, None)
    assert np.array_equal(z[:n_c], np.minimum(g, v[:n_c]))
    vt, zt = v[n_c:].reshape(2, n_c), z[n_c:].reshape(2, n_c)
    for i in range(n_c):     # the prox of (s/rho)|.| in R^2: a shrink of the length, direction kept
        r = np.linalg.norm(vt[:, i])
        assert np.allclose(zt[:, i], max(0.0, 1 - s[i] / rho / r) * vt[:, i])
    assert np.array_equal(shrink(np.array([[0.5, -2.0]]), np.array([1.0, 1.0])), np.array([[0.0, -1.0]]))


def test_tangent_frames_are_orthonormal():
    n2 = np.array([[0.0, -1.0], [0.6, 0.8]])
    t2 = tangent_frames(n2)
    assert np.allclose(t2[0, 0], [1.0, 0.0]) and np.allclose(np.sum(t2[:, 0] * n2, axis=1), 0)
    rng = np.random.default_rng(0)
    n3 = rng.standard_normal((5, 3)); n3 /= np.linalg.norm(n3, axis=1, keepdims=True)
    n3 = np.vstack([[0.0, 0.0, -1.0], n3])
    t3 = tangent_frames(n3)
    frame = np.concatenate([t3, n3[:, None, :]], axis=1)
    assert np.allclose(frame @ frame.transpose(0, 2, 1), np.eye(3))
    assert np.allclose(t3[0], [[1, 0, 0], [0, 1, 0]])


@pytest.mark.parametrize("changes, match", [
    (dict(tangential="coulomb", mu=-0.1), "mu = -0.1 is outside"),
    (dict(tangential="coulomb", mu=float("nan")), "mu = nan is outside"),
    (dict(tangential="coulomb", mu=float("inf")), "mu = inf is outside"),
    (dict(tangential="coulomb", mu="0.3"), "mu = '0.3' is outside"),
    (dict(tangential="coulomb"), "needs a friction coefficient"),
    (dict(tangential="tresca", slip_bound=-1.0), "slip_bound: negative value"),
    (dict(tangential="tresca", slip_bound=float("nan")), "slip_bound: not finite"),
    (dict(tangential="tresca", slip_bound=float("inf")), "slip_bound: not finite"),
    (dict(tangential="tresca", slip_bound="x - 1"), "slip_bound: negative value"),
    (dict(tangential="tresca", slip_bound="log(x)"), "slip_bound"),
    (dict(tangential="tresca"), "needs a slip bound"),
    (dict(slip_bound=1.0), "slip_bound is Tresca's"),
    (dict(tangential="stick", mu=0.3), "mu is Coulomb's"),
    (dict(tangential="tresca", slip_bound=1.0, obstacle_slide=float("nan")), "obstacle_slide"),
    (dict(obstacle_slide=0.01), "acts only with friction"),
    (dict(tangential="tresca", slip_bound=1.0, contact=""), "contact"),
    (dict(tangential="coulomb", mu=0.3, contact="floor"), "contact: unknown boundary label 'floor'"),
])
def test_bad_friction_input_2d(changes, match):
    with pytest.raises(ValueError, match=match):
        example1(h=1 / 10, **changes)


@pytest.mark.parametrize("changes, match", [
    (dict(tangential="coulomb", mu=-1.0), "mu = -1.0 is outside"),
    (dict(tangential="tresca", slip_bound=-0.5), "slip_bound: negative value"),
    (dict(tangential="tresca", slip_bound=0.5, obstacle_slide=(0.1,)), "obstacle_slide"),
    (dict(obstacle_slide=(0.1, 0.0)), "acts only with friction"),
    (dict(tangential="sliding"), "tangential = 'sliding'"),
])
def test_bad_friction_input_3d(changes, match):
    with pytest.raises(ValueError, match=match):
        example2_3d(h=1 / 2, **changes)


def test_bad_friction_objects():
    with pytest.raises(ValueError, match="friction law"):
        Friction("amontons", np.zeros(3))
    with pytest.raises(ValueError, match="slip_bound: negative"):
        Friction("tresca", -np.ones(3))
    ops = assemble(example1(h=1 / 4, tangential="coulomb", mu=0.1))
    from admmkit.problems.contact.solvers.problem import contact_problem
    with pytest.raises(ValueError, match="coulomb tol"):
        coulomb_fixed_point(contact_problem(ops), lambda warm: None, 0.1, tol=0.0)


def test_frictionless_and_stick_keep_their_meaning():
    """The default stays frictionless; 'stick' (the literal eq. (1)) still clamps u_t."""
    assert Scene().tangential == "frictionless" and example1().tangential == "frictionless"
    ops = assemble(example1(h=1 / 10, tangential="stick"))
    assert ops.friction is None and ops.T.nnz == 0     # the tangential component is a Dirichlet dof
    sol = solve_scene(ops, "sadmm", rho=1e3)
    assert sol.tangential_traction is None and sol.zones is None and sol.result.lam.size == ops.n_c
