"""admmkit.BalancedStop: the stop balanced with a discretisation estimate, on the scalar problem of conftest.

A subclass reports max |z - z*| (z* from a tight solve) as its "algebraic
error bound" and a fixed "discretisation estimate", so when the rule fires is
known exactly.
"""
import math

import numpy as np
import pytest

from admmkit import BalancedStop, ResidualTolerance, solve
from admmkit.loop.norms import LAZY_FIELDS

_NONE = (None,) * len(LAZY_FIELDS)          # a stub record's lazy norms, none computed yet (rec.computed())


class Known(BalancedStop):
    """Bound = max |z - z_star| (the true error), estimate = ``eta``; ``calls`` counts the checks."""

    def __init__(self, eta, z_star=None, **kwargs):
        super().__init__(**kwargs)
        self.eta, self.z_star, self.calls = eta, z_star, []

    def algebraic_error_bound(self, rec):
        self.calls.append(rec.k + 1)
        return float(np.max(np.abs(rec.z - self.z_star)))

    def discretisation_estimate(self, rec):
        return self.eta


def test_fires_when_the_bound_is_below_gamma_times_the_estimate(vector_problem):
    z_star = solve(vector_problem, rho=1.0, order="zx", stop=ResidualTolerance(1e-14, 1e-14), max_iter=5000).z
    stop = Known(1e-5, z_star, gamma=0.1, every=5)
    res = solve(vector_problem, rho=1.0, policy="fixed", order="zx", stop=stop, max_iter=5000)
    assert res.converged and res.stopped_by == stop.name
    assert stop.algebraic <= 0.1 * 1e-5 == 0.1 * stop.discretisation
    assert np.max(np.abs(res.z - z_star)) <= 1e-6
    assert stop.calls[:2] == [1, 2] and stop.calls == stop.tests and stop.calls[-1] == res.iterations
    assert all(1 <= b - a <= 5 for a, b in zip(stop.calls, stop.calls[1:]))      # at most `every` apart
    assert stop.calls[:-1] and all(k < res.iterations for k in stop.calls[:-1])   # it did not fire earlier


def test_the_schedule_stops_near_the_crossing_with_few_tests(vector_problem):
    """Tested at every iteration the rule fires at the first iterate whose error is <= gamma eta (k_star);
    with the predicted schedule it fires at most 2 iterations later, after far fewer tests."""
    z_star = solve(vector_problem, rho=1.0, order="zx", stop=ResidualTolerance(1e-14, 1e-14), max_iter=5000).z
    run = lambda every: solve(vector_problem, rho=1.0, policy="fixed", order="zx",      # noqa: E731
                              stop=Known(1e-6, z_star, gamma=0.3, every=every), max_iter=5000)
    k_star = run(1).iterations
    stop = Known(1e-6, z_star, gamma=0.3, every=50)
    res = solve(vector_problem, rho=1.0, policy="fixed", order="zx", stop=stop, max_iter=5000)
    assert res.converged and k_star >= 20
    assert k_star <= res.iterations <= k_star + 2
    assert len(stop.tests) <= k_star / 3


def test_a_rule_used_again_starts_its_schedule_again(vector_problem):
    """A Coulomb fixed point runs ADMM again with the same rule: the second run is tested from iteration 1,
    as a fresh rule's would be, and stops where a fresh rule stops."""
    z_star = solve(vector_problem, rho=1.0, order="zx", stop=ResidualTolerance(1e-14, 1e-14), max_iter=5000).z
    run = lambda stop: solve(vector_problem, rho=1.0, policy="fixed", order="zx", stop=stop, max_iter=5000)  # noqa
    stop = Known(1e-6, z_star, gamma=0.3, every=50)
    first = run(stop)
    tested = len(stop.tests)
    again, fresh = run(stop), run(Known(1e-6, z_star, gamma=0.3, every=50))
    assert stop.tests[tested:tested + 2] == [1, 2]
    assert again.iterations == fresh.iterations == first.iterations


def test_a_plug_in_may_test_later_first():
    """``first_tests`` moves the first two tests; the defaults are iterations 1 and 2."""
    from types import SimpleNamespace

    class Late(Known):
        first_tests = (2, 3)
    stop = Late(1.0, gamma=0.3, every=10)
    stop.algebraic_error_bound = lambda rec: 10.0
    moving = dict(primal_residual=1.0, x_change=1.0, z_change=1.0, computed=lambda: _NONE)
    assert [rec_k + 1 for rec_k in range(4) if stop.fired(SimpleNamespace(k=rec_k, **moving)) is None and
            (stop.tests and stop.tests[-1] == rec_k + 1)] == [2, 3]
    assert Known(1.0).first_tests == (1, 2)


def test_a_bound_that_does_not_fall_is_tested_at_doubling_intervals():
    """With nothing to predict from (the bound flat or rising), the interval after the first tests doubles up to
    ``every`` (1, 2, 4, 8, then 10): a bound that rises for a few iterations and then falls is caught within twice
    the iterations it took, not left for ``every``."""
    from types import SimpleNamespace

    stop = Known(1.0, gamma=0.3, every=10)
    stop.algebraic_error_bound = lambda rec: 10.0
    moving = dict(primal_residual=1.0, x_change=1.0, z_change=1.0, computed=lambda: _NONE)
    for k in range(40):
        assert stop.fired(SimpleNamespace(k=k, **moving)) is None
    assert stop.tests == [1, 2, 4, 8, 16, 26, 36]
    assert not stop.converging


def test_a_bound_near_its_threshold_is_tested_at_every_iteration():
    """Within NEAR x gamma x the estimate one iteration may cross the threshold (a cold radial P2 level's bound
    fell from 3.3 to 0.6 of the estimate in one iteration after a plateau), so the bound is tested at every
    iteration there, flat or not; above it the doubling intervals stay."""
    from types import SimpleNamespace

    from admmkit.fe.balanced_stop import NEAR

    moving = dict(primal_residual=1.0, x_change=1.0, z_change=1.0, computed=lambda: _NONE)
    for bound, tests in ((0.9 * NEAR * 0.3, list(range(1, 21))), (1.1 * NEAR * 0.3, [1, 2, 4, 8, 16])):
        stop = Known(1.0, gamma=0.3, every=10)                    # estimate 1: the threshold is 0.3
        stop.algebraic_error_bound = lambda rec, b=bound: b
        for k in range(20):
            assert stop.fired(SimpleNamespace(k=k, **moving)) is None
        assert stop.tests == tests


def test_an_iterate_that_stopped_changing_is_tested_at_once():
    """ADMM's fixed point (x, z and lam unchanged) is tested whatever the schedule, so a run started on the
    solution ends converged, not stalled (tests/problems/test_obstacle_warm_start.py runs one)."""
    from types import SimpleNamespace

    class Late(Known):
        first_tests = (2, 3)
    stop = Late(1.0, gamma=0.3, every=10)
    stop.algebraic_error_bound = lambda rec: 0.0
    assert stop.fired(SimpleNamespace(k=0, primal_residual=1e-9, x_change=0.0, z_change=0.0, computed=lambda: _NONE)) is None
    assert stop.tests == []                                           # still moving: left to the schedule
    again = Late(1.0, gamma=0.3, every=10)
    again.algebraic_error_bound = lambda rec: 0.0
    assert again.fired(SimpleNamespace(k=0, primal_residual=0.0, x_change=0.0, z_change=0.0, computed=lambda: _NONE)) == again.name
    assert again.tests == [1]                                         # before the schedule's first test, 2


def test_an_infinite_bound_never_fires(scalar_problem):
    class Blind(Known):
        def algebraic_error_bound(self, rec):
            return math.inf
    stop = Blind(1.0)
    res = solve(scalar_problem, rho=1.0, policy="fixed", order="zx", stop=stop, max_iter=50)
    assert res.status.value == "max_iter" and math.isnan(stop.discretisation)


@pytest.mark.parametrize("kwargs, match", [({"gamma": 0}, r"gamma = 0 is outside the accepted range \(0, 1\]"),
                                           ({"gamma": float("nan")}, "gamma = nan"),
                                           ({"gamma": 1.5}, "gamma = 1.5"),
                                           ({"every": 0}, "every = 0 is outside")])
def test_bad_parameters_are_named(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Known(1.0, **kwargs)


def test_needed_unknowns_extrapolates_the_last_levels():
    """A capped adaptive run says what the target needs at the levels' own rate (N^-1/2 here: 100x the unknowns
    for a tenth of the error), and nothing when it cannot tell."""
    from types import SimpleNamespace as L

    from admmkit.fe.adaptive import needed_unknowns
    levels = [L(unknowns=n, relative_estimate=n ** -0.5) for n in (1e2, 1e3, 1e4)]
    text = needed_unknowns(levels, 1e-3)
    assert "N^-0.50" in text and "1.0e+06 unknowns" in text
    assert needed_unknowns(levels[:2], 1e-3) == ""
    assert needed_unknowns([L(unknowns=n, relative_estimate=0.1) for n in (1e2, 1e3, 1e4)], 1e-3) == ""


def test_the_estimate_is_computed_only_near_firing():
    """The dearer estimate is taken afresh only where the bound is within 2 gamma x the last one, and the rule
    fires only on a fresh estimate: a bound halving each test meets a constant estimate of 1 at gamma 0.1."""
    from types import SimpleNamespace

    import admmkit

    class Counted(admmkit.BalancedStop):
        calls = 0

        def algebraic_error_bound(self, rec):
            return 2.0 ** -(rec.k // 10)                 # 1, 0.5, 0.25, ... at k = 9, 19, 29, ...

        def discretisation_estimate(self, rec):
            Counted.calls += 1
            return 1.0

    stop = Counted(gamma=0.1, every=10)
    fired = next(k for k in range(9, 80, 10) if stop.fired(SimpleNamespace(k=k)))
    # bounds 1, .5, .25, .125, .0625: estimated at k = 9 (first), then from .125 <= 0.2 on; fires at .0625
    assert fired == 49 and Counted.calls == 3 and stop.discretisation == 1.0 and stop.algebraic == 0.0625


def test_a_warm_level_holds_rho_then_hands_over_to_the_rule():
    from admmkit import IterationRecord  # noqa: F401  (the records are built by the loop; a stand-in here)
    from admmkit.fe.adaptive import HeldRho
    from admmkit.policies import Summable

    class Record:
        def __init__(self, k, rho):
            self.k, self.rho, self.lam_change, self.rho_Ax_change = k, rho, 10.0, 1.0     # w = 10: raise rho
    rule = HeldRho("summable", hold=3)
    rule.reset(5.0)
    assert [rule.update(Record(k, 5.0)) for k in range(3)] == [5.0, 5.0, 5.0]
    assert rule.update(Record(3, 5.0)) == 15.0                     # the wrapped rule's (1 + tau) rho
    assert rule.unchanged_until(0) == 3 and isinstance(rule.inner, Summable)
    with pytest.raises(ValueError, match="hold"):
        HeldRho("summable", hold=-1)


def test_keep_holds_rho_past_hold_while_it_says_so():
    """``keep`` (the balanced stop's ``converging``) holds rho after ``hold``; once it turns False the rule acts."""
    from admmkit.fe.adaptive import HeldRho

    class Record:
        def __init__(self, k, rho):
            self.k, self.rho, self.lam_change, self.rho_Ax_change = k, rho, 10.0, 1.0     # w = 10: raise rho
    state = {"converging": True}
    rule = HeldRho("summable", hold=2, keep=lambda: state["converging"])
    rule.reset(5.0)
    assert [rule.update(Record(k, 5.0)) for k in range(6)] == [5.0] * 6
    state["converging"] = False
    assert rule.update(Record(6, 5.0)) == 15.0
    with pytest.raises(ValueError, match="keep"):
        HeldRho("summable", keep=3)


def test_converging_says_whether_the_crossing_is_predicted_within_every():
    """A bound falling 2x an iteration towards gamma x 1: predicted within ``every`` once two tests are taken;
    a bound that does not fall predicts nothing."""
    from types import SimpleNamespace

    import admmkit

    class Falling(admmkit.BalancedStop):
        def algebraic_error_bound(self, rec):
            return self.bounds[rec.k]

        def discretisation_estimate(self, rec):
            return 1.0

    stop = Falling(gamma=0.1, every=5)
    stop.bounds = [0.8 * 2.0 ** -k for k in range(10)]                # tests at iterations 1, 2, then predicted
    assert stop.fired(SimpleNamespace(k=0)) is None and not stop.converging       # one test: no rate yet
    assert stop.fired(SimpleNamespace(k=1)) is None and stop.converging           # 0.4 -> 0.1 in 2 iterations
    flat = Falling(gamma=0.1, every=5)
    flat.bounds = [0.8] * 10
    flat.fired(SimpleNamespace(k=0))
    flat.fired(SimpleNamespace(k=1))
    assert not flat.converging
    slow = Falling(gamma=0.1, every=5)
    slow.bounds = [0.8 * 0.99 ** k for k in range(10)]                 # 200 iterations away: not within 5
    slow.fired(SimpleNamespace(k=0))
    slow.fired(SimpleNamespace(k=1))
    assert not slow.converging


def test_a_bound_that_falls_by_less_than_rounding_is_scheduled_without_a_prediction():
    """A bound that falls by one ulp per test (q rounds to 1, log q = 0) above a tiny estimate: the schedule
    doubles its intervals as for a flat bound, instead of dividing by log q = 0 (ZeroDivisionError before)."""
    from types import SimpleNamespace

    stop = Known(1e-8, gamma=0.3, every=10)
    bounds = iter(1.66e-7 - 2.6e-23 * i for i in range(100))     # one ulp less per test
    stop.algebraic_error_bound = lambda rec: next(bounds)
    moving = dict(primal_residual=1.0, x_change=1.0, z_change=1.0, computed=lambda: _NONE)
    for k in range(40):
        assert stop.fired(SimpleNamespace(k=k, **moving)) is None
    assert len(stop.tests) >= 4 and max(b - a for a, b in zip(stop.tests, stop.tests[1:])) <= 10
