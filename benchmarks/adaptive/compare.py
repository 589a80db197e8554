"""The numbers of ``admmkit bench adaptive``'s report: a method at a common true error, ratios, rates.

At a common true error e* (1e-3 where both methods reach it, else the
smallest error both reach), the unknowns and the wall time each method needs,
interpolated linearly in log-log between the two levels on either side of
e*; their ratios uniform / adaptive (and a priori / adaptive for Hertz); the
convergence rates (least-squares slope of log error against log unknowns
over the finer half of the levels); the effectivity range; the iterations
per level; Hertz's errors in a and p0.  Levels whose true error is NaN (not
measurable by the energy, ``contact.py``) are left out of all of it.
"""
from __future__ import annotations

import math

import numpy as np

GROUPS = (("obstacle", 1, "radial obstacle, P1 (exact solution)"), ("obstacle", 2, "radial obstacle, P2 (exact solution)"),
          ("ex1", 1, "contact Example 1, P1"),
          ("ex1", 2, "contact Example 1, P2"), ("ex2", 2, "contact Example 2, P2"), ("hertz", 1, "contact Hertz, P1"),
          ("hertz", 2, "contact Hertz, P2"))
#: today's stop on uniform meshes, by x-step (in P1, the plug-in's model before adaptivity: every order is
#: compared with it)
TODAY = {"uniform_today": "SuperLU x-step (the default)", "uniform_today_amg": "AMG-CG x-step (--backend iterative)"}
TARGET_ERROR = 1e-3
#: Hertz's a and p0 errors are summed up over the meshes of at least this many unknowns
HERTZ_FINE = 5_000


def series(rows: list[dict], scene: str, order: int, method: str) -> list[dict]:
    """The rows of one scene, order and method with a finite true error, by unknowns (today's stop: P1's)."""
    order = 1 if method in TODAY else order
    return sorted((r for r in rows if (r["scene"], r["order"], r["method"]) == (scene, order, method)
                   and math.isfinite(r["true_error"])), key=lambda r: r["unknowns"])


def at_error(rows: list[dict], key: str, error: float) -> float | None:
    """``key`` (unknowns or wall_seconds) where the true error first falls to ``error`` (log-log interpolation).

    None if it never does; the first level's value if that level is already below.
    """
    for i, r in enumerate(rows):
        if r["true_error"] <= error:
            if i == 0:
                return float(r[key])
            a, b = rows[i - 1], r
            t = math.log(error / a["true_error"]) / math.log(b["true_error"] / a["true_error"])
            return float(math.exp(math.log(a[key]) + t * (math.log(b[key]) - math.log(a[key]))))
    return None


def common_error(a: list[dict], b: list[dict]) -> float:
    """1e-3 if both series reach it, else the smallest true error both reach."""
    reach = max(min(r["true_error"] for r in a), min(r["true_error"] for r in b))
    return max(reach, TARGET_ERROR)


def rate(rows: list[dict]) -> float:
    """Slope of log true error against log unknowns over the finer half of the levels (at least 3)."""
    tail = rows[-max(3, len(rows) // 2):]
    if len(tail) < 2:
        return math.nan
    return float(np.polyfit(np.log([r["unknowns"] for r in tail]), np.log([r["true_error"] for r in tail]), 1)[0])


def comparison(rows: list[dict]) -> list[dict]:
    """Per scene: the common error, unknowns and wall time of each method there, and the ratios."""
    out = []
    for scene, order, title in GROUPS:
        ad, un = series(rows, scene, order, "adaptive"), series(rows, scene, order, "uniform")
        if not ad or not un:
            continue
        e = common_error(ad, un)
        c = {"scene": title, "error": e}
        for name, s in (("adaptive", ad), ("uniform", un), ("uniform_today", series(rows, scene, order,
                                                                                      "uniform_today"))):
            c[f"{name}_unknowns"] = at_error(s, "unknowns", e) if s else None
            c[f"{name}_seconds"] = at_error(s, "wall_seconds", e) if s else None
            c[f"{name}_rate"] = rate(s) if s else None
        c["unknowns_ratio"] = _ratio(c["uniform_unknowns"], c["adaptive_unknowns"])
        c["time_ratio"] = _ratio(c["uniform_seconds"], c["adaptive_seconds"])
        c["today"] = {}
        for method in TODAY:
            today = series(rows, scene, order, method)
            if today:
                e_today = common_error(ad, today)
                t, a = at_error(today, "wall_seconds", e_today), at_error(ad, "wall_seconds", e_today)
                c["today"][method] = {"error": e_today, "seconds": t, "adaptive_seconds": a, "ratio": _ratio(t, a)}
        c["at_target"] = {"adaptive_unknowns": at_error(ad, "unknowns", TARGET_ERROR),
                          "adaptive_seconds": at_error(ad, "wall_seconds", TARGET_ERROR),
                          "uniform_unknowns": at_error(un, "unknowns", TARGET_ERROR),
                          "uniform_extrapolated": _extrapolate(un, TARGET_ERROR)}
        eff = [r["effectivity"] for r in ad]
        c["effectivity"] = (min(eff), max(eff))
        c["iterations"] = [r["iterations"] for r in ad]
        warm_cold = [r["iterations"] / r["cold_iterations"] for r in ad[1:]]
        c["warm_over_cold"] = (float(np.median(warm_cold)), max(warm_cold)) if warm_cold else None
        c["cold_iterations"] = [r["cold_iterations"] for r in ad]
        alg = [r["algebraic_over_estimate"] for r in ad if np.isfinite(r.get("algebraic_over_estimate", np.nan))]
        c["algebraic"] = (min(alg), float(np.median(alg)), max(alg), len(alg), len(ad)) if alg else None
        c["uniform_iterations"] = [r["iterations"] for r in un]
        c["a_priori"] = _a_priori(ad, series(rows, scene, order, "a_priori"))
        c["hertz"] = {m: hertz_errors(series(rows, scene, order, m)) for m in ("adaptive", "uniform", "a_priori")
                      if scene == "hertz"}
        out.append(c)
    return out


def _extrapolate(rows: list[dict], error: float) -> float | None:
    """Unknowns where the series would reach ``error`` at the rate of its two finest meshes (not run)."""
    if len(rows) < 2 or rows[-1]["true_error"] <= error:
        return None
    a, b = rows[-2], rows[-1]
    slope = math.log(b["true_error"] / a["true_error"]) / math.log(b["unknowns"] / a["unknowns"])
    return b["unknowns"] * (error / b["true_error"]) ** (1 / slope) if slope < 0 else None


def _ratio(a, b):
    return a / b if a is not None and b else None


def _measured(v) -> bool:
    """A finite number (a CSV read back gives '' where a level has no Hertz measure)."""
    return isinstance(v, (int, float)) and math.isfinite(v)


def _a_priori(ad: list[dict], ap: list[dict]) -> dict | None:
    """The a priori meshes against adaptive at the smallest error both reach (1e-3 at the least)."""
    if not ap:
        return None
    e = common_error(ad, ap)
    c = {"error": e, "smallest": min(r["true_error"] for r in ap)}
    for name, s in (("adaptive", ad), ("a_priori", ap)):
        c[f"{name}_unknowns"], c[f"{name}_seconds"] = at_error(s, "unknowns", e), at_error(s, "wall_seconds", e)
    c["unknowns_ratio"] = _ratio(c["a_priori_unknowns"], c["adaptive_unknowns"])
    c["time_ratio"] = _ratio(c["a_priori_seconds"], c["adaptive_seconds"])
    return c


def hertz_errors(rows: list[dict]) -> dict | None:
    """a and p0 errors: on the finest mesh, and the largest in size over the meshes of >= HERTZ_FINE unknowns."""
    fine = [r for r in rows if r["unknowns"] >= HERTZ_FINE and _measured(r.get("a_error"))]
    if not fine:
        return None
    return {"unknowns": fine[-1]["unknowns"], "a": fine[-1]["a_error"], "p0": fine[-1]["p0_error"],
            "a_max": max(abs(r["a_error"]) for r in fine), "p0_max": max(abs(r["p0_error"]) for r in fine),
            "meshes": len(fine)}
