"""A QP run three ways, for the tests that compare the compiled segment with the Python loop bit for bit."""
import numpy as np

from admmkit.problems.qp import segment_checks, solve_qp


def same_run(a, b):
    """Two results with the same iterates, iterations, rho path, factorisations, status, certificate and
    accelerator's counts."""
    assert a.status == b.status and a.termination == b.termination
    assert a.iterations == b.iterations and a.rho == b.rho
    assert np.array_equal(a.x, b.x) and np.array_equal(a.y, b.y) and np.array_equal(a.z, b.z)
    assert np.array_equal(a.history["rho"], b.history["rho"])
    assert a.counters["factorizations"] == b.counters["factorizations"]
    if a.certificate is not None or b.certificate is not None:
        assert np.array_equal(a.certificate, b.certificate)
    assert a.acceleration == b.acceleration


def three_ways(qp, monkeypatch, settings=None, accelerator=None, **changes):
    """``solve_qp(qp, settings, **changes)`` with OSQP's test in the segment, with it in Python (the segment ending
    at every read iteration), and in the Python loop; ``accelerator``: a function making a new accelerator for each
    run (None: plain ADMM)."""
    def solve(**kw):
        extra = {} if accelerator is None else {"acceleration": accelerator()}
        return solve_qp(qp, settings, **extra, **kw, **changes)
    inside = solve(compiled=True)
    monkeypatch.setattr(segment_checks, "TESTS_IN_KERNEL", False)
    outside = solve(compiled=True)
    monkeypatch.setattr(segment_checks, "TESTS_IN_KERNEL", True)
    return inside, outside, solve(compiled=False)
