"""Anderson on the QP's compiled path with its interval: the segment (OSQP's test and rule in its kernel included)
takes the loop's steps bit for bit, for every interval."""
from pathlib import Path

import numpy as np
import pytest

from admmkit import kernels
from admmkit.loop.acceleration import Anderson
from admmkit.problems.qp import admmkit_settings, load_mat, random_qp, solve_qp
from admmkit.problems.qp.generate import infeasible_qp, unbounded_qp
from tests import qp_paths

MM = Path(__file__).resolve().parents[3] / "shared" / "data" / "maros_meszaros"
pytestmark = pytest.mark.skipif(not kernels.AVAILABLE, reason="numba is not installed: no compiled segment")


def three_ways(qp, interval, monkeypatch, settings=None, **changes):
    """Anderson at ``interval``: with OSQP's test in the segment, with it in Python, and the Python loop."""
    return qp_paths.three_ways(qp, monkeypatch, settings, lambda: Anderson(interval=interval), **changes)


@pytest.mark.parametrize("make", [
    lambda: random_qp(40, 60, seed=1),
    lambda: random_qp(30, 50, kind="equality", seed=2),
    lambda: random_qp(25, 40, kind="lp", seed=3),
    lambda: infeasible_qp(seed=4),
    lambda: unbounded_qp(seed=5),
], ids=["mixed", "equality", "lp", "infeasible", "unbounded"])
@pytest.mark.parametrize("interval", [1, 3, 10])
@pytest.mark.parametrize("eps", [1e-3, 1e-8])
def test_compiled_is_python_bit_for_bit_at_every_interval(make, interval, eps, monkeypatch):
    inside, outside, python = three_ways(make(), interval, monkeypatch, eps_abs=eps, eps_rel=eps)
    qp_paths.same_run(inside, python)
    qp_paths.same_run(outside, python)
    assert python.acceleration["accelerator"].endswith(f"interval={interval})")


@pytest.mark.parametrize("interval", [1, 10])
def test_the_admmkit_preset_too(interval, monkeypatch):
    """admmkit's preset (a penalty per row, polishing during the run): the segment ends where its rule reads."""
    inside, outside, python = three_ways(random_qp(40, 60, seed=7), interval, monkeypatch, admmkit_settings(),
                                         eps_abs=1e-6, eps_rel=1e-6)
    qp_paths.same_run(inside, python)
    qp_paths.same_run(outside, python)


def test_anderson_keeps_the_test_in_the_kernel():
    """With Anderson the loop's Python no longer runs every tested iteration (25): only where it must look (here the
    end and a change of rho); the kernel's tested rows carry NaN norms.  Before, each of the 14 tested iterations of
    this run ran in Python, some 100 us each: most of what Anderson cost on a small QP."""
    res = solve_qp(random_qp(25, 40, kind="lp", seed=3), acceleration="anderson", eps_abs=1e-7, eps_rel=1e-7,
                   compiled=True)
    assert res.termination == "solved" and res.iterations >= 300
    assert np.isfinite(res.history["primal_residual"]).sum() <= 3


@pytest.mark.skipif(not MM.is_dir(), reason="Maros-Meszaros data not present")
@pytest.mark.parametrize("name", ["HS118", "HS268"])
def test_maros_meszaros_runs_are_python_bit_for_bit(name, monkeypatch):
    qp = load_mat(MM / f"{name}.mat")
    for interval in (1, 10):
        inside, outside, python = three_ways(qp, interval, monkeypatch, eps_abs=1e-6, eps_rel=1e-6)
        qp_paths.same_run(inside, python)
        qp_paths.same_run(outside, python)
        assert python.termination == "solved"
