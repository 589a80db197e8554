"""Anderson's interval (SCS >= 3.2's acceleration_interval): a step after every k-th iteration, the others plain."""
import numpy as np
import pytest

from admmkit.loop.acceleration import INTERVAL, Anderson


@pytest.mark.parametrize("bad", [0, -3, 2.5, True, "10", None.__class__])
def test_a_bad_interval_is_named(bad):
    with pytest.raises(ValueError, match="interval .* integer >= 1"):
        Anderson(interval=bad)


def test_the_default_interval_is_the_measured_one():
    assert Anderson().interval == INTERVAL == 10 and Anderson(interval=np.int64(3)).interval == 3
    assert "interval=10" in repr(Anderson())


def contraction_calls(accel, calls, reset_after=None):
    """Propose along a linear contraction s -> f = 0.5 s + c, one call per iteration; the calls after which the
    extrapolated count grew (1-based), resetting (a change of rho) after call ``reset_after``."""
    inner = lambda u, v: float(np.dot(u, v))
    rng = np.random.default_rng(4)
    c, scale = rng.standard_normal(6), np.linspace(0.2, 0.9, 6)
    s = (np.zeros(6), np.zeros(6))
    accel.start()
    grew = []
    for k in range(1, calls + 1):
        f = (scale * s[0] + c, 0.5 * s[1] - c)
        before = accel.stats["extrapolated"]
        s = accel.propose(s, f, 1.0, inner)
        if accel.stats["extrapolated"] > before:
            grew.append(k)
        if k == reset_after:
            accel.reset()
    return grew


@pytest.mark.parametrize("bound", [False, True], ids=["numpy", "kernel"])
def test_steps_come_every_interval_and_restart_with_the_memory(bound):
    """Interval 3: the 3rd call seeds the memory, the 6th extrapolates, every 3rd after it too; a reset (a change of
    rho) restarts the clock: 3 calls to seed again, 3 more to extrapolate.  The same calls on numpy's path and the
    kernel's (admmkit.loop.anderson_kernel)."""
    accel = Anderson(m=4, interval=3)
    if bound:
        accel.bind(np.ones(6), 6)
    assert contraction_calls(accel, 15) == [6, 9, 12, 15]
    assert accel.stats["rejected"] == 0
    assert contraction_calls(accel, 20, reset_after=7) == [6, 13, 16, 19]


@pytest.mark.parametrize("bound", [False, True], ids=["numpy", "kernel"])
def test_interval_one_steps_after_every_iteration(bound):
    """Interval 1 is the step after every iteration (the accelerator before the interval): from the 2nd call on,
    every call extrapolates on this contraction."""
    accel = Anderson(m=4, interval=1)
    if bound:
        accel.bind(np.ones(6), 6)
    assert contraction_calls(accel, 12) == list(range(2, 13))


class Logged(Anderson):
    """Anderson on numpy's path noting, per call, whether it extrapolated and whether it rejected."""

    def start(self):
        super().start()
        self.log = []

    def propose(self, s, f, rho, inner):
        e, r = self.stats["extrapolated"], self.stats["rejected"]
        out = super().propose(s, f, rho, inner)
        self.log.append((self.stats["extrapolated"] > e, self.stats["rejected"] > r))
        return out


def test_the_safeguard_looks_at_the_iteration_right_after_an_extrapolation():
    """With interval 4 a rejection comes at the call right after an extrapolation (SCS's aa_safeguard), not 4 calls
    later; extrapolations come at calls 4 apart, counted from the last step (a rejection restarts the clock)."""
    import admmkit
    from test_acceleration import lasso
    accel = Logged(m=6, interval=4)
    admmkit.solve(lasso(seed=3), rho=1e-2, order="zx", acceleration=accel,
                  stop=admmkit.ResidualTolerance(1e-10, 1e-10), max_iter=3000)
    extrapolated = [k for k, (e, _) in enumerate(accel.log) if e]
    rejected = [k for k, (_, r) in enumerate(accel.log) if r]
    assert len(extrapolated) > 10 and rejected
    assert all(k - 1 in extrapolated for k in rejected)
    steps = sorted(set(extrapolated) | set(rejected))
    gaps = [b - a for a, b in zip(steps, steps[1:]) if b not in rejected]
    assert all(gap % 4 == 0 for gap in gaps), gaps
