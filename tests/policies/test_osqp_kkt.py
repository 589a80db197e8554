"""OSQP 1.x's KKT-error rho mode (``policies.OSQPKKTRule``) on hand-made residuals."""
import math
from types import SimpleNamespace

import pytest

import admmkit
from admmkit.policies import OSQPKKTRule


def feed(rule, errors, rho=1.0, interval=1):
    """Feed (r_rel, s_rel) pairs as the records of iterations 0, 1, ...; return the rho after each."""
    rule.residuals = lambda rec: errors[rec.k]
    rule.reset(rho)
    out = []
    for k in range(len(errors)):
        rho = rule.update(SimpleNamespace(k=k, rho=rho))
        out.append(rho)
    return out


def test_rho_moves_only_once_the_kkt_error_fell_to_the_fraction():
    rule = OSQPKKTRule(interval=1, tolerance=5.0, fraction=0.4)
    # error 1 (the reference), 0.5 (not below 0.4: no update though the estimate sqrt(100) = 10 is far off),
    # 0.39 (below: rho <- 1 * sqrt(0.39 / 0.0039) = 10)
    rhos = feed(rule, [(1.0, 0.01), (0.5, 0.005), (0.39, 0.0039)])
    assert rhos[:2] == [1.0, 1.0]
    assert rhos[2] == pytest.approx(10.0)
    assert rule.reference == pytest.approx(0.39)


def test_an_estimate_within_the_tolerance_is_not_adopted_but_resets_the_reference():
    rule = OSQPKKTRule(interval=1, tolerance=5.0, fraction=0.5)
    rhos = feed(rule, [(1.0, 1.0), (0.4, 0.2)])          # estimate sqrt(2) < 5: kept
    assert rhos == [1.0, 1.0] and rule.reference == pytest.approx(0.4)


def test_reads_every_interval_iterations_only():
    rule = OSQPKKTRule(interval=25)
    assert rule.unchanged_until(0) == 24 and rule.unchanged_until(25) == 49


def test_registered_and_checked():
    assert "osqp_kkt" in admmkit.policy_names()
    assert isinstance(admmkit.make_policy("osqp_kkt"), OSQPKKTRule)
    for bad in (0.0, 1.0, math.nan, "x"):
        with pytest.raises(ValueError, match="fraction"):
            OSQPKKTRule(fraction=bad)


# ---------------------------------------------------------------- OSQP's rule with each change priced
def test_a_priced_change_soon_after_the_last_needs_a_larger_disagreement():
    from admmkit.policies import OSQPPricedRule
    rule = OSQPPricedRule(interval=1, tolerance=5.0, price=100.0)
    # estimate 10 x rho: log 10 = 2.30 against log 5 x 100 / (k + 1) = 161 / (k + 1): kept until k = 68,
    # adopted at k = 69 (161 / 70 = 2.30 - 0.0005)
    errors = [(1.0, 0.01)] * 100
    rhos = feed(rule, errors)
    assert rhos[0] == 1.0 and rhos[68] == 1.0
    assert rhos[69] == pytest.approx(10.0)
    assert rule.last_change == 69


def test_price_zero_is_osqps_rule():
    from admmkit.policies import OSQPRule, OSQPPricedRule
    errors = [(1.0, 0.01), (0.5, 0.5), (0.001, 1.0), (1.0, 1.0)]
    assert feed(OSQPPricedRule(interval=1, price=0.0), errors) == feed(OSQPRule(interval=1), errors)


def test_priced_rule_is_registered_and_checked():
    from admmkit.policies import OSQPPricedRule
    assert isinstance(admmkit.make_policy("osqp_priced"), OSQPPricedRule)
    with pytest.raises(ValueError, match="price"):
        OSQPPricedRule(price=-1.0)
