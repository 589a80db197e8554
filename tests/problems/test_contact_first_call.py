"""A small contact solve from a fresh process (issue #49): no numba, no AMG, no plotting imported, and the
numba-free set-up gives the iterates of the compiled ordering bit for bit."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import admmkit
from admmkit import RelativeChange, policies
from admmkit.problems.contact import assemble, contact_problem, example1, example2
from admmkit.problems.contact.solvers.dissection import use_kernels
from admmkit.problems.contact.solvers.schur import available_schur_backends

ROOT = Path(__file__).resolve().parents[2]
UNNEEDED = ("numba", "pyamg", "matplotlib", "pandas", "admmkit.blocks.iterative", "admmkit.linalg.amg")


def fresh(code: str, timeout: float = 300, env: dict | None = None):
    """``code`` run by a fresh Python process from the repository root, with ``env`` (default: this process's,
    BLAS on one thread); it must exit 0."""
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, "OMP_NUM_THREADS": "1"} if env is None else env)
    assert done.returncode == 0, done.stderr
    return done


def test_solve_contact_imports_no_numba_for_a_small_body():
    code = ("import contextlib, io, sys, json, admmkit.cli\n"
            "out = io.StringIO()\n"
            "with contextlib.redirect_stdout(out):\n"
            "    code = admmkit.cli.main(['solve', 'contact', '--scene', 'ex1', '--h', '1/10', '-q'])\n"
            f"print(json.dumps({{'code': code, 'loaded': [m for m in {list(UNNEEDED)!r} if m in sys.modules],\n"
            "                  'mode': 'mode condensed' in out.getvalue()}))")
    done = fresh(code)
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out == {"code": 0, "loaded": [], "mode": True}


def test_a_fresh_solve_contact_builds_one_blas_controller():
    """threadpoolctl's controller lists every loaded library (10-25 ms in a fresh process): the condensed set-up
    loads SuperLU and LAPACK before it pins BLAS, so the solve's pin reuses that controller."""
    code = ("import contextlib, io, json, admmkit.cli, admmkit.loop.blas as blas\n"
            "built, make = [], blas._current_controller\n"
            "def counted():\n"
            "    before = blas._controller\n"
            "    c = make()\n"
            "    built.extend([c] if c is not before else [])\n"
            "    return c\n"
            "blas._current_controller = counted\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            "    code = admmkit.cli.main(['solve', 'contact', '--scene', 'ex1', '--h', '1/10', '-q'])\n"
            "print(json.dumps({'code': code, 'built': len(built)}))")
    done = fresh(code)
    assert json.loads(done.stdout.strip().splitlines()[-1]) == {"code": 0, "built": 1}


def run(problem):
    order, rule = policies.method("sadmm")
    return admmkit.solve(problem, rho=1e3, policy=rule, order=order, stop=RelativeChange(1e-5), max_iter=2000)


def same_bits(a, b):
    """Two results with the same iterates bit for bit (x, z, lam) and the same history of rho."""
    assert a.iterations == b.iterations and a.status == b.status
    for u, v in ((a.x, b.x), (a.z, b.z), (a.lam, b.lam)):
        assert np.array_equal(u.view(np.int64), v.view(np.int64))
    assert np.array_equal(a.history["rho"], b.history["rho"])


@pytest.mark.parametrize("example", [example1, example2])
def test_the_numpy_set_up_gives_the_compiled_orderings_iterates(example):
    if available_schur_backends()[0] == "cholmod" or not use_kernels(1, True):
        pytest.skip("CHOLMOD installed, or numba not installed")
    ops = assemble(example(h=1 / 20))
    plain = contact_problem(ops, "condensed", compiled=False)          # no numba: numpy twins, SuperLU
    kernels = contact_problem(ops, "condensed", backend="superlu", compiled=True)
    assert plain.schur.backend == kernels.schur.backend == "superlu"
    same_bits(run(plain), run(kernels))
    same_bits(run(contact_problem(ops, "condensed")), run(plain))      # "auto": the same


@pytest.mark.parametrize("example", [example1, example2])
def test_compiled_true_keeps_the_ldl_path(example):
    """The path before issue #49 (ldl for a small body) stays reachable: the same solution to round-off."""
    if available_schur_backends()[0] == "cholmod" or not use_kernels(1, True):
        pytest.skip("CHOLMOD installed, or numba not installed")
    ops = assemble(example(h=1 / 20))
    old = contact_problem(ops, "condensed", compiled=True)
    assert old.schur.backend == "ldl"
    a, b = run(old), run(contact_problem(ops, "condensed"))
    assert a.iterations == b.iterations
    assert np.abs(a.x - b.x).max() <= 1e-10 * np.abs(a.x).max()
    assert np.allclose(a.lam, b.lam, rtol=1e-8, atol=1e-10 * np.abs(a.lam).max())


def test_compiled_is_checked_in_every_mode():
    ops = assemble(example1(h=1 / 5))
    for mode in ("full", "condensed", "auto"):
        with pytest.raises(ValueError, match="compiled must be 'auto', True or False, got 'yes'"):
            contact_problem(ops, mode, compiled="yes")


#: what a warm ``solve contact`` process (operators from the cache) no longer imports (issue #49)
NOT_WARM = ("scipy.linalg", "scipy.sparse.linalg", "admmkit.blocks.xstep", "fractions",
            "admmkit.problems.contact.model.scene3d", "ngsolve", "numba")


def test_a_warm_process_imports_no_scipy_linalg(tmp_path):
    """Fails before: SuperLU came from scipy.sparse.linalg and LAPACK from scipy.linalg (0.1 s of 0.68 s)."""
    code = ("import contextlib, io, sys, json, admmkit.cli\n"
            "out = io.StringIO()\n"
            "with contextlib.redirect_stdout(out):\n"
            "    code = admmkit.cli.main(['solve', 'contact', '--scene', 'ex1', '--h', '1/10', '-q'])\n"
            f"print(json.dumps({{'code': code, 'loaded': [m for m in {list(NOT_WARM)!r} if m in sys.modules]}}))")
    env = {**os.environ, "OMP_NUM_THREADS": "1", "ADMMKIT_CACHE_DIR": str(tmp_path)}
    env.pop("ADMMKIT_NO_CACHE", None)
    runs = []
    for _ in range(2):                                   # the first assembles and stores, the second reads back
        done = fresh(code, env=env)
        runs.append(json.loads(done.stdout.strip().splitlines()[-1]))
    assert runs[0]["code"] == 0 and "ngsolve" in runs[0]["loaded"]
    assert runs[1] == {"code": 0, "loaded": []}


def test_the_direct_routines_give_the_librarys_bits():
    """lapack.py's SuperLU and LAPACK calls against scipy.sparse.linalg.splu, cho_factor, dpotrs, solve_triangular."""
    import scipy.linalg as sla
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla
    from admmkit.problems.contact.solvers import lapack
    rng = np.random.default_rng(0)
    A = sp.random(60, 60, density=0.1, random_state=1, format="csc")
    A = (A + A.T + 10 * sp.eye(60)).tocsc()
    b = rng.standard_normal(60)
    lu, ref = lapack.splu_natural(A.copy()), spla.splu(A, permc_spec="NATURAL", diag_pivot_thresh=0.0,
                                                       options=dict(SymmetricMode=True))
    assert np.array_equal(lu.solve(b), ref.solve(b)) and (lu.U != ref.U).nnz == 0 and (lu.L != ref.L).nnz == 0
    raw = lapack.splu_natural(A.copy(), factor_arrays=True)          # the factors as SuperLU's arrays
    for mine, theirs in ((raw.U, ref.U), (raw.L, ref.L)):
        data, indices, indptr = lapack.factor_csc_arrays(mine)
        assert isinstance(mine, tuple) and (sp.csc_array((data, indices, indptr), shape=A.shape) != theirs).nnz == 0
    assert lapack.factor_csc_arrays(ref.U)[0] is ref.U.data
    M = A.toarray()
    c, lower = lapack.cho_factor(M)
    c_ref, lower_ref = sla.cho_factor(M)
    assert lower == lower_ref and np.array_equal(np.triu(c), np.triu(c_ref))
    assert np.array_equal(lapack.cho_solve(c, lower, b), sla.lapack.dpotrs(c_ref, b, lower=lower_ref)[0])
    R = np.triu(c)
    for a in (R, np.asfortranarray(R), R.T):
        for trans in ("N", "T"):
            for rhs in (b, rng.standard_normal((60, 3)), rng.standard_normal((3, 60)).T):
                lo = a is R.T
                assert np.array_equal(lapack.solve_triangular(a, rhs, trans=trans, lower=lo),
                                      sla.solve_triangular(a, rhs, trans=trans, lower=lo, check_finite=False))
    with pytest.raises(np.linalg.LinAlgError, match="not positive definite"):
        lapack.cho_factor(-M)
    with pytest.raises(ValueError):
        lapack.cho_factor(np.full((2, 2), np.nan))


@pytest.mark.parametrize("example", [example1, example2])
def test_the_plain_library_path_gives_the_same_iterates(example, monkeypatch):
    """lapack.DIRECT = False (scipy.linalg and scipy.sparse.linalg as usual): the same bits."""
    from admmkit.problems.contact.solvers import lapack
    ops = assemble(example(h=1 / 20))
    direct = run(contact_problem(ops, "condensed", backend="superlu"))
    monkeypatch.setattr(lapack, "DIRECT", False)
    same_bits(run(contact_problem(ops, "condensed", backend="superlu")), direct)


def test_kkt_and_objective_share_k_u_and_see_a_changed_u():
    """The result's objective, kkt and kkt_relative compute K u once (base._product), never from a stale u."""
    ops = assemble(example1(h=1 / 10))
    problem = contact_problem(ops, "condensed")
    r = run(problem)
    u, lam = r.x.copy(), r.lam

    def stationarity(v):
        return float(np.abs(ops.K @ v - ops.f + problem.A.T @ (problem.w * lam)).max() / np.abs(ops.f).max())
    assert problem.kkt(u, r.z, lam)["stationarity"] == stationarity(u)
    assert problem.objective(u, r.z) == float(0.5 * u @ (ops.K @ u) - ops.f @ u)
    u[0] += 1.0                                            # the same array, changed in place
    assert problem.kkt(u, r.z, lam)["stationarity"] == stationarity(u)
    assert problem.objective(u, r.z) == float(0.5 * u @ (ops.K @ u) - ops.f @ u)


def test_a_process_that_loads_the_modules_directly_can_import_scipy_linalg_after():
    """The direct load first (no scipy.linalg in the process), the library imported after: both work, same bits."""
    code = ("import sys, numpy as np, scipy.sparse as sp\n"
            "from admmkit.problems.contact.solvers import lapack\n"
            "A = (sp.random(30, 30, density=0.2, random_state=2) + 8 * sp.eye(30)).tocsc(); A = (A + A.T).tocsc()\n"
            "b = np.arange(30.0); M = A.toarray()\n"
            "x, (c, low) = lapack.splu_natural(A.copy()).solve(b), lapack.cho_factor(M)\n"
            "direct = 'scipy.linalg' not in sys.modules and 'scipy.sparse.linalg' not in sys.modules\n"
            "import scipy.linalg as sla, scipy.sparse.linalg as spla\n"
            "y = spla.splu(A, permc_spec='NATURAL', diag_pivot_thresh=0.0, options=dict(SymmetricMode=True)).solve(b)\n"
            "print(direct, np.array_equal(x, y), np.array_equal(np.triu(c), np.triu(sla.cho_factor(M)[0])))")
    done = fresh(code, timeout=120)
    assert done.stdout.split() == ["True", "True", "True"]


def test_a_scipy_whose_private_routines_differ_falls_back_to_the_library(monkeypatch):
    """A direct routine that does not take the arguments (another scipy version: here a stand-in that raises
    TypeError) turns DIRECT off; the call and later ones give the library's result."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla
    from admmkit.problems.contact.solvers import lapack

    class Changed:
        def __getattr__(self, name):
            def routine(*args, **kwargs):
                raise TypeError(f"{name}() got an unexpected keyword argument")
            return routine
    monkeypatch.setattr(lapack, "DIRECT", True)
    monkeypatch.setattr(lapack, "_extension", lambda package, name: Changed() if lapack.DIRECT else None)
    A = (sp.random(30, 30, density=0.2, random_state=2, format="csc") + 10 * sp.eye(30)).tocsc()
    A = (A + A.T).tocsc()
    b = np.arange(30.0)
    lu = lapack.splu_natural(A.copy())
    assert lapack.DIRECT is False
    ref = spla.splu(A, permc_spec="NATURAL", diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
    assert np.array_equal(lu.solve(b), ref.solve(b))
    monkeypatch.setattr(lapack, "DIRECT", True)
    c, lower = lapack.cho_factor(A.toarray())
    assert lapack.DIRECT is False and np.allclose(np.triu(c).T @ np.triu(c), A.toarray())


def test_the_condensed_modes_dense_factors_live_in_the_one_factor_cache():
    """The dense factors of M_c^-1 + rho C are held by CachedFactorization (the one cache a change of rho reaches),
    with its whole interface: bench stability empties it between cases (``clear``), which a stand-in lacked."""
    from admmkit.linalg.linsolve import CachedFactorization
    problem = contact_problem(assemble(example1(h=1 / 10)), "condensed")
    assert isinstance(problem.factors, CachedFactorization)
    problem.update_rho(10.0)
    assert len(problem.factors) == 1 and 10.0 in problem.factors
    problem.factors.clear()
    assert len(problem.factors) == 0
    res = run(problem)
    assert res.status.value == "converged" and problem.factors.factorizations >= 1
