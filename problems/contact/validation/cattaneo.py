"""Cattaneo-Mindlin partial slip of a cylinder: the Coulomb validation (plane strain).

The Hertz half-cylinder of :mod:`admmkit.problems.contact.validation.hertz` (radius R, top
clamped, the plane raised by delta) is also sheared: the plane moves by
``obstacle_slide`` = delta_t along x, the same as moving the clamped top by
-delta_t.  With the measured normal load P and tangential load Q < mu P,
Cattaneo (1938) and Mindlin (1949) give, for two half-spaces without
normal-tangential coupling (K. L. Johnson, *Contact Mechanics*, 1985,
section 7.1), the traction

    q(x) = mu p0 sqrt(1 - x^2/a^2) - mu p0 (c/a) sqrt(1 - x^2/c^2)   (|x| < c, stick)
    q(x) = mu p(x)                                                   (c < |x| < a, slip)

with the stick half-width c = a sqrt(1 - Q/(mu P)) and the peak of |q| at
|x| = c: q_max = mu p0 sqrt(1 - c^2/a^2) = mu p0 sqrt(Q/(mu P)).

**Coupling.** For a rigid plane on an elastic body the coupling is Dundurs'
beta = (1 - 2 nu) / (2 (1 - nu)); it vanishes for nu = 1/2, and then the
shear changes neither the pressure nor the contact width (and the pressing
causes no tangential slip, so the static problem solved in one step is the
loading path "press, then shear").  We run near it, nu = 0.49 (beta = 0.0196)
by default; what remains shows as a shift of the stick zone off the centre
(``stick_shift``) and a change of the pressure against the frictionless run.
"""
from __future__ import annotations

import math

import numpy as np

from admmkit.problems.contact.validation.hertz import HertzCase, hertz_half_width, hertz_peak_pressure


def dundurs_beta(nu: float) -> float:
    """Dundurs' coupling parameter of an elastic body on a rigid plane: (1 - 2 nu) / (2 (1 - nu))."""
    return (1.0 - 2.0 * nu) / (2.0 * (1.0 - nu))


def stick_half_width(a: float, Q: float, mu: float, P: float) -> float:
    """c = a sqrt(1 - Q/(mu P)) (Cattaneo-Mindlin), for 0 <= Q <= mu P."""
    ratio = Q / (mu * P)
    if not 0 <= ratio <= 1:
        raise ValueError(f"Q/(mu P) = {ratio:g}; accepted: 0 <= Q <= mu P (partial slip)")
    return a * math.sqrt(1.0 - ratio)


def cattaneo_traction(x: np.ndarray, P: float, Q: float, mu: float, R: float, E: float, nu: float) -> np.ndarray:
    """|q(x)| of Cattaneo-Mindlin at loads P, Q (Hertz's a and p0 from P)."""
    a = hertz_half_width(P, R, E, nu)
    p0 = hertz_peak_pressure(P, a)
    c = stick_half_width(a, Q, mu, P)
    x = np.abs(np.asarray(x, dtype=float))
    q = mu * p0 * np.sqrt(np.maximum(1 - (x / a) ** 2, 0.0))
    return q - np.where(x < c, mu * p0 * (c / a) * np.sqrt(np.maximum(1 - (x / c) ** 2, 0.0)), 0.0)


def cattaneo_scene(case: HertzCase, h_c: float, mu: float, slide: float, delta: float | None = None):
    """The Hertz scene of ``case`` with Coulomb friction mu and the plane moved by ``slide`` along x."""
    import dataclasses
    return dataclasses.replace(case.scene(h_c, delta), tangential="coulomb", mu=mu, obstacle_slide=slide,
                               name=f"cattaneo(h_c={h_c:.3g})")


def measure_stick(sol, case: HertzCase, mu: float) -> dict:
    """Stick half-width, peak tractions and loads of a Coulomb solution, and Cattaneo-Mindlin's values.

    P = sum mc p_n and Q = |sum mc q| (measured); c_h: on each side, d = mu p_n - |q| (zero in the
    slip zone, ~ sqrt(c^2 - x^2) inside the stick zone near its edge) has d^2 linear in x^2, extrapolated
    to zero from the two outermost stick nodes; c_h the mean of both sides, ``stick_shift`` half their
    difference (0 without coupling).  a_h as in :func:`admmkit.problems.contact.validation.hertz.measure`.
    """
    from admmkit.problems.contact.validation.hertz import measure
    ops = sol.ops
    x = ops.xc[:, 0]
    p = sol.pressure
    q = np.abs(sol.tangential_traction[0])
    hertz = measure(ops, p, sol.result.z[: ops.n_c], case)
    P, a_h = hertz["P"], hertz["a_h"]
    Q = abs(float(ops.mc @ sol.tangential_traction[0]))
    zones = sol.zones
    stick = zones == 1
    if stick.sum() < 2:
        raise ValueError("fewer than two stick nodes: lower the slide or refine")
    d = mu * p - q
    sides = []
    for side in (+1, -1):
        idx = np.flatnonzero(stick & (side * x >= 0))
        idx = idx[np.argsort(side * x[idx])]
        last, prev = idx[-1], idx[-2]
        d_last, d_prev = d[last] ** 2, d[prev] ** 2
        if d_prev > d_last:
            x2 = x[last] ** 2 + d_last * (x[last] ** 2 - x[prev] ** 2) / (d_prev - d_last)
            sides.append(math.sqrt(x2))
        else:
            sides.append(abs(x[last]))
    c_h = float(np.mean(sides))
    ratio = Q / (mu * P)
    c_ref = a_h * math.sqrt(max(1 - ratio, 0.0))                 # with the measured contact width
    c_theory = hertz["a_hertz"] * math.sqrt(max(1 - ratio, 0.0))  # with Hertz's width at the measured P
    q_max_ref = mu * hertz["p0_hertz"] * math.sqrt(min(ratio, 1.0))
    return {"P": P, "Q": Q, "Q_over_muP": ratio, "a_h": a_h, "a_hertz": hertz["a_hertz"],
            "p0_h": hertz["p0_h"], "p0_hertz": hertz["p0_hertz"], "p0_err": hertz["p0_err"], "a_err": hertz["a_err"],
            "c_h": c_h, "c_ref": c_theory, "c_ref_measured_a": c_ref, "c_err": c_h / c_theory - 1.0,
            "stick_shift": float((sides[0] - sides[1]) / 2), "stick_nodes": int(stick.sum()),
            "q_max_h": float(q.max()), "q_max_ref": q_max_ref, "q_max_err": float(q.max()) / q_max_ref - 1.0}
