"""The summary of ``admmkit bench rules``: the rules ranked, per family and overall.

A *configuration* is a rule with an acceleration (``osqp``, ``osqp+anderson``);
a *problem* of a family is everything else of a run (the problem, h, nu,
P, order, rho_0, eps), so each configuration meets the same problems.  From
one row per run the summary writes

- ``runs.csv``: every run (family, problem, configuration, solved, status,
  iterations, seconds);
- ``profiles_iterations.png`` / ``profiles_time.png``: Dolan-More profiles
  per family and overall (the mean of the families' profiles, so that each
  family weighs the same however many runs it has);
- ``README.md``: the ranking by the overall iteration score (the mean of the
  profile over log tau in [0, 1], i.e. tau from 1 to 10), the time score,
  solved counts, the robustness across rho_0 (median over the sweeps of
  log10(max / min iterations) among the rho_0 that solved, and the share
  of sweeps solved at every rho_0), what acceleration does per family and
  rule (median iteration and time ratio accelerated / plain over the runs
  both solve, runs rescued: solved only with it, runs broken: solved only
  without it);
- ``failures.md``: every run that did not solve, with its status.
"""
from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path

import numpy as np

from admmkit.benchmarks.runner import profiles
from admmkit.benchmarks.runner.harness import check_harness, first_line, harness_failures, is_harness_failure
from admmkit.benchmarks.runner.profiles import plot_profiles, profile, score
from admmkit.benchmarks.runner.report import (NOISE_NOTE, fmt, md_table, pyplot, save_figure, write_csv,
                                               write_text)

#: the fields of a case that make a family's problem (the configuration's fields excluded)
PROBLEM_FIELDS = ("problem", "scene", "h", "nu", "p", "sweep", "order", "rho0", "rho_scale")
TAUS = np.logspace(0, 2, 300)


def config_of(case: dict) -> str:
    """``rule`` or ``rule+acceleration``; ``rule@preset`` for a QP case in a preset other than OSQP's."""
    preset = f"@{case['preset']}" if case.get("preset") else ""
    return case["rule"] + preset + (f"+{case['acceleration']}" if case.get("acceleration") else "")


def rows_of(records: dict) -> list[dict]:
    """One row per run; a case that raised or timed out fails at each of its accuracies.

    ``harness``: the case failed in the harness (a missing package, an error outside the rule's code): such
    a row is no run of the rule (``without_harness_failures`` leaves its problem out).
    """
    rows = []
    for rec in records.values():
        case = rec["case"]
        problem = " ".join(f"{k}={case[k]:g}" if isinstance(case[k], float) else f"{k}={case[k]}"
                           for k in PROBLEM_FIELDS if case.get(k) is not None)
        rule = case["rule"] + (f"@{case['preset']}" if case.get("preset") else "")
        base = {"family": case["family"], "problem": problem, "rule": rule,
                "acceleration": case.get("acceleration") or "none", "config": config_of(case),
                "rho_sweep": " ".join(problem.split(" rho")[0:1])}
        runs = (rec.get("result") or {}).get("runs")
        harness = is_harness_failure(rec)
        if runs is None:
            error = (rec.get("error") or "error").split(":")[0]
            runs = [{"eps": e, "solved": False, "status": error, "iterations": math.nan, "seconds": math.nan}
                    for e in (case.get("eps") or [None])]
        for run in runs:
            suffix = f" eps={run['eps']:g}" if run.get("eps") is not None else ""
            rows.append(base | {"problem": problem + suffix, "rho_sweep": base["rho_sweep"] + suffix,
                                "solved": bool(run["solved"]), "status": run["status"],
                                "iterations": run["iterations"], "seconds": run["seconds"], "harness": harness})
    return rows


def without_harness_failures(rows: list[dict]) -> tuple[list[dict], set]:
    """(the rows of the problems on which no run failed in the harness, the (family, problem) left out).

    A problem with a harness failure is left out for every configuration: a profile compares the
    configurations on the same problems, and a missing run would count as the configuration's failure.
    """
    bad = {(r["family"], r["problem"]) for r in rows if r.get("harness")}
    kept = [{k: v for k, v in r.items() if k != "harness"} for r in rows if (r["family"], r["problem"]) not in bad]
    return kept, bad


def cost_table(rows: list[dict], metric: str, configs: list[str]) -> np.ndarray:
    """problems x configurations: the metric where solved, inf where not (a missing run counts as a failure)."""
    return profiles.cost_table(rows, configs, metric, config=lambda r: r["config"], solved=lambda r: r["solved"])


def robustness(rows: list[dict], config: str) -> tuple[float, float]:
    """(median log10 spread of iterations across rho_0 among solved runs, share of sweeps solved at every rho_0)."""
    sweeps = defaultdict(list)
    for r in rows:
        if r["config"] == config and (" rho0=" in r["problem"] or " rho_scale=" in r["problem"]):
            sweeps[(r["family"], r["rho_sweep"])].append(r)
    spreads, whole = [], []
    for runs in (runs for runs in sweeps.values() if len(runs) >= 2):
        its = [r["iterations"] for r in runs if r["solved"]]
        whole.append(len(its) == len(runs))
        if len(its) >= 2:
            spreads.append(math.log10(max(max(its), 1) / max(min(its), 1)))
    return (float(np.median(spreads)) if spreads else math.nan, float(np.mean(whole)) if whole else math.nan)


def acceleration_effect(rows: list[dict]) -> list[dict]:
    """Per family, rule and acceleration: runs, median ratios accelerated / plain, rescued and broken runs."""
    plain = {(r["family"], r["problem"], r["rule"]): r for r in rows if r["acceleration"] == "none"}
    groups = defaultdict(list)
    for r in rows:
        p = plain.get((r["family"], r["problem"], r["rule"]))
        if r["acceleration"] != "none" and p is not None:
            groups[(r["family"], r["rule"], r["acceleration"])].append((p, r))
    out = []
    for (family, rule, accel), pairs in sorted(groups.items()):
        both = [(p, a) for p, a in pairs if p["solved"] and a["solved"]]
        out.append({"family": family, "rule": rule, "acceleration": accel, "runs": len(pairs), "both": len(both),
                    "iteration_ratio": _median([a["iterations"] / max(p["iterations"], 1) for p, a in both]),
                    "time_ratio": _median([a["seconds"] / p["seconds"] for p, a in both if p["seconds"] > 0]),
                    "rescued": sum(a["solved"] and not p["solved"] for p, a in pairs),
                    "broken": sum(p["solved"] and not a["solved"] for p, a in pairs)})
    return out


def _median(values) -> float:
    return float(np.median(values)) if values else math.nan


def figure(rows: list[dict], families: list[str], configs: list[str], metric: str, path: Path) -> Path:
    """The profiles of one metric: one panel per family and the overall mean (:func:`profiles_figure`)."""
    save_figure(profiles_figure(rows, families, configs, metric), path)
    return path


def profiles_figure(rows: list[dict], families: list[str], configs: list[str], metric: str):
    """The figure of :func:`figure` (open; the caller saves or closes it): a grid of at most 4 columns, the legend
    in a spare panel; a panel without a curve says why in it (:func:`empty_note`)."""
    plt = pyplot()
    panels = families + ["overall"]
    cols = min(len(panels), 4)
    nrows = math.ceil(len(panels) / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4.2 * cols, 3.6 * nrows), squeeze=False)
    styles = _styles(configs)
    mean, empty = np.zeros((len(TAUS), len(configs))), 0
    for ax, family in zip(axes.flat, panels):
        if family == "overall":
            fractions, n = mean / max(len(families), 1), len(families)
            title, note = f"overall: mean of {n} famil{'y' if n == 1 else 'ies'}", None
            if empty:
                title += f"\n({empty} without a solved run count as 0)"
        else:
            sub = [r for r in rows if r["family"] == family]
            table = cost_table(sub, metric, configs)
            fractions = profile(table, TAUS)[1]
            mean += fractions
            title, note = f"{family}: {table.shape[0]} problems", empty_note(sub, table)
            empty += note is not None
        plot_profiles(ax, TAUS, fractions, configs, title, styles)
        if note:
            ax.text(0.5, 0.55, note, transform=ax.transAxes, ha="center", va="center", fontsize=9, wrap=True,
                    bbox=dict(boxstyle="round", fc="lightyellow", ec="0.5"))
    spare = list(axes.flat)[len(panels):]
    for ax in spare:
        ax.axis("off")
    handles, names = axes.flat[0].get_legend_handles_labels()
    fig.suptitle(f"Performance profiles ({'iterations' if metric == 'iterations' else 'wall time'})")
    if spare:                                           # the legend in an empty panel, off the curves
        spare[0].legend(handles, names, loc="center", fontsize=8, ncol=2 if len(names) > 12 else 1)
        fig.tight_layout()
    else:
        fig.legend(handles, names, loc="lower center", fontsize=8, ncol=min(len(names), 6))
        fig.tight_layout(rect=(0, 0.06 * math.ceil(len(names) / 6) / nrows, 1, 1))
    return fig


def empty_note(rows: list[dict], table: np.ndarray) -> str | None:
    """Why a family's panel has no curve (None when it has one): it has no runs, or none of its runs solved."""
    if not rows:
        return "no run of this family in this study\n(not run yet, or not in --quick)"
    if not np.isfinite(table).any():
        statuses = sorted({str(r["status"]) for r in rows})
        shown = ", ".join(statuses[:3]) + (", ..." if len(statuses) > 3 else "")
        return (f"no run of this family solved:\n{len(rows)} runs failed ({shown});\n"
                "every one is in failures.md")
    return None


def _styles(configs: list[str]) -> dict[str, dict]:
    """A colour per rule, a line style per acceleration."""
    rules = sorted({c.split("+")[0] for c in configs})
    cmap = pyplot().get_cmap("tab10")
    dash = {"": "-", "anderson": "--", "fast": ":"}
    return {c: dict(color=cmap(rules.index(c.split("+")[0]) % 10),
                    linestyle=dash.get(c.partition("+")[2], "-."), linewidth=1.4) for c in configs}


def summarise(records: dict, out: Path, *, command: str, wall: float | None, notes=(), missing: int = 0,
              families=None) -> list[Path]:
    """Write runs.csv, the profiles, failures.md and README.md (the ranking); returns the files.

    Cases that failed in the harness are ranked on nowhere: their problems are left out for every
    configuration, the README says how many, and ``HarnessFailed`` (``admmkit.benchmarks.runner.harness``)
    is raised once the files are written (none if nothing is left to rank).
    """
    out.mkdir(parents=True, exist_ok=True)
    harness = harness_failures(records)
    rows, left_out = without_harness_failures(rows_of(records))
    if not rows:                                       # nothing to rank: no file, the reason in one line
        check_harness(harness, len(records) + missing, left_out="nothing ranked on them: no file written")
    families = [f for f in (families or []) if any(r["family"] == f for r in rows)]
    configs = sorted({r["config"] for r in rows})
    files = [write_csv(out / "runs.csv", rows)]
    files += [figure(rows, families, configs, m, out / f"profiles_{name}.png")
              for m, name in (("iterations", "iterations"), ("seconds", "time"))]
    ranking = _ranking(rows, families, configs)
    effect = acceleration_effect(rows)
    write_text(out / "failures.md", _failures(rows))
    lines = [f"# Penalty rules ranked: `{command}`", "",
             (f"Wall time of this invocation: {wall:.0f} s." if wall is not None else
              "Rewritten from results.jsonl (--report-only).") + f" {len(rows)} runs"
             + (f"; {missing} cases not run yet (resume with the same command)." if missing else "."), ""]
    if harness:
        notes = [*notes, f"**{len(harness)} cases failed in the harness** ({first_line(harness[0]['error'])}): not "
                 f"runs of the rules; their {len(left_out)} problems are left out of the ranking for every "
                 "configuration (the cases are in results.jsonl with their errors; the same command runs them again)"]
    lines += [f"- {n}" for n in notes] + ([""] if notes else [])
    lines += ["Ranked by the overall iteration score: the mean, over the families, of the Dolan-More profile "
              "averaged over log tau for tau in [1, 10] (1 = the fewest iterations on every problem). "
              "Spread: median over the rho_0 sweeps of log10(max/min iterations) among the rho_0 that solved; "
              "whole: the share of sweeps solved at every rho_0. " + NOISE_NOTE, "",
              md_table(["rank", "configuration", "iterations score", "time score", "solved"]
                       + [f"{f} solved" for f in families] + ["spread", "whole"], ranking), "",
              "![iterations](profiles_iterations.png)", "", "![time](profiles_time.png)", ""]
    if effect:
        lines += ["## What acceleration does", "",
                  "Ratios accelerated / plain over the runs both solve (median); rescued: solved only with "
                  "acceleration; broken: solved only without.", "",
                  md_table(["family", "rule", "acceleration", "runs", "both solved", "iterations ratio",
                            "time ratio", "rescued", "broken"],
                           [[e["family"], e["rule"], e["acceleration"], e["runs"], e["both"],
                             fmt(e["iteration_ratio"], ".2f"), fmt(e["time_ratio"], ".2f"), e["rescued"], e["broken"]]
                            for e in effect]), ""]
    failed = sum(not r["solved"] for r in rows)
    lines += ["## Failures", "", f"{failed} of {len(rows)} runs did not solve; every one is in "
              "[failures.md](failures.md) with its status."]
    write_text(out / "README.md", "\n".join(lines) + "\n")
    files += [out / "failures.md", out / "README.md"]
    check_harness(harness, len(records) + missing, files,
                  left_out=f"nothing ranked on them (their {len(left_out)} problems left out for every configuration)")
    return files


def _ranking(rows: list[dict], families: list[str], configs: list[str]) -> list[list]:
    """The ranking table's rows, best first."""
    scores = {m: np.zeros(len(configs)) for m in ("iterations", "seconds")}
    solved = defaultdict(lambda: defaultdict(int))
    totals = defaultdict(int)
    for family in families:
        sub = [r for r in rows if r["family"] == family]
        for m in scores:
            scores[m] += score(cost_table(sub, m, configs)) / max(len(families), 1)
        for r in sub:
            solved[r["config"]][family] += r["solved"]
        totals[family] = len({r["problem"] for r in sub})
    order = np.argsort(-scores["iterations"], kind="stable")
    table = []
    for rank, j in enumerate(order, 1):
        c = configs[j]
        spread, whole = robustness(rows, c)
        table.append([rank, c, f"{scores['iterations'][j]:.3f}", f"{scores['seconds'][j]:.3f}",
                      f"{sum(solved[c].values())}/{sum(totals.values())}"]
                     + [f"{solved[c][f]}/{totals[f]}" for f in families] + [fmt(spread, ".2f"), fmt(whole, ".2f")])
    return table


def _failures(rows: list[dict]) -> str:
    """failures.md: every run that did not solve."""
    bad = sorted((r for r in rows if not r["solved"]), key=lambda r: (r["family"], r["config"], r["problem"]))
    body = [[r["family"], r["config"], r["problem"], r["status"], fmt(r["iterations"], ".0f")] for r in bad]
    return ("# Runs that did not solve\n\n" + (md_table(["family", "configuration", "problem", "status", "iterations"],
                                                         body, "lllll") if body else "None.") + "\n")
