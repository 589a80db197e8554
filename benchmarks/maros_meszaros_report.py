"""The report of the QP benchmark (:mod:`benchmarks.maros_meszaros`): statistics, profiles, tables.

Shifted geometric means (Mittelmann), Dolan-More performance profiles, the
per-run CSV (``results.csv``), ``summary.csv`` and the README; every file is
written whole or not at all.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from admmkit.io import atomic_open, atomic_path, write_text

RHO0 = 0.1
SHIFT = 10.0
#: the label of OSQP called directly
OSQP_DIRECT = "OSQP"
FIELDS = ("problem", "n", "m", "solver", "order", "eps", "solved", "status", "iterations", "time", "setup_time",
          "factorizations", "rho_changes", "rho_final", "rho_max", "primal_res", "dual_res")


# ---------------------------------------------------------------- statistics
def shifted_geometric_mean(values, shift: float = SHIFT) -> float:
    """exp(mean(log(v + shift))) - shift (Mittelmann's shifted geometric mean)."""
    v = np.asarray(list(values), dtype=float)
    if v.size == 0:
        return math.nan
    return float(np.exp(np.mean(np.log(v + shift))) - shift)


def solver_keys(rows: list[dict]) -> list[tuple[str, str]]:
    """(solver, order) pairs in first-seen order."""
    return list(dict.fromkeys((r["solver"], r["order"]) for r in rows))


def summarize(rows: list[dict], max_iter: int, time_limit: float) -> list[dict]:
    """One line per (solver, order, eps): successes, shifted geometric means, factorisations, statuses."""
    out = []
    for eps in sorted({r["eps"] for r in rows}, reverse=True):
        for solver, order in solver_keys(rows):
            sel = [r for r in rows if r["solver"] == solver and r["order"] == order and r["eps"] == eps]
            if not sel:
                continue
            solved = [r for r in sel if _true(r["solved"])]
            statuses: dict[str, int] = {}
            for r in sel:
                if not _true(r["solved"]):
                    statuses[r["status"]] = statuses.get(r["status"], 0) + 1
            facts = [float(r["factorizations"]) for r in sel]
            out.append({
                "eps": eps, "solver": solver, "order": order, "problems": len(sel), "solved": len(solved),
                "rate": len(solved) / len(sel),
                "sgm_iterations": shifted_geometric_mean(
                    float(r["iterations"]) if _true(r["solved"]) else max_iter for r in sel),
                "sgm_time": shifted_geometric_mean(
                    float(r["time"]) if _true(r["solved"]) else time_limit for r in sel),
                "factorizations_mean": float(np.mean(facts)), "factorizations_max": int(max(facts)),
                "failures": statuses,
                "runaway": sum(1 for r in sel if _finite(r["rho_max"]) and float(r["rho_max"]) > 1e20 * RHO0),
            })
    return out


def performance_profile(rows: list[dict], metric: str, eps: float):
    """Dolan-More profile: {(solver, order): (taus, fraction of problems solved within tau x the best)}."""
    sel = [r for r in rows if r["eps"] == eps]
    problems = sorted({r["problem"] for r in sel})
    keys = solver_keys(sel)
    table = np.full((len(problems), len(keys)), np.inf)
    index = {p: i for i, p in enumerate(problems)}
    for r in sel:
        if _true(r["solved"]):
            table[index[r["problem"]], keys.index((r["solver"], r["order"]))] = max(float(r[metric]), 1e-9)
    best = table.min(axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(np.isfinite(best), table / best, np.inf)
    finite = ratio[np.isfinite(ratio)]
    top = max(float(finite.max()) if finite.size else 2.0, 2.0)
    taus = np.logspace(0, math.log10(top) + 0.05, 400)
    return {key: (taus, (ratio[:, j][:, None] <= taus[None, :]).mean(axis=0)) for j, key in enumerate(keys)}


def _true(v) -> bool:
    return v is True or str(v) == "True"


def _finite(v) -> bool:
    try:
        return math.isfinite(float(v))
    except (TypeError, ValueError):
        return False


# ---------------------------------------------------------------- output
def plot_profiles(rows: list[dict], path_stem: Path) -> list[Path]:
    """Performance profiles (rows: accuracies, columns: iterations and time) as PNG and SVG."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    epss = sorted({r["eps"] for r in rows}, reverse=True)
    names = list(dict.fromkeys(r["solver"] for r in rows))
    colors = {name: plt.cm.tab10(i % 10) for i, name in enumerate(n for n in names if n != OSQP_DIRECT)}
    colors[OSQP_DIRECT] = "black"
    styles = {"xz": "-", "zx": "--", "-": "-"}
    fig, axes = plt.subplots(len(epss), 2, figsize=(13, 4.6 * len(epss)), squeeze=False)
    for i, eps in enumerate(epss):
        for j, (metric, label) in enumerate([("iterations", "iterations"), ("time", "time")]):
            ax = axes[i][j]
            for (solver, order), (taus, frac) in performance_profile(rows, metric, eps).items():
                ax.step(taus, frac, where="post", color=colors[solver], linestyle=styles.get(order, "-"),
                        linewidth=2.2 if solver == OSQP_DIRECT else 1.4,
                        label=solver if order == "-" else f"{solver} ({order})")
            ax.set_xscale("log", base=2)
            ax.set_ylim(0, 1.02)
            ax.grid(True, which="both", alpha=0.3)
            ax.set_xlabel(f"tau: within tau x the best {label}")
            ax.set_ylabel("fraction of problems")
            ax.set_title(f"{label}, eps_abs = eps_rel = {eps:g}")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="center right", fontsize=8, frameon=False)
    fig.suptitle("Performance profiles on the Maros-Meszaros QPs (solid: order xz, dashed: zx)")
    fig.tight_layout(rect=(0, 0, 0.83, 0.97))
    paths = []
    for ext in ("png", "svg"):
        p = path_stem.with_suffix(f".{ext}")
        with atomic_path(p) as tmp:
            fig.savefig(tmp, dpi=110)
        paths.append(p)
    plt.close(fig)
    return paths


def _fmt_failures(failures: dict) -> str:
    return ", ".join(f"{k} {v}" for k, v in sorted(failures.items())) or "-"


def markdown(summary: list[dict], skipped: dict[str, str], meta: dict, command: str, n_run: int,
             figure: str, kkt_form: dict[str, str] | None = None) -> str:
    """The report: settings, one table per accuracy, the KKT-form and the skipped problems, the machine."""
    lines = [
        "# Penalty rules on the Maros-Meszaros QPs",
        "",
        f"Command (from the repository root): `{command}`",
        "",
        f"{n_run} problems run, {len(skipped)} skipped (listed below).  Every admmkit rule starts from "
        f"rho_0 = {RHO0:g}; iteration cap {meta['max_iter']}, time limit {meta['time_limit']:g} s per problem and "
        f"configuration.  Times are CPU seconds of the process (setup + solve, BLAS on one thread): the 2-core "
        f"machine was shared (the sweep ran on {meta['workers']}, beside other jobs), and wall time would "
        "charge a run for the other processes.  "
        "Solved means OSQP's test with eps_abs = eps_rel = eps on the unscaled QP (docs/policies.md).  "
        f"Shifted geometric means use shift {SHIFT:g} and count a failure as the cap / the limit.  "
        "Factorisations: of the x-step matrix during the run up to that accuracy (OSQP: 1 + rho updates).  "
        "'runaway': runs where rho exceeded 1e20 rho_0.  Per-run data: `results.csv`.",
        "",
        f"![performance profiles]({figure})",
        "",
    ]
    for eps in sorted({s["eps"] for s in summary}, reverse=True):
        lines += [f"## eps = {eps:g}", "",
                  "| rule | order | solved | rate | SGM iterations | SGM time [s] | factorisations mean / max "
                  "| failures | runaway |",
                  "|---|---|---|---|---|---|---|---|---|"]
        rows = sorted((s for s in summary if s["eps"] == eps), key=lambda s: (-s["rate"], s["sgm_time"]))
        for s in rows:
            lines.append(f"| {s['solver']} | {s['order']} | {s['solved']}/{s['problems']} | {100 * s['rate']:.1f}% "
                         f"| {s['sgm_iterations']:.1f} | {s['sgm_time']:.3f} | {s['factorizations_mean']:.1f} / "
                         f"{s['factorizations_max']} | {_fmt_failures(s['failures'])} | {s['runaway']} |")
        lines.append("")
    lines += ["## x-step in KKT form", "",
              "A dense row of A makes A'A dense; these problems ran with OSQP's KKT form of the x-step "
              "(`QP(xstep=\"auto\")`, factorised by qdldl or SuperLU):", ""]
    lines += [f"- {name}: {why}" for name, why in sorted((kkt_form or {}).items())] or ["- none"]
    lines += ["", "## Skipped", ""]
    lines += [f"- {name}: {why}" for name, why in sorted(skipped.items())] or ["- none"]
    lines += ["", "## Machine", ""] + [f"- {k}: {v}" for k, v in meta["machine"].items()]
    lines += [f"- started {meta['started']}, wall time {meta['wall']:.0f} s", ""]
    return "\n".join(lines)


def write_rows(rows: list[dict], path: Path) -> None:
    """Write per-run rows as CSV, whole or not at all."""
    with atomic_open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{r[k]:.6g}" if isinstance(r[k], float) else r[k]) for k in FIELDS})


def read_rows(path: Path) -> list[dict]:
    """Rows written by :func:`write_rows`, numbers parsed."""
    rows = []
    with path.open(newline="") as fh:
        for r in csv.DictReader(fh):
            for k in ("n", "m", "iterations", "factorizations", "rho_changes"):
                r[k] = int(r[k])
            for k in ("eps", "time", "setup_time", "rho_final", "rho_max", "primal_res", "dual_res"):
                r[k] = float(r[k])
            r["solved"] = _true(r["solved"])
            rows.append(r)
    return rows


def write_summary(summary: list[dict], path: Path) -> None:
    """summary.csv: one line per (eps, solver, order), whole or not at all."""
    with atomic_open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["eps", "solver", "order", "problems", "solved", "rate", "sgm_iterations", "sgm_time",
                    "factorizations_mean", "factorizations_max", "failures", "runaway"])
        for s in summary:
            w.writerow([s["eps"], s["solver"], s["order"], s["problems"], s["solved"], f"{s['rate']:.4f}",
                        f"{s['sgm_iterations']:.2f}", f"{s['sgm_time']:.4f}", f"{s['factorizations_mean']:.2f}",
                        s["factorizations_max"], _fmt_failures(s["failures"]), s["runaway"]])


def write_report(rows: list[dict], out: Path, *, skipped: dict, kkt_form: dict, meta: dict, command: str) -> dict:
    """results.csv, summary.csv, the profiles and README.md from the per-run rows; returns summary and figures."""
    rows.sort(key=lambda r: (r["problem"], r["solver"], r["order"], -r["eps"]))
    write_rows(rows, out / "results.csv")
    summary = summarize(rows, meta["max_iter"], meta["time_limit"])
    figures = plot_profiles(rows, out / "profiles") if rows else []
    text = markdown(summary, skipped, meta, command, len({r["problem"] for r in rows}), "profiles.png", kkt_form)
    write_text(out / "README.md", text)
    write_summary(summary, out / "summary.csv")
    return {"summary": summary, "figures": figures, "text": text}
