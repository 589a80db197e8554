"""The statistics of the QP study: shifted geometric means, success per configuration, performance profiles, the targets and the time per iteration."""
from __future__ import annotations

import math
import numpy as np

from admmkit.benchmarks.runner.profiles import cost_table, profile

RHO0 = 0.1
SHIFT = 10.0
#: the label of OSQP called directly
OSQP_DIRECT = "OSQP"
#: mid-sized problems for the time per iteration: MID_SIZE[0] <= n + m <= MID_SIZE[1]
MID_SIZE = (1000, 20000)


# ---------------------------------------------------------------- statistics
def shifted_geometric_mean(values, shift: float = SHIFT) -> float:
    """exp(mean(log(v + shift))) - shift (Mittelmann's shifted geometric mean)."""
    v = np.asarray(list(values), dtype=float)
    if v.size == 0:
        return math.nan
    return float(np.exp(np.mean(np.log(v + shift))) - shift)


def config_keys(rows: list[dict]) -> list[tuple[str, str, str]]:
    """(variant, solver, order) triples in first-seen order."""
    return list(dict.fromkeys((r["variant"], r["solver"], r["order"]) for r in rows))


def label(key: tuple[str, str, str]) -> str:
    """'preset/osqp (xz)', 'OSQP', 'OSQP + polish'."""
    variant, solver, order = key
    if solver == OSQP_DIRECT:
        return OSQP_DIRECT + (" + polish" if variant == "polish" else "")
    return f"{variant}/{solver} ({order})"


def summarize(rows: list[dict], max_iter: int, time_limit: float) -> list[dict]:
    """One line per (variant, solver, order, eps): successes by both judgements, shifted geometric means over the
    neutral successes, factorisations, failures (runs the neutral criteria rejected, by status)."""
    out = []
    for eps in sorted({r["eps"] for r in rows}, reverse=True):
        for key in config_keys(rows):
            sel = [r for r in rows if (r["variant"], r["solver"], r["order"]) == key and r["eps"] == eps]
            if not sel:
                continue
            ok = [_true(r["neutral"]) for r in sel]
            statuses: dict[str, int] = {}
            for r, good in zip(sel, ok):
                if not good:
                    name = r["status"] if r["status"] != "solved" else "solved, neutral criteria not met"
                    statuses[name] = statuses.get(name, 0) + 1
            facts = [float(r["factorizations"]) for r in sel]
            out.append({
                "eps": eps, "variant": key[0], "solver": key[1], "order": key[2], "problems": len(sel),
                "neutral": sum(ok), "solved": sum(_true(r["solved"]) for r in sel), "rate": sum(ok) / len(sel),
                "sgm_iterations": shifted_geometric_mean(
                    float(r["iterations"]) if good else max_iter for r, good in zip(sel, ok)),
                "sgm_time": shifted_geometric_mean(
                    float(r["time"]) if good else time_limit for r, good in zip(sel, ok)),
                "factorizations_mean": float(np.mean(facts)), "factorizations_max": int(max(facts)),
                "failures": statuses,
                "runaway": sum(1 for r in sel if _finite(r["rho_max"]) and float(r["rho_max"]) > 1e20 * RHO0),
            })
    return out


def performance_profile(rows: list[dict], metric: str, eps: float, keys=None):
    """Dolan-More profile over the neutral successes: {key: (taus, fraction of problems within tau x the best)}
    (the best among ``keys``, default every configuration)."""
    sel = [r for r in rows if r["eps"] == eps]
    keys = list(keys) if keys is not None else config_keys(sel)
    table = cost_table(sel, keys, metric, config=lambda r: (r["variant"], r["solver"], r["order"]),
                       solved=lambda r: _true(r["neutral"]))
    taus, fractions = profile(table)
    return {key: (taus, fractions[:, j]) for j, key in enumerate(keys)}


def target(summary: list[dict]) -> list[dict]:
    """Per accuracy: the best admmkit configuration without and with polishing against OSQP without and with it."""
    out = []
    for eps in sorted({s["eps"] for s in summary}, reverse=True):
        sel = [s for s in summary if s["eps"] == eps]
        for polish in (False, True):
            ours = [s for s in sel if s["solver"] != OSQP_DIRECT and (s["variant"] == "polish") == polish]
            theirs = [s for s in sel if s["solver"] == OSQP_DIRECT and (s["variant"] == "polish") == polish]
            if not ours or not theirs:
                continue
            best = max(ours, key=lambda s: (s["neutral"], -s["sgm_time"]))
            out.append({"eps": eps, "polish": polish, "best": label((best["variant"], best["solver"], best["order"])),
                        "best_neutral": best["neutral"], "osqp_neutral": theirs[0]["neutral"],
                        "problems": best["problems"], "met": best["neutral"] >= theirs[0]["neutral"]})
    return out


def time_per_iteration(rows: list[dict], mid=MID_SIZE) -> dict[float, dict]:
    """Per accuracy: time per iteration of preset/osqp (xz) over OSQP's, on mid-sized problems both solved
    by the neutral criteria: median, min, max and the count.  The loops' wall times (``loop_time``: admmkit's
    ``timings["total"]``, OSQP's ``info.solve_time``), measured in the same process one after the other."""
    out = {}
    for eps in sorted({r["eps"] for r in rows}, reverse=True):
        ours = {r["problem"]: r for r in rows if r["eps"] == eps and (r["variant"], r["solver"], r["order"])
                == ("preset", "osqp", "xz") and _true(r["neutral"])}
        ratios = []
        for r in rows:
            if (r["eps"] == eps and r["solver"] == OSQP_DIRECT and r["variant"] == "default" and _true(r["neutral"])
                    and r["problem"] in ours and mid[0] <= int(r["n"]) + int(r["m"]) <= mid[1]):
                o = ours[r["problem"]]
                ratios.append((float(o["loop_time"]) / int(o["iterations"]))
                              / (float(r["loop_time"]) / int(r["iterations"])))
        if ratios:
            out[eps] = {"median": float(np.median(ratios)), "min": float(min(ratios)), "max": float(max(ratios)),
                        "count": len(ratios)}
    return out


def _true(v) -> bool:
    return v is True or str(v) == "True"


def _finite(v) -> bool:
    try:
        return math.isfinite(float(v))
    except (TypeError, ValueError):
        return False
