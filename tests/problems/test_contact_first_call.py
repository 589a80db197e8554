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


def test_solve_contact_imports_no_numba_for_a_small_body():
    code = ("import contextlib, io, sys, json, admmkit.cli\n"
            "out = io.StringIO()\n"
            "with contextlib.redirect_stdout(out):\n"
            "    code = admmkit.cli.main(['solve', 'contact', '--scene', 'ex1', '--h', '1/10', '-q'])\n"
            f"print(json.dumps({{'code': code, 'loaded': [m for m in {list(UNNEEDED)!r} if m in sys.modules],\n"
            "                  'mode': 'mode condensed' in out.getvalue()}))")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300,
                          env={**os.environ, "OMP_NUM_THREADS": "1"})
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out == {"code": 0, "loaded": [], "mode": True}


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
