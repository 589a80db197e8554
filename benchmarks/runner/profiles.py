"""Performance profiles (Dolan & More 2002) and the figures that show them.

A study measures a cost t[p, s] (iterations, seconds) of each solver s on
each problem p, with inf where s failed on p.  The profile of s is::

    rho_s(tau) = #{p : t[p, s] <= tau min_s' t[p, s']} / #problems,

the fraction of the problems that s solves within tau times the best cost
(a problem no solver solves counts against every solver).  rho_s(1) is the
share of problems on which s is the best (ties count for each), and
rho_s(inf) the share s solves at all.
"""
from __future__ import annotations

import math

import numpy as np

#: the floor of a cost, so that a zero cost (a solved start) does not divide by zero
FLOOR = 1e-9


def cost_table(rows, configs, metric: str, *, config, solved) -> np.ndarray:
    """problems x configurations: ``row[metric]`` where ``solved(row)``, inf where not (a missing run is a failure).

    Problems are ``row["problem"]`` in sorted order; ``config(row)`` names the column (rows of other
    configurations are left out).
    """
    problems = sorted({r["problem"] for r in rows})
    index, column = {p: i for i, p in enumerate(problems)}, {c: j for j, c in enumerate(configs)}
    table = np.full((len(problems), len(column)), np.inf)
    for r in rows:
        j = column.get(config(r))
        if j is not None and solved(r):
            table[index[r["problem"]], j] = float(r[metric])
    return table


def ratios(costs: np.ndarray) -> np.ndarray:
    """t[p, s] / min_s t[p, s]: the performance ratios (inf where s failed or no solver solved p)."""
    costs = np.maximum(np.asarray(costs, dtype=float), FLOOR)
    best = costs.min(axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(np.isfinite(best), costs / best, np.inf)


def profile(costs: np.ndarray, taus: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(taus, fractions[tau, s]): the profile of every column of ``costs`` (rows: problems)."""
    r = ratios(costs)
    if taus is None:
        finite = r[np.isfinite(r)]
        top = max(float(finite.max()) if finite.size else 2.0, 2.0)
        taus = np.logspace(0, math.log10(top) + 0.05, 400)
    if r.shape[0] == 0:
        return taus, np.zeros((len(taus), r.shape[1]))
    return taus, (r[:, None, :] <= taus[None, :, None]).mean(axis=0)


def score(costs: np.ndarray, tau_max: float = 10.0) -> np.ndarray:
    """The mean of rho_s(tau) over log tau in [0, log tau_max]: one number per solver in [0, 1].

    1 means best on every problem; a solver that solves everything within
    tau_max of the best but is never best scores between 0 and 1.
    """
    taus = np.logspace(0, math.log10(tau_max), 200)
    return profile(costs, taus)[1].mean(axis=0)


def plot_profiles(ax, taus: np.ndarray, fractions: np.ndarray, labels: list[str], title: str, styles=None) -> None:
    """Draw one profile per label on ``ax`` (log tau); ``styles``: a dict of plot keywords per label."""
    for j, label in enumerate(labels):
        ax.step(taus, fractions[:, j], where="post", label=label, **((styles or {}).get(label, {})))
    ax.set_xscale("log")
    ax.set_ylim(0, 1.02)
    ax.set_xlabel("tau (within tau x the best)")
    ax.set_ylabel("fraction of problems")
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
