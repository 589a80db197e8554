# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # 5. Reading the benchmark charts
#
# Two questions decide which penalty rule to use:
#
# 1. **Where does it fail?** A rule should reach the solution from any
#    starting penalty $\rho_0$, and its stopping rule should not fire far from
#    the solution.
# 2. **How long does it take to reach the accuracy I need?** This is a
#    work-precision chart: the true error against CPU time.
#
# The benchmark commands measure both and commit their numbers as CSV files
# under `docs/results/`. The benchmarks page (`docs/benchmarks.md`) says how
# they measure. This tutorial reads the committed CSV files, redraws the
# charts, and shows how to read them. It runs nothing expensive: the numbers
# are those of the committed runs, so they describe the machine and the code
# of those runs. Timings are noisy on a shared machine, so we compare them as
# ratios within one run.

# %%
import csv
import math
from collections import Counter, defaultdict
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

# the repository root: this folder's parents (as a notebook the working directory is docs/tutorials)
ROOT = next(p for p in [Path.cwd(), *Path.cwd().parents] if (p / "docs" / "results").is_dir())
RESULTS = ROOT / "docs" / "results"
BENCH = RESULTS / "bench"


def number(text):
    """A CSV cell as a float (empty cells are NaN)."""
    return float(text) if text not in ("", None) else math.nan


def read(path):
    """The rows of a CSV file as dicts."""
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


# %% [markdown]
# ## 1. The rules across rho_0
#
# `admmkit bench policies` runs every registered rule, in both orders, on the
# paper's Example 1 ($h = 1/20$), on the same example with Tresca friction
# (slip bound 2) and on the radial obstacle problem ($h = 1/16$). It starts from 13 values of $\rho_0$, from $10^{-4}$ to
# $10^{8}$. Each run goes until the iterate is within a relative $10^{-6}$
# of the reference solution, or 20 000 iterations. The same run also records
# where the paper's stopping rule (relative change of $u$ below $10^{-5}$)
# would have fired, and the true error at that point.

# %%
sweep = read(RESULTS / "policies_fe" / "sweep.csv")
cases = list(dict.fromkeys(r["case"] for r in sweep))
rules = list(dict.fromkeys(r["rule"] for r in sweep))
ORDER = "zx"

fig, axes = plt.subplots(2, len(cases), figsize=(4.2 * len(cases), 7), sharex=True)
for col, case in enumerate(cases):
    for rule in rules:
        runs = sorted((number(r["rho0"]), r) for r in sweep
                      if r["case"] == case and r["rule"] == rule and r["order"] == ORDER)
        rho0 = [x for x, _ in runs]
        style = dict(marker="o", ms=3, lw=2.5 if rule in ("fixed", "summable") else 1, label=rule)
        axes[0, col].loglog(rho0, [number(r["iterations"]) for _, r in runs], **style)
        axes[1, col].loglog(rho0, [number(r["paper_error"]) for _, r in runs], **style)
    axes[0, col].set(title=f"{case} (order {ORDER})", ylabel="iterations to a relative error 1e-6")
    axes[1, col].axhline(1e-3, color="r", ls="--", lw=1)
    axes[1, col].set(xlabel="rho_0", ylabel="true error where the paper's rule fires")
    for ax in axes[:, col]:
        ax.grid(alpha=0.3, which="both")
axes[0, 0].legend(fontsize=7, ncol=2)
fig.tight_layout()
plt.show()

# %% [markdown]
# **Top row.** A flat line is a rule that does not care about $\rho_0$. The
# fixed penalty draws a narrow V: it reaches the tolerance only within a few
# decades of its best value, and elsewhere it hits the cap of 20 000. Every
# adaptive rule is flat to within a small factor, but the factors differ.
#
# **Bottom row.** The error at which the paper's stopping rule would have
# stopped. Points above the red line at $10^{-3}$ are *false convergence*:
# the run would look finished, yet the answer is wrong. This happens to the
# fixed penalty far from its band, because $u$ hardly moves there. It also
# happens to adaptive rules started from an extreme $\rho_0$, before they
# have moved $\rho$. The stopping rule, not only the penalty rule, decides
# whether a result can be trusted.

# %%
def summary(case, rule, order):
    runs = [r for r in sweep if r["case"] == case and r["rule"] == rule and r["order"] == order]
    return dict(runs=len(runs), reached=sum(r["reached"] == "True" for r in runs),
                worst=max(int(r["iterations"]) for r in runs),
                false=sum(number(r["paper_error"]) > 1e-3 for r in runs),
                factorizations=max(int(r["factorizations"]) for r in runs))


print(f"{'':28}{'rule':>16}{'order':>6}{'reached':>9}{'worst':>7}{'false stops':>12}{'max fact.':>10}")
for case in cases:
    for rule in rules:
        for order in ("xz", "zx"):
            s = summary(case, rule, order)
            print(f"{case:28}{rule:>16}{order:>6}{s['reached']:>5}/{s['runs']:<3}{s['worst']:>7}"
                  f"{s['false']:>12}{s['factorizations']:>10}")

contact, obstacle, tresca = cases
for order in ("xz", "zx"):
    assert summary(contact, "fixed", order)["reached"] == 5        # 5 of 13 rho_0 on contact
    assert summary(tresca, "fixed", order)["reached"] == 5         # the same 5 with Tresca friction
    assert summary(obstacle, "fixed", order)["reached"] == 4       # 4 of 13 on the obstacle
    assert summary(contact, "fixed", order)["false"] == 9          # 9 false stops of the paper's rule
    for case in cases:
        assert summary(case, "summable", order)["reached"] == 13   # SADMM's rule: from every rho_0
assert summary(contact, "summable", "zx")["worst"] <= 71

# %% [markdown]
# The last column is the cost that the iteration count hides. Every new
# value of $\rho$ costs a sparse factorisation, and rules differ by an
# order of magnitude in how many they need. The `quantized` wrapper exists
# for that reason: it rounds $\rho$ to a grid, so values repeat and come
# from the cache.
#
# ## 2. Work-precision and stability: `admmkit bench precision | stability`
#
# The two larger benchmarks write their CSV files to `docs/results/bench/`.
# Each part below runs when its CSV file is committed.

# %%
PRECISION = BENCH / "precision" / "precision.csv"
STABILITY = BENCH / "stability" / "stability.csv"
have_precision, have_stability = PRECISION.is_file(), STABILITY.is_file()
if have_precision:
    precision = read(PRECISION)
    print(f"{len(precision)} work-precision points; problems:",
          ", ".join(dict.fromkeys(r["problem"] for r in precision)))
else:
    print("no committed precision.csv yet: run `admmkit bench precision`")
if have_stability:
    stability = read(STABILITY)
    print(f"{len(stability)} stability runs")
else:
    print("no committed stability.csv yet: run `admmkit bench stability`")

# %% [markdown]
# ### Work-precision: error against time
#
# Each ADMM method makes **one run**, to a very tight residual tolerance. On
# the way, the benchmark records where each looser tolerance of a ladder
# ($10^{-1}, 10^{-1.5}, \dots$) would have stopped it: the CPU time of the
# process at that iteration (the shared machine's load distorts wall time
# more; the CSV keeps both), and the true relative error against a reference
# solution at that point. Every row of `precision.csv` is such a point. The peers,
# cvxpy + Clarabel and OSQP, are run once per tolerance. So each method
# becomes a curve of (time, error) points:
#
# - **lower left is better**: less error for less time;
# - a curve that **falls steeply** converges fast at that stage;
# - a **flat stretch** is time spent without gaining accuracy;
# - a curve that **stops early** hit the iteration cap or the time limit
#   (its `run_status` says which).

# %%
def curves(problem):
    """{method: (times, errors)} of one problem, sorted by time."""
    out = defaultdict(list)
    for r in precision:
        if r["problem"] == problem and not math.isnan(number(r["err"])):
            out[r["method"]].append((number(r["time_s"]), number(r["err"])))
    return {m: tuple(np.array(v) for v in zip(*sorted(pts))) for m, pts in out.items()}


def draw(problem, methods, ax):
    data = curves(problem)
    for m in methods:
        if m in data:
            t, e = data[m]
            ax.loglog(t, e, "o-" if "/" in m or m.startswith(("admm", "sadmm")) else "s--", ms=3, label=m)
    ax.set(xlabel="CPU time (s)", ylabel="true relative error", title=problem)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7, ncol=2)


if have_precision:
    SHOW = ["admm1", "admm2", "sadmm", "aadmm/zx", "wohlberg/xz", "osqp/zx", "clarabel", "osqp", "pdas"]
    problems = list(dict.fromkeys(r["problem"] for r in precision))
    # the finest contact mesh and the finest obstacle mesh, if present
    shown = [p for prefix in ("ex1", "radial") for p in [q for q in problems if q.startswith(prefix)][-1:]]
    shown = (shown + [p for p in problems if p not in shown])[:2]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for ax, problem in zip(axes, shown):
        draw(problem, SHOW, ax)
    fig.tight_layout()
    plt.show()

# %% [markdown]
# ### Time to a target error
#
# A chart is read at the accuracy you need. Draw a horizontal line at the
# target error: the first point of each curve below the line is the time
# that method needs. `time_to_error.csv` tabulates this for $10^{-4}$ and
# $10^{-8}$. Here we recompute it from the points, which checks that we read
# the chart as the benchmark meant it:

# %%
def time_to_error(problem, method, target):
    """The smallest time among the points of (problem, method) with error <= target (None: never)."""
    times = [number(r["time_s"]) for r in precision
             if r["problem"] == problem and r["method"] == method and number(r["err"]) <= target]
    return min(times) if times else None


if have_precision:
    table = read(BENCH / "precision" / "time_to_error.csv")
    for row in table:
        mine = time_to_error(row["problem"], row["method"], float(row["target"]))
        theirs = number(row["time_s"])
        assert (mine is None and math.isnan(theirs)) or math.isclose(mine, theirs, rel_tol=1e-12), row
    print(f"all {len(table)} entries of time_to_error.csv agree with the points")

    for target in (1e-4, 1e-8):
        print(f"\nfastest to a relative error of {target:g}:")
        for problem in problems:
            times = {m: time_to_error(problem, m, target) for m in curves(problem)}
            reached = {m: t for m, t in times.items() if t is not None}
            if reached:
                best = min(reached, key=reached.get)
                sadmm = reached.get("sadmm")
                note = (", the paper's SADMM" if best == "sadmm" else
                        f"; sadmm takes {sadmm / reached[best]:.1f}x that" if sadmm else "; sadmm did not get there")
                print(f"  {problem:<18} {best:<22} {reached[best]:.3g} s{note}; "
                      f"{len(times) - len(reached)} of {len(times)} methods never did")

# %% [markdown]
# ### Stability over rho_0, meshes and materials
#
# The stability sweep stops every run by the paper's rule (relative change
# of $u$ below $10^{-5}$), as a user would, and then classifies the stop
# against the reference solution:
#
# - `converged`: the rule fired and the true error is at most $10^{-3}$;
# - `false_convergence`: the rule fired, but the error is larger. This is the
#   dangerous case, because the run looks successful;
# - `max_iter`, `diverged`, `stalled`, `time_limit`: the run did not stop
#   by the rule.
#
# The $\rho_0$ sweep starts each method from $\rho_0 = s\,E$ for 13 values
# of $s$, from $10^{-6}$ to $10^{6}$, on both of the paper's examples.

# %%
if have_stability:
    OUTCOMES = ["converged", "false_convergence", "max_iter", "diverged", "stalled", "time_limit", "error"]
    rho_rows = [r for r in stability if r["sweep"] == "rho"]
    scales = sorted({number(r["rho_scale"]) for r in rho_rows})
    methods = list(dict.fromkeys(r["method"] for r in rho_rows))

    fig, axes = plt.subplots(1, 2, figsize=(12, 0.32 * len(methods) + 1.8), sharey=True)
    colours = {"converged": 0, "false_convergence": 1, "max_iter": 2, "diverged": 3, "stalled": 3, "time_limit": 2,
               "error": 3}
    cmap = plt.matplotlib.colors.ListedColormap(["#4caf50", "#ff9800", "#9e9e9e", "#e53935"])
    for ax, scene in zip(axes, ["ex1", "ex2"]):
        grid = np.full((len(methods), len(scales)), np.nan)
        for r in rho_rows:
            if r["scene"] == scene:
                i, j = methods.index(r["method"]), scales.index(number(r["rho_scale"]))
                grid[i, j] = colours[r["outcome"]]
                ax.text(j, i, r["iterations"] or "", ha="center", va="center", fontsize=5)
        ax.imshow(grid, cmap=cmap, vmin=0, vmax=3, aspect="auto")
        ax.set_xticks(range(len(scales)), [f"{s:.0e}" for s in scales], rotation=90, fontsize=7)
        ax.set_yticks(range(len(methods)), methods, fontsize=7)
        ax.set(title=f"{scene}: outcome by rho_0 / E (numbers: iterations)", xlabel="rho_0 / E")
    handles = [plt.matplotlib.patches.Patch(color=cmap(k), label=l)
               for k, l in enumerate(["converged", "false convergence", "max_iter / time limit", "diverged / error"])]
    fig.legend(handles=handles, loc="lower center", ncol=4, fontsize=8)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    plt.show()

# %% [markdown]
# Read a row from left to right. A fixed $\rho$ (`admm1`, `admm2`) is
# green only in a band around its good value. Outside the band it either
# hits the cap or, worse, stops early with a large error. The adaptive
# rules are green over most of the range. Orange cells at the far right
# mean that even an adaptive rule can be fooled: from an enormous $\rho_0$,
# $u$ barely moves in the first iterations, and the relative-change rule
# fires before the rule has moved $\rho$.
#
# Over every sweep (all $\rho_0$, meshes, $\nu$ and elements) the counts
# per method are:

# %%
if have_stability:
    counts = {m: Counter(r["outcome"] for r in stability if r["method"] == m)
              for m in dict.fromkeys(r["method"] for r in stability)}
    print(f"{'method':<22}{'runs':>6}" + "".join(f"{o[:12]:>14}" for o in OUTCOMES[:4]))
    for m, c in counts.items():
        print(f"{m:<22}{sum(c.values()):>6}" + "".join(f"{c.get(o, 0):>14}" for o in OUTCOMES[:4]))

    # the same counts as the benchmark's own failures.md
    failures = (BENCH / "stability" / "failures.md").read_text(encoding="utf-8")
    for m, c in counts.items():
        line = next(ln for ln in failures.splitlines() if ln.startswith(f"| {m} |"))
        cells = [x.strip() for x in line.strip("|").split("|")]
        assert int(cells[1]) == sum(c.values()) and int(cells[2] or 0) == c.get("converged", 0), (m, cells)
