"""A change of rho made in place, and the x-step's work arrays kept (issue #51 item 1).

A new rho changes K + rho D only where D is stored (for contact: the contact dofs).  The iterative
x-step rewrites those values in place (the matrix, CG's product, every AMG level, the compiled cycle's
storage and its 1 / a_ii) instead of copying and laying out every level again; the values must be the
ones a full refresh gives, bit for bit.  CG and the V-cycle write into arrays kept for the whole solve.
"""
import numpy as np
import pytest

from admmkit.blocks.iterative import IterativeXSolver
from admmkit.kernels import library_kernels
from admmkit.linalg import amg as amg_module
from admmkit.linalg.symmetric import pencil_products
from admmkit.linalg.vcycle import VCycle
from admmkit.problems.contact.model.assembly3d import assemble3d
from admmkit.problems.contact.model.scene3d import example2_3d
from admmkit.problems.contact.solvers.problem import IterativeContact


@pytest.fixture(scope="module")
def block_ops():
    """The 3D block at h = 1/8 (the scene of issue #51's target; 5,832 unknowns)."""
    return assemble3d(example2_3d(h=1 / 8))


def _solver(ops, **options):
    return IterativeContact(ops, **options).solver


def _spy_in_place(monkeypatch):
    """Record what every AMGPreconditioner._refresh_in_place returns."""
    calls = []
    original = amg_module.AMGPreconditioner._refresh_in_place

    def spy(self, A, rho):
        calls.append(original(self, A, rho))
        return calls[-1]
    monkeypatch.setattr(amg_module.AMGPreconditioner, "_refresh_in_place", spy)
    return calls


def test_a_rho_change_in_place_gives_the_values_of_a_full_refresh(block_ops, monkeypatch):
    calls = _spy_in_place(monkeypatch)
    solver = _solver(block_ops)
    rng = np.random.default_rng(0)
    b = rng.standard_normal(solver.n)
    solver.solve(1e3, b)
    amg, cycle = solver._amg, solver._amg._cycle
    for rho in (3e3, 9e3, 2.7e4):     # the first change too: every level holds values of its own, not its pencil's K
        solver.update_rho(rho)
        assert solver._amg._cycle is cycle                       # the same cycle, updated, not a new one
        levels = amg.ml.levels
        np.testing.assert_array_equal(levels[0].A.data, solver.pencil.at(rho).data)
        for level, pencil in zip(levels[1:], amg._pencils):
            np.testing.assert_array_equal(level.A.data, pencil.at(rho - amg._rho).data)
        fresh = VCycle(amg.ml, values=cycle.values, blocks3d=True, smoother=cycle.smoother)  # laid out anew
        for ours, theirs in zip(cycle.block, fresh.block):
            np.testing.assert_array_equal(ours.data, theirs.data)
        for ours, theirs in zip(cycle._inverse, fresh._inverse):
            np.testing.assert_array_equal(ours, theirs)
        r = rng.standard_normal(solver.n)
        np.testing.assert_array_equal(cycle(r), fresh(r))
        x = rng.standard_normal(solver.n)
        np.testing.assert_array_equal(solver._product(x), pencil_products(solver.pencil)(rho)(x))
    assert calls == [True, True, True]


def test_in_place_and_full_refreshes_give_the_same_iterates(block_ops, monkeypatch):
    rng = np.random.default_rng(1)
    rhs = [rng.standard_normal(block_ops.n_free) for _ in range(5)]
    rhos = [1e3, 1e3, 3e3, 9e3, 9e3]

    def run():
        solver = _solver(block_ops)
        return [solver.solve(rho, b) for rho, b in zip(rhos, rhs)]
    in_place = run()
    monkeypatch.setattr(amg_module.AMGPreconditioner, "_refresh_in_place", lambda self, A, rho: False)
    for ours, theirs in zip(in_place, run()):
        np.testing.assert_array_equal(ours, theirs)


def test_the_library_path_refreshes_anew(block_ops, monkeypatch):
    calls = _spy_in_place(monkeypatch)
    with library_kernels(True):
        solver = _solver(block_ops, tol=1e-10)
        b = np.random.default_rng(2).standard_normal(solver.n)
        x0 = solver.solve(1e3, b)
        A0 = solver._A
        for rho in (3e3, 9e3):
            solver.update_rho(rho)
            assert solver._A is not A0                       # a new matrix for every rho
            x = solver.solve(rho, b)
            residual = b[solver.perm] - solver.pencil.at(rho) @ x[solver.perm]    # in the solver's node order
            assert np.linalg.norm(residual) <= 1e-6 * np.linalg.norm(b)
    assert calls and not any(calls)
    assert np.all(np.isfinite(x0))


def test_cycle_and_products_write_into_the_given_arrays(block_ops):
    solver = _solver(block_ops)
    b = np.random.default_rng(3).standard_normal(solver.n)
    solver.solve(1e3, b)
    r = np.random.default_rng(4).standard_normal(solver.n)
    for f in (solver._amg, solver._product):
        assert f.writes_into
        out = np.full(solver.n, np.nan)
        assert f(r, out=out) is out
        np.testing.assert_array_equal(out, f(r))
    with library_kernels(True):
        out = np.full(solver.n, np.nan)
        assert solver._amg(r, out=out) is out
        np.testing.assert_array_equal(out, solver._amg(r))


def test_products_from_ds_entries_equal_those_from_its_gathered_values(block_ops):
    from admmkit.linalg.symmetric import SymmetricPattern
    solver = _solver(block_ops)
    pencil = solver.pencil
    entries = pencil.changed_entries()
    assert 0 < entries.size < pencil.D_data.size // 100          # D: the contact dofs only
    pattern = SymmetricPattern(pencil.pattern)
    by_entries = pattern.pencil_products(pencil.K_data, pencil.D_data, entries)
    gathered = pattern.pencil_products(pencil.K_data, pencil.D_data)
    x = np.random.default_rng(5).standard_normal(solver.n)
    for rho in (1e3, 2.7e4):
        ours, theirs = by_entries(rho), gathered(rho)
        for a, b in zip(ours.values, theirs.values):
            np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(ours(x), theirs(x))
