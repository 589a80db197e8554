"""A QP run three ways, for the tests that compare the compiled segment with the Python loop bit for bit."""
from admmkit.problems.qp import segment_checks, solve_qp


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
