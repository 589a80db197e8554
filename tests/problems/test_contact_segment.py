"""The condensed mode's compiled steps and segment (issue #49): the same run as numpy's steps, the segment's
iterates those of the Python steps bit for bit, and the numpy/LAPACK path still taken where no compiled code runs."""
import numpy as np
import pytest

import admmkit
from admmkit import RelativeChange, policies
from admmkit.kernels import AVAILABLE, compiled_code
from admmkit.problems.contact import assemble, contact_problem, example1, example2
from admmkit.problems.contact.solvers import condensed_segment as cs

pytestmark = pytest.mark.skipif(not AVAILABLE, reason="numba is not installed")


@pytest.fixture(scope="module", params=["example1", "example2"])
def ops(request):
    scene = {"example1": example1, "example2": example2}[request.param]
    return assemble(scene(1 / 10))


def run(ops, steps_compiled: bool, segments: bool = True, method: str = "sadmm", **options):
    """A condensed run with the compiled steps (or numpy's) and the loop's segments on (or off)."""
    problem = contact_problem(ops, mode="condensed", backend="superlu")
    order, rule = policies.method(method)
    with compiled_code(steps_compiled):
        result = admmkit.solve(problem, rho=1e3, policy=rule, order=order, stop=RelativeChange(1e-5),
                               max_iter=2000, compiled=segments, **options)
    return problem, result


def rho_path(result) -> np.ndarray:
    return np.asarray(result.history["rho"])


def test_compiled_steps_give_the_numpy_run(ops):
    _, numpy_run = run(ops, False)
    problem, compiled_run = run(ops, True)
    assert problem.compiled_steps and compiled_run.counters["compiled_iterations"] == compiled_run.iterations
    assert compiled_run.iterations == numpy_run.iterations
    assert compiled_run.status == numpy_run.status
    assert compiled_run.rho_changes == numpy_run.rho_changes >= 1
    assert compiled_run.factorizations == numpy_run.factorizations
    np.testing.assert_array_equal(rho_path(compiled_run), rho_path(numpy_run))
    scale = np.abs(numpy_run.x).max()
    assert np.abs(compiled_run.x - numpy_run.x).max() <= 1e-11 * scale
    assert np.abs(compiled_run.lam - numpy_run.lam).max() <= 1e-9 * np.abs(numpy_run.lam).max()


@pytest.mark.parametrize("method, options", [("sadmm", {}), ("sadmm", {"check_every": 3}), ("admm2", {}),
                                             ("sadmm", {"history": "full"})])
def test_segments_give_the_python_steps_bit_for_bit(ops, method, options):
    _, python = run(ops, True, segments=False, method=method, **options)
    _, fast = run(ops, True, segments=True, method=method, **options)
    assert "compiled_iterations" not in python.counters
    for name in ("x", "z", "lam", "x_iterate"):
        np.testing.assert_array_equal(getattr(fast, name), getattr(python, name))
    assert (fast.iterations, fast.status, fast.rho, fast.factorizations) == \
        (python.iterations, python.status, python.rho, python.factorizations)
    np.testing.assert_array_equal(rho_path(fast), rho_path(python))
    assert fast.counters["solves"] == python.counters["solves"] == python.iterations
    if options.get("history") == "full":                       # every record read: no segment can run
        assert fast.counters.get("compiled_iterations", 0) == 0
    else:
        assert fast.counters["compiled_iterations"] > python.iterations // 2


def test_the_numpy_path_runs_where_no_compiled_code_does():
    ops = assemble(example1(1 / 10))
    problem, result = run(ops, False)
    assert not problem.compiled_steps
    assert "compiled_iterations" not in result.counters
    assert problem.segment(result.x_iterate, result.z, result.lam, problem.apply_A(result.x_iterate), 1e3, 1.0,
                           "zx", 5, read=True) is None


def test_friction_and_other_orders_take_the_python_steps():
    ops = assemble(example1(1 / 10, tangential="tresca", slip_bound=0.3))
    problem, result = run(ops, True)
    assert not problem.compiled_steps and "compiled_iterations" not in result.counters
    frictionless = contact_problem(assemble(example1(1 / 10)), mode="condensed", backend="superlu")
    with compiled_code(True):
        frictionless.begin_run()
        x, z, lam = frictionless.initial_point()
        Ax = frictionless.apply_A(x)
        assert frictionless.segment(x, z, lam, Ax, 1e3, 1.0, "xz", 5, read=True) is None
        assert frictionless.segment(x, z, lam, Ax, 1e3, 1.5, "zx", 5, read=True) is None
        out = frictionless.segment(x, z, lam, Ax, 1e3, 1.0, "zx", 5, read=True)
    assert out[4] == 5 and out[5] is not None


def test_cholesky_solve_solves():
    rng = np.random.default_rng(0)
    G = rng.standard_normal((30, 30))
    A = G @ G.T + 30 * np.eye(30)
    R = np.linalg.cholesky(A).T                     # upper, R'R = A
    b = rng.standard_normal(30)
    x = np.empty(30)
    with compiled_code(True):
        cs.cholesky_solve(np.asfortranarray(R), b, x)
    np.testing.assert_allclose(A @ x, b, rtol=1e-12, atol=1e-12)


def go_on_at(ratio_w: float, change: float, tested: bool = True) -> bool:
    """:func:`cs.go_on` on a one-node state built so that w_k = ``ratio_w`` and ||u^{k+1} - u^k||_K = ``change``,
    ||u^{k+1}||_K = 1 (e0 = 1, d0 = 0, C w = w with w = 0: u = u0)."""
    mass, d0 = np.ones(1), np.zeros(1)
    x, x0 = np.array([1.0, 0.0]), np.array([1.0 - change, 0.0])    # ds = change, e0 = 1: the change is ``change``
    Ax, Ax0 = np.array([1.0]), np.array([0.0])                     # ||A x - A x0|| = 1
    z = np.array([1.0 - ratio_w])                                  # ||r|| = ratio_w: w_k = ratio_w
    zeros = np.zeros(2)
    with compiled_code(True):
        return cs.go_on(0, 1 if tested else 2, True, 1e-5, True, 1 / 3, 3.0, 1e3, mass, 1.0, d0, x, z, Ax,
                        np.zeros(1), x0, Ax0, np.zeros(1), zeros)


def test_the_kernel_goes_on_only_where_the_loop_certainly_would():
    assert go_on_at(1.0, 1e-3)
    assert not go_on_at(3.5, 1e-3)                        # rho would grow
    assert not go_on_at(0.2, 1e-3)                        # rho would shrink
    assert not go_on_at(3.0 * (1 - 1e-12), 1e-3)          # inside the band by less than BAND_MARGIN: Python's call
    assert not go_on_at(1.0, 1e-5)                        # the stop fires
    assert not go_on_at(1.0, 1e-5 * (1 + 1e-9))           # within STOP_MARGIN of firing: Python's call
    assert go_on_at(1.0, 1e-6, tested=False)              # an untested iteration: only the rule
    assert not go_on_at(1.0, np.inf)                      # a norm out of range: the loop's divergence test


def test_the_progress_bar_leaves_the_segments_their_decisions(ops):
    """The command line's bar reads k and rho of the records it is given (``every_tested = False``): a condensed
    SADMM run with it runs most iterations in segments, with the iterates of the run without it."""
    from admmkit.cli.output import Progress
    _, plain = run(ops, True)
    with Progress(2000, delay=1e9) as bar:
        problem = contact_problem(ops, mode="condensed", backend="superlu")
        order, rule = policies.method("sadmm")
        with compiled_code(True):
            shown = admmkit.solve(problem, rho=1e3, policy=rule, order=order, stop=RelativeChange(1e-5),
                                  max_iter=2000, callback=bar)
    assert shown.counters.get("compiled_iterations", 0) > shown.iterations // 2
    assert shown.counters["segments"] == plain.counters["segments"] < shown.iterations // 2    # not one per test
    np.testing.assert_array_equal(shown.x, plain.x)
    assert (shown.iterations, shown.status, shown.rho) == (plain.iterations, plain.status, plain.rho)
