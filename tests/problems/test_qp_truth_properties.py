"""What a QP result claims is true whatever the scale (issue #46 items 1 and 3).

Random small QPs (n, m <= 8), their rows and columns scaled by 10**uniform(-12, 12), with duplicate and
zero rows, feasible, infeasible and unbounded: a ``converged`` run's answer meets OSQP's test in the
user's own problem (recomputed here from the arrays) or the result carries a warning; every declared
infeasibility is a certificate of the user's problem.  And the scale-aware fix itself: rows scaled by
1e-8 or 1e-150 (the same feasible set) end converged at the unscaled problem's solution, through
solve_qp and through cvxpy, with a ScaleWarning.
"""
import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from admmkit import Status
from admmkit.problems.qp import QP, random_qp, solve_qp
from admmkit.problems.qp.generate import infeasible_qp, unbounded_qp
from admmkit.problems.qp.reference import solve_with_cvxpy
from admmkit.problems.qp.residuals import support
from admmkit.problems.qp.termination import ScaleWarning

EPS = 1e-5
PROPERTY = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def base_qp(kind: str, n: int, m: int, seed: int) -> QP:
    """A feasible, a primal infeasible (m + 1 rows) or an unbounded QP of the generator."""
    if kind == "infeasible":
        return infeasible_qp(n, m, seed=seed)
    if kind == "unbounded":
        return unbounded_qp(max(n, 2), m, seed=seed)
    return random_qp(n, m, kind=kind, seed=seed)


def with_rows(qp: QP, duplicate: bool, zero: bool) -> tuple:
    """P, q, A, l, u of ``qp`` with a copy of its first row and a zero row (bounds [-1, 1]) appended."""
    A, l, u = qp.A.tocsr(), qp.l, qp.u
    if duplicate:
        A, l, u = sp.vstack([A, A[0]]), np.r_[l, l[0]], np.r_[u, u[0]]
    if zero:
        A, l, u = sp.vstack([A, sp.csr_matrix((1, qp.n))]), np.r_[l, -1.0], np.r_[u, 1.0]
    return qp.P, qp.q, sp.csc_matrix(A), l, u


def scaled(data: tuple, row: np.ndarray, col: np.ndarray) -> QP:
    """The same QP in x = diag(col) x' with row i multiplied by row_i (rows keep their direction)."""
    P, q, A, l, u = data
    R, C = sp.diags(row), sp.diags(col)
    return QP((C @ P @ C).tocsc(), col * q, (R @ A @ C).tocsc(), row * l, row * u)


def osqp_test_holds(qp: QP, res, eps: float) -> bool:
    """OSQP's (R1)-(R3) at the returned x, z, y, recomputed from the user's arrays (a hair of slack for round-off)."""
    x, z, y = res.x, res.z, res.y
    Ax, Px, Aty = qp.A @ x, qp.P @ x, qp.A.T @ y
    inf = lambda v: float(np.max(np.abs(v), initial=0.0))  # noqa: E731
    quad, lin, sup = float(x @ Px), float(qp.q @ x), support(y, qp.l, qp.u)
    slack = 1 + 1e-6
    return (inf(Ax - z) <= slack * (eps + eps * max(inf(Ax), inf(z)))
            and inf(Px + qp.q + Aty) <= slack * (eps + eps * max(inf(Px), inf(Aty), inf(qp.q)))
            and abs(quad + lin + sup) <= slack * (eps + eps * max(abs(quad), abs(lin), abs(sup))))


def certificate_verifies(qp: QP, res) -> bool:
    """The declared certificate of the user's problem, column by column against the sizes it sums (so that a
    column scaled by 1e-12 is judged as strictly as the others)."""
    c = res.certificate
    if res.status is Status.PRIMAL_INFEASIBLE:
        y = c / np.max(np.abs(c))
        absA = abs(qp.A)
        pushes = np.any((y > 0) & np.isinf(qp.u)) or np.any((y < 0) & np.isinf(qp.l))
        size = np.abs(np.where(y > 0, qp.u, 0.0) * y) + np.abs(np.where(y < 0, qp.l, 0.0) * y)
        return (not pushes and support(y, qp.l, qp.u) < -1e-9 * size.sum()
                and np.all(np.abs(qp.A.T @ y) <= 1e-6 * (absA.T @ np.abs(y)) + 1e-300))
    dx = c / np.max(np.abs(c))
    Ad, absA = qp.A @ dx, abs(qp.A) @ np.abs(dx)
    cone = np.all(np.where(np.isfinite(qp.u), Ad <= 1e-6 * absA, True)) and \
        np.all(np.where(np.isfinite(qp.l), Ad >= -1e-6 * absA, True))
    return (qp.q @ dx < -1e-9 * (np.abs(qp.q) @ np.abs(dx))
            and np.all(np.abs(qp.P @ dx) <= 1e-6 * (abs(qp.P) @ np.abs(dx)) + 1e-300) and cone)


@st.composite
def scaled_qps(draw):
    """(kind, the scaled QP): sizes up to 8, rows and columns scaled by 10**uniform(-12, 12) (or not), duplicate
    and zero rows."""
    kind = draw(st.sampled_from(["mixed", "inequality", "lp", "infeasible", "unbounded"]))
    n, m = draw(st.integers(1, 8)), draw(st.integers(1, 8))
    seed = draw(st.integers(0, 10_000))
    data = with_rows(base_qp(kind, n, m, seed), draw(st.booleans()), draw(st.booleans()))
    rows, cols = data[2].shape
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    row = 10.0 ** rng.uniform(-12, 12, rows) if draw(st.booleans()) else np.ones(rows)
    col = 10.0 ** rng.uniform(-12, 12, cols) if draw(st.booleans()) else np.ones(cols)
    return kind, scaled(data, row, col)


@PROPERTY
@given(scaled_qps())
def test_a_verdict_is_true_in_the_users_problem_or_warned(case):
    kind, qp = case
    res = solve_qp(qp, eps_abs=EPS, eps_rel=EPS, max_iter=2000)
    if res.status is Status.CONVERGED:
        assert res.termination == "solved"
        assert osqp_test_holds(qp, res, EPS) or res.warnings, res.message
    if res.status in (Status.PRIMAL_INFEASIBLE, Status.DUAL_INFEASIBLE):
        assert certificate_verifies(qp, res), (kind, res.status, res.certificate)
        assert kind != "mixed" and kind != "inequality" and kind != "lp"      # these are feasible and bounded


@settings(max_examples=12, deadline=None)
@given(st.integers(0, 10_000), st.floats(-150, -9), st.integers(1, 8))
def test_tiny_rows_end_at_the_unscaled_solution(seed, exponent, rows):
    """Rows multiplied by 10**exponent <= 1e-9 describe the same feasible set: a converged run is the solution.

    Tiny rows must not cost convergence: where the unscaled problem converges within the cap, so does the
    scaled one.  Some random bases do not converge in 10,000 iterations at 1e-6 at all (seed 260: three
    equality rows, OSQP 1.1.3 also stops at its cap); for those the scaled run must not claim convergence
    at a wrong answer either."""
    base = random_qp(6, 8, seed=seed)
    factor = np.ones(base.m)
    factor[:rows] = 10.0 ** exponent
    settings = dict(eps_abs=1e-6, eps_rel=1e-6, max_iter=10_000)
    res = solve_qp(scaled((base.P, base.q, base.A, base.l, base.u), factor, np.ones(base.n)), **settings)
    _, _, f_ref = solve_with_cvxpy(base)
    if solve_qp(base, **settings).status is Status.CONVERGED:
        assert res.status is Status.CONVERGED
    if res.status is Status.CONVERGED:
        assert abs(res.objective - f_ref) <= 1e-3 * max(1.0, abs(f_ref))


@pytest.mark.parametrize("factor", [1e-8, 1e-150])
def test_rows_scaled_by_a_tiny_factor_are_solved_not_skipped(factor):
    """#46 item 1: before, the run ended converged at the unconstrained minimum (the rows' residuals were below
    eps_abs whatever x did); now the row-normalised test (R1') is asked too, and Ruiz lifts the rows."""
    base = random_qp(20, 30, seed=0)
    qp = scaled((base.P, base.q, base.A, base.l, base.u), np.full(base.m, factor), np.ones(base.n))
    res = solve_qp(qp)
    _, _, f_ref = solve_with_cvxpy(base)
    assert res.status is Status.CONVERGED
    assert abs(res.objective - f_ref) <= 1e-3 * abs(f_ref)            # the unconstrained minimum is -4.79, f_ref 94.4
    assert any("row-normalised test (R1') held" in w or "also met the row-normalised" in w for w in res.warnings)


def test_columns_out_of_the_dual_tests_sight_are_not_reported_converged():
    base = random_qp(6, 8, seed=1)
    col = np.ones(base.n)
    col[0] = 1e-12
    res = solve_qp(scaled((base.P, base.q, base.A, base.l, base.u), np.ones(base.m), col), eps_abs=1e-6, eps_rel=1e-6)
    assert res.status is not Status.CONVERGED and not res.solved        # nor "solved" for the exit code
    assert any(w.startswith("columns 0 of (P; A)") for w in res.warnings)


def test_well_scaled_qps_get_no_warning():
    for seed in range(5):
        assert solve_qp(random_qp(20, 30, seed=seed)).warnings == []


# ---------------------------------------------------------------- the textbook loop (#46 item 7)
def relative_kkt(qp: QP, x, z, y) -> float:
    """The worst of OSQP's (R1)-(R3) divided by its scale, from the user's arrays."""
    Ax, Px, Aty = qp.A @ x, qp.P @ x, qp.A.T @ y
    inf = lambda v: float(np.max(np.abs(v), initial=0.0))  # noqa: E731
    quad, lin, sup = float(x @ Px), float(qp.q @ x), support(y, qp.l, qp.u)
    return max(inf(Ax - z) / max(inf(Ax), inf(z)), inf(Px + qp.q + Aty) / max(inf(Px), inf(Aty), inf(qp.q)),
               abs(quad + lin + sup) / max(abs(quad), abs(lin), abs(sup)))


def textbook(qp: QP, tol: float = 1e-5):
    """The textbook preset's loop: rho_0 = 1, residual balancing, the relative-change stop."""
    import admmkit
    from admmkit.policies import ResidualBalancing
    from admmkit.loop.stopping import RelativeChange
    return admmkit.solve(qp, rho=1.0, policy=ResidualBalancing(), order="xz", stop=RelativeChange(tol),
                         max_iter=10_000)


def test_a_textbook_stop_far_from_the_solution_is_not_converged():
    """random_qp(5, 8, seed=23): the relative change fell below 1e-5 at iteration 39 with the objective 2 % off;
    the check fell back on the ADMM residuals (relative 8e-5) and said converged.  The QP's own relative
    primal residual is 1.8e-4 > 10 x 1e-5."""
    qp = random_qp(5, 8, seed=23)
    res = textbook(qp)
    _, _, f_ref = solve_with_cvxpy(qp)
    assert abs(res.objective - f_ref) > 1e-2 * abs(f_ref)              # what the run found is not the solution
    assert res.status is Status.CONVERGED_INACCURATE
    assert set(res.accuracy) == {"primal", "dual", "gap"} and res.accuracy["primal"] > 1e-4


@pytest.mark.parametrize("seed", range(30))
def test_a_converged_textbook_run_meets_the_qps_kkt_at_10x_its_tolerance(seed):
    qp = random_qp(10, 15, seed=seed)
    res = textbook(qp)
    if res.status is Status.CONVERGED:
        assert relative_kkt(qp, res.x, res.z, res.lam) <= 10 * 1e-5


def test_solve_qp_textbook_preset_exits_1_when_inaccurate(capsys):
    from admmkit.cli import main
    code = main(["solve", "qp", "--random", "5", "8", "--seed", "23", "--preset", "textbook", "-q"])
    out = capsys.readouterr().out
    assert code == 1 and "status       converged_inaccurate" in out


def test_solve_qp_prints_a_warning_line_for_rows_the_tolerance_cannot_see(tmp_path, capsys):
    import json

    import scipy.io
    from admmkit.cli import main
    base = random_qp(20, 30, seed=0)
    path = tmp_path / "tiny_rows.mat"
    scipy.io.savemat(path, {"P": base.P, "q": base.q, "A": 1e-8 * base.A, "l": 1e-8 * base.l, "u": 1e-8 * base.u,
                            "r": 0.0})
    code = main(["solve", "qp", "--mat", str(path), "--json", str(tmp_path / "r.json"), "-q"])
    out = capsys.readouterr().out
    warning = [row for row in out.splitlines() if row.startswith("warning      ")]
    assert code == 0 and len(warning) == 1 and "row-normalised test (R1')" in warning[0]
    assert json.loads((tmp_path / "r.json").read_text())["result"]["warnings"] == [warning[0][13:]]


# ---------------------------------------------------------------- the same through cvxpy
cp = pytest.importorskip("cvxpy")


@pytest.mark.parametrize("factor", [1e-8, 1e-150])
def test_cvxpy_rows_scaled_by_a_tiny_factor(factor):
    from admmkit.problems.qp.cvxpy_interface import ADMMKIT
    rng = np.random.default_rng(3)
    n, m = 6, 4
    G, c, A = rng.standard_normal((n, n)), rng.standard_normal(n), rng.standard_normal((m, n))
    b = A @ rng.uniform(-0.5, 0.5, n) + 0.1
    x = cp.Variable(n)
    objective = cp.Minimize(0.5 * cp.sum_squares(G @ x) + c @ x)
    reference = cp.Problem(objective, [A @ x <= b])
    reference.solve(solver=cp.CLARABEL)
    problem = cp.Problem(objective, [(factor * A) @ x <= factor * b])
    with pytest.warns(ScaleWarning, match="rows of the QP cvxpy passes.* have inf-norms"):
        problem.solve(solver=ADMMKIT())
    assert problem.status == cp.OPTIMAL
    assert abs(problem.value - reference.value) <= 1e-4 * max(1.0, abs(reference.value))
