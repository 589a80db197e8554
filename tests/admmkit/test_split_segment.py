"""The building blocks' compiled segment (issue #25): SplitProblem's iterations between checks in one numba call,
bit for bit the Python loop's (x, z, lam, iterations, rho path, status)."""
import numpy as np
import pytest
import scipy.sparse as sp

import admmkit
from admmkit import QuadraticXStep, SplitProblem, prox
from admmkit import kernels
from admmkit.blocks.split_segment import run_segment

pytestmark = pytest.mark.skipif(not kernels.AVAILABLE, reason="numba is not installed: no compiled segment")
HAS_QDLDL = "qdldl" in admmkit.linalg.linsolve.available_backends()
rng = np.random.default_rng(25)
N, P_ROWS = 30, 40


def bits(a):
    """The bits of a float array (np.array_equal would take -0. for 0.)."""
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


def same_run(a, b):
    """Two results with the same iterates bit for bit, iterations, rho path and status."""
    assert a.status == b.status and a.iterations == b.iterations and a.rho == b.rho
    for u, v in ((a.x, b.x), (a.z, b.z), (a.lam, b.lam), (a.x_iterate, b.x_iterate)):
        assert np.array_equal(bits(u), bits(v))
    assert np.array_equal(a.history["rho"], b.history["rho"])


def xstep(P, q, A=None, M=None, solver="direct", backend="qdldl", sigma=0.0):
    if solver == "direct" and backend == "qdldl" and not HAS_QDLDL:
        pytest.skip("the direct segment reads qdldl's factors; qdldl is not installed")
    kw = dict(backend=backend) if solver == "direct" else {}
    return QuadraticXStep(P, q, A, M=M, n=len(q), solver=solver, sigma=sigma, **kw)


def lasso(solver="direct", c=0.0, backend="qdldl"):
    D, b = rng.standard_normal((50, N)), rng.standard_normal(50)
    mu = 0.1 * np.abs(D.T @ b).max()
    return SplitProblem(xstep(D.T @ D, -D.T @ b, backend=backend), prox.L1(mu), c=c)


def box_weighted(solver="direct", c=0.0):
    C, d = rng.standard_normal((45, N)), 3 * rng.standard_normal(45)
    P = C.T @ C if solver == "direct" else np.diag(rng.uniform(0.5, 3, N))
    lo, up = -np.ones(N), np.linspace(0.2, 1.5, N)
    return SplitProblem(xstep(P, -C.T @ d, None, M=rng.uniform(0.1, 10, N), solver=solver), prox.Box(lo, up), c=c)


def nonnegative_sparse_A(solver="direct", c=0.0):
    """A sparse diagonal A (the diagonal solver takes it too), M weights, sigma > 0, g the orthant."""
    A = sp.diags(rng.uniform(0.5, 2, N), format="csr")
    P = sp.diags(rng.uniform(0.1, 1, N)) if solver == "diagonal" else sp.csr_matrix(np.cov(rng.standard_normal((N, 60))))
    return SplitProblem(xstep(P, rng.standard_normal(N), A, M=rng.uniform(0.5, 2, N), solver=solver, sigma=1e-3),
                        prox.NonNegative(), c=c)


def upper_bound_tall_A(solver="direct", c=0.0):
    """A tall sparse A (CSR products both ways), the contact set z <= g."""
    A = sp.random(P_ROWS, N, density=0.2, random_state=3, format="csr") + sp.eye(P_ROWS, N)
    return SplitProblem(xstep(sp.eye(N) * 2.0, rng.standard_normal(N), A), prox.UpperBound(rng.uniform(-0.2, 0.5, P_ROWS)),
                        c=c)


def tv(solver="direct", c=0.0):
    side = 6
    diff = sp.diags([-np.ones(side - 1), np.ones(side - 1)], [0, 1], shape=(side - 1, side))
    D = sp.vstack([sp.kron(sp.eye(side), diff), sp.kron(diff, sp.eye(side))]).tocsr()
    y = rng.standard_normal(side * side)
    return SplitProblem(xstep(sp.identity(side * side), -y, D), prox.L1(0.15), c=c)


def consensus(solver="direct", c=0.0, weighted=False):
    blocks, k = 5, 6
    Cs = [rng.standard_normal((8, k)) for _ in range(blocks)]
    P = sp.block_diag([C.T @ C for C in Cs], format="csr")
    q = -np.concatenate([C.T @ rng.standard_normal(8) for C in Cs])
    M = rng.uniform(0.5, 2, blocks * k) if weighted else None
    return SplitProblem(xstep(P, q, None, M=M), prox.Consensus(blocks), c=c)


def zero_g(solver="diagonal", c=0.0):
    return SplitProblem(xstep(np.diag(rng.uniform(1, 2, N)), rng.standard_normal(N), solver=solver), prox.Zero(), c=c)


PROBLEMS = {
    "lasso": lasso, "box_weighted": box_weighted, "box_weighted_diagonal": lambda c: box_weighted("diagonal", c),
    "nonnegative_sparse_A": nonnegative_sparse_A,
    "nonnegative_diagonal": lambda c: nonnegative_sparse_A("diagonal", c), "upper_bound_tall_A": upper_bound_tall_A,
    "tv": tv, "consensus": consensus, "consensus_M": lambda c: consensus(c=c, weighted=True), "zero": zero_g,
}
RUNS = {   # (policy, check_every): OSQP's rule changes rho every 50 iterations; fixed rho leaves only the checks
    "osqp": (lambda: "osqp", 25), "fixed": (lambda: "fixed", 10),
    "osqp_interval_30": (lambda: admmkit.policies.OSQPRule(interval=30), 7),
}


def c_value(kind, p):
    return {"zero": 0.0, "number": 0.3, "vector": rng.uniform(-0.5, 0.5, p)}[kind]


@pytest.mark.parametrize("name", list(PROBLEMS))
@pytest.mark.parametrize("order", ["xz", "zx"])
@pytest.mark.parametrize("alpha", [1.0, 1.6])
@pytest.mark.parametrize("run", list(RUNS))
def test_compiled_iterates_are_the_python_ones_bit_for_bit(name, order, alpha, run):
    make = PROBLEMS[name]
    for ckind in ("zero", "vector") if run == "osqp" else ("number",):
        problem = make(c=0.0) if ckind == "zero" else make(c=c_value(ckind, make(c=0.0).map.p))
        policy, every = RUNS[run]
        kw = dict(order=order, alpha=alpha, check_every=every, max_iter=600, rho=0.5)
        fast = admmkit.solve(problem, policy=policy(), **kw)
        slow = admmkit.solve(problem, policy=policy(), compiled=False, **kw)
        same_run(fast, slow)
        assert fast.counters["compiled_iterations"] > fast.iterations // 2
        assert "compiled_iterations" not in slow.counters
        assert fast.counters["solves"] == slow.counters["solves"] == fast.iterations
        assert fast.counters.get("factorizations") == slow.counters.get("factorizations")


@pytest.mark.parametrize("make", [
    lambda: lasso(backend="superlu"),
    lambda: SplitProblem(QuadraticXStep(np.eye(N), np.ones(N), rng.standard_normal((20, N))), prox.L1(0.1)),
    lambda: SplitProblem(QuadraticXStep(np.eye(N), np.ones(N), solver="cg"), prox.L1(0.1)),
    lambda: SplitProblem(xstep(np.eye(12), np.ones(12)), prox.GroupL1([np.arange(6), np.arange(6, 12)], 0.5)),
    lambda: SplitProblem(xstep(np.eye(12), np.ones(12)), prox.L2Ball(1.0)),
    lambda: SplitProblem(xstep(np.eye(12), np.ones(12)), prox.Consensus(12)),
    lambda: SplitProblem(xstep(np.eye(12), np.ones(12)), type("MyBox", (prox.Box,), {})(-1.0, 1.0)),
], ids=["superlu", "dense_A", "cg", "group_l1", "l2_ball", "consensus_of_scalars", "box_subclass"])
def test_blocks_without_a_kernel_run_in_python(make):
    problem = make()
    x, z = np.zeros(problem.n), np.zeros(problem.map.p)
    assert problem.segment(x, z, z, z, 1.0, 1.0, "xz", 10) is None
    fast = admmkit.solve(problem, policy="osqp", check_every=25, max_iter=300)
    assert "compiled_iterations" not in fast.counters
    same_run(fast, admmkit.solve(problem, policy="osqp", check_every=25, max_iter=300, compiled=False))


def test_pyproximal_runs_in_python():
    pyproximal = pytest.importorskip("pyproximal")
    problem = SplitProblem(xstep(np.eye(N), np.ones(N)), prox.PyProximal(pyproximal.L1(sigma=0.5)))
    assert problem.segment(np.zeros(N), np.zeros(N), np.zeros(N), np.zeros(N), 1.0, 1.0, "xz", 10) is None


def test_a_rule_that_reads_every_record_runs_in_python():
    problem = lasso()
    fast = admmkit.solve(problem, policy="summable", check_every=25, max_iter=300)
    assert "compiled_iterations" not in fast.counters
    same_run(fast, admmkit.solve(problem, policy="summable", check_every=25, max_iter=300, compiled=False))


@pytest.mark.parametrize("order", ["xz", "zx"])
def test_kernel_stops_before_a_non_finite_step(order):
    problem = box_weighted()
    x, z, lam = np.zeros(N), np.zeros(N), np.zeros(N)
    z[3] = lam[4] = np.nan
    out = run_segment(problem, x, z, lam, x.copy(), 1.0, 1.5, order, 10)
    assert out[-1] == 0 and np.array_equal(out[0], x) and np.isnan(out[1][3])
    big = np.full(N, 1e307)                             # lam / rho overflows in the first z-step
    out = run_segment(problem, x, np.zeros(N), big, np.zeros(N), 1e-3, 1.0, order, 10)
    assert out[-1] == 0


def test_four_problems_get_segments():
    """The problems of ``admmkit bench four-problems`` with qdldl: every block has a kernel."""
    if not HAS_QDLDL:
        pytest.skip("qdldl is not installed")
    from admmkit.benchmarks.framework import four_problems as fp
    for name, make in fp.PROBLEMS.items():
        problem = make()[0]
        f = problem.f
        problem.f = QuadraticXStep(f.P, f.q, f.A, solver="direct", backend="qdldl")
        fast = admmkit.solve(problem, policy="osqp", check_every=25, max_iter=400, alpha=1.6)
        assert fast.counters["compiled_iterations"] > 0, name
        same_run(fast, admmkit.solve(problem, policy="osqp", check_every=25, max_iter=400, alpha=1.6, compiled=False))
