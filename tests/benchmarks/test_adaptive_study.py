"""``admmkit bench adaptive --quick``: the files, and numbers that hang together."""
import csv
import math
import subprocess
import sys

import pytest

from admmkit.fe.balanced_stop import GAMMA
from admmkit.problems.obstacle.estimate import OBSTACLE_GAMMA
from admmkit.benchmarks.adaptive.compare import at_error, common_error, comparison, rate
from admmkit.benchmarks.adaptive.hertz import penetration_term

pytestmark = pytest.mark.study      # the whole adaptive study's smoke run (its fixture runs the study)


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    """Run the quick study once through the command line; its folder, rows and summary."""
    out = tmp_path_factory.mktemp("adaptive")
    done = subprocess.run([sys.executable, "-m", "admmkit", "bench", "adaptive", "--quick", "--out", str(out)],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    with open(out / "adaptive.csv", newline="") as fh:
        rows = [{k: _number(v) for k, v in r.items()} for r in csv.DictReader(fh)]
    return out, rows, (out / "adaptive.md").read_text()


def _number(v):
    if v == "":
        return math.nan                 # write_csv leaves NaN (not measured) empty
    try:
        return int(v)
    except ValueError:
        try:
            return float(v)
        except ValueError:
            return v


def test_the_files_are_written(quick):
    out, rows, md = quick
    for name in ("adaptive.csv", "adaptive.md", "adaptive.png", "adaptive_levels.png"):
        assert (out / name).stat().st_size > 0
    assert {(r["scene"], r["order"], r["method"]) for r in rows} == {
        ("obstacle", 1, "adaptive"), ("obstacle", 1, "uniform"), ("obstacle", 1, "uniform_today"),
        ("obstacle", 1, "uniform_today_amg"), ("obstacle", 2, "adaptive"), ("obstacle", 2, "uniform"),
        ("ex1", 1, "adaptive"), ("ex1", 1, "uniform"), ("ex1", 2, "adaptive"),
        ("ex1", 2, "uniform"), ("ex2", 2, "adaptive"), ("ex2", 2, "uniform"), ("hertz", 1, "adaptive"),
        ("hertz", 1, "uniform"), ("hertz", 1, "a_priori"), ("hertz", 2, "adaptive"), ("hertz", 2, "uniform"),
        ("hertz", 2, "a_priori")}
    assert "## At the same true error" in md and "Made by `admmkit bench adaptive --quick" in md
    assert "SuperLU x-step (the default)" in md and "AMG-CG x-step (--backend iterative)" in md   # today, both


def test_errors_fall_with_refinement_and_the_estimates_are_effective(quick):
    _, rows, _ = quick
    for key in {(r["scene"], r["order"], r["method"]) for r in rows if r["scene"] != "hertz"}:   # Hertz: below
        s = sorted((r for r in rows if (r["scene"], r["order"], r["method"]) == key), key=lambda r: r["unknowns"])
        # NaN: not measurable by the energy (an x-iterate a little infeasible has J(u_h) below the quick J_ref)
        errors = [r["true_error"] for r in s if math.isfinite(r["true_error"])]
        assert len(errors) >= len(s) - 1, (key, [r["true_error"] for r in s])
        assert all(b < a for a, b in zip(errors, errors[1:])), (key, errors)
        measured = [r for r in s if math.isfinite(r["true_error"])]
        assert all(0 < r["effectivity"] < math.inf for r in measured), key
        assert all(0.3 < r["effectivity"] < 3 for r in measured), key     # the factor 3 band, around 1
        # today's stop (RelativeChange) may end converged_inaccurate: its complementarity check (issue #24)
        allowed = {"converged", "converged_inaccurate"} if key[2].startswith("uniform_today") else {"converged"}
        assert all(r["status"] in allowed for r in s), key
        if key[2] == "adaptive":
            assert errors[-1] < 0.5 * errors[0]
            # not the obstacle: its warm levels hold rho for one test interval (a move costs the x-step), so a
            # coarse level whose inherited rho is untuned takes one interval more (20 against 10); nor Example 2
            # (nu = 0.49), whose finer levels need more iterations than its first, warm or cold (28, 30 against 26)
            if key[0] not in ("obstacle", "ex2"):
                assert all(r["iterations"] <= s[0]["iterations"] for r in s[1:]), key     # the warm start
            # against a cold start there; each run schedules its tests by its own bounds (admmkit.fe.balanced_stop),
            # so a warm level may stop a few iterations after a cold one (obstacle P1, 89 unknowns: 13 against 11)
            assert all(r["iterations"] <= r["cold_iterations"] + 3 for r in s[1:]), key
            # the balanced stop's guarantee, checked against the exact discrete solution of each level
            ratios = [r["algebraic_over_estimate"] for r in s]
            gamma = OBSTACLE_GAMMA if key[0] == "obstacle" else GAMMA     # each plug-in's default
            assert all(0 < a <= gamma * (1 + 1e-6) for a in ratios if math.isfinite(a)), (key, ratios)
            assert sum(math.isfinite(a) for a in ratios) >= len(ratios) - 1, (key, ratios)
        else:
            assert all(r["iterations"] == r["cold_iterations"] for r in s), key


def test_adaptive_needs_fewer_unknowns_on_example1(quick):
    _, rows, _ = quick
    comp = {c["scene"]: c for c in comparison(rows)}
    for name in ("Example 1, P1", "Example 1, P2", "Example 2, P2"):
        c = comp[f"contact {name}"]
        assert c["unknowns_ratio"] is not None and c["unknowns_ratio"] > 1.5, c
        assert c["adaptive_rate"] < c["uniform_rate"] < 0                 # steeper: errors fall faster
    assert comp["radial obstacle, P1 (exact solution)"]["uniform_rate"] == pytest.approx(-0.5, abs=0.1)


def test_hertz_adaptive_beats_uniform_and_a_priori_and_resolves_a_and_p0(quick):
    _, rows, md = quick
    comp = {c["scene"]: c for c in comparison(rows)}
    for order in (1, 2):
        c = comp[f"contact Hertz, P{order}"]
        assert c["unknowns_ratio"] > 5 and c["adaptive_rate"] < 0 and c["uniform_rate"] < 0, c
        uniform = [r for r in rows if (r["scene"], r["order"], r["method"]) == ("hertz", order, "uniform")
                   and math.isfinite(r["true_error"])]
        if len(uniform) >= 3:          # a rate from two meshes (quick P2: the coarsest is NaN) compares nothing
            assert c["adaptive_rate"] < c["uniform_rate"], c
        assert c["a_priori"]["unknowns_ratio"] > 1.5, c["a_priori"]          # the zone alone does not carry the energy
        ad = [r for r in rows if (r["scene"], r["order"], r["method"]) == ("hertz", order, "adaptive")]
        measured = [r for r in ad if math.isfinite(r["true_error"])]
        assert len(measured) >= len(ad) - 2                                  # NaN only on the coarsest levels
        assert all(0.5 <= r["effectivity"] <= 3 for r in measured), [r["effectivity"] for r in measured]
        assert all(r["status"] == "converged" for r in ad)
    finest = max((r for r in rows if (r["scene"], r["order"], r["method"]) == ("hertz", 2, "adaptive")),
                 key=lambda r: r["unknowns"])
    assert abs(finest["a_error"]) < 0.01 and abs(finest["p0_error"]) < 0.02, finest     # against Hertz's formulas
    assert "Hertz against the a priori local refinement" in md and "p0 error (Hertz)" in md


@pytest.mark.parametrize("order", [1, 2])
def test_the_penetration_term_is_the_overlap_of_the_interpolated_parabola(order):
    """All nodes in contact, p = 1: c_h = int (I_h g - g) dx, s^3 / (12 R) a P1 element, 0 in P2 (exact)."""
    from types import SimpleNamespace

    import numpy as np
    import scipy.sparse as sp
    from admmkit.problems.contact.validation.hertz import HertzCase
    case = HertzCase(profile="parabola", R=2.0)
    x = np.linspace(-0.04, 0.04, 9)[::-1]                    # not in the order of x: a refined mesh's are not
    g = case.gap(case.delta_guess())(x, 0.0)
    ops = SimpleNamespace(xc=np.column_stack([x, np.zeros_like(x)]), mc=np.ones_like(x), g=g, B=sp.identity(9),
                          scene=SimpleNamespace(order=order))
    res = SimpleNamespace(x=g, lam=np.ones_like(x), z=g)
    s = 0.01
    expected = 8 * s ** 3 / (12 * case.R) if order == 1 else 0.0
    assert penetration_term(case, ops, res) == pytest.approx(expected, abs=1e-16)
    res.z = g - 1.0                                          # no node active: no element counted
    assert penetration_term(case, ops, res) == 0.0


def test_interpolation_at_a_common_error():
    a = [{"unknowns": 100, "wall_seconds": 1.0, "true_error": 1e-1}, {"unknowns": 10000, "wall_seconds": 4.0,
                                                                      "true_error": 1e-3}]
    b = [{"unknowns": 100, "wall_seconds": 1.0, "true_error": 5e-2}]
    assert at_error(a, "unknowns", 1e-2) == pytest.approx(1000)
    assert at_error(a, "wall_seconds", 1e-2) == pytest.approx(2.0)
    assert at_error(a, "unknowns", 1e-4) is None
    assert at_error(b, "unknowns", 1e-1) == 100
    assert common_error(a, b) == 5e-2 and common_error(a, a) == 1e-3
    assert rate(a) == pytest.approx(-1.0)


def test_the_energy_floor_is_the_largest_rise_between_levels():
    """Energies that only fall leave every true error measurable; a rise r sets the floor sqrt(2 r) / ||u||_a."""
    from admmkit.benchmarks.adaptive.contact import energy_floor
    assert energy_floor([3.0, 2.0, 1.5, 1.25], 2.0) == 0.0
    assert energy_floor([3.0, 2.0, 2.5, 1.0, 1.08], 2.0) == pytest.approx(math.sqrt(2 * 0.5) / 2.0)
    assert energy_floor([1.0], 1.0) == 0.0
