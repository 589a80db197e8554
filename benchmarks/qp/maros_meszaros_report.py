"""The report of the QP benchmark (:mod:`admmkit.benchmarks.qp.maros_meszaros`): statistics, profiles, tables.

Shifted geometric means (Mittelmann), Dolan-More performance profiles, the
per-run CSV (``results.csv``), ``summary.csv`` and the README; every file is
written whole or not at all.
"""
from __future__ import annotations

import csv
from pathlib import Path


from admmkit.io import atomic_open, atomic_path, write_text
from admmkit.benchmarks.qp.maros_meszaros_stats import MID_SIZE, OSQP_DIRECT, RHO0, SHIFT, _true, config_keys, label, performance_profile, summarize, target, time_per_iteration

FIELDS = ("problem", "n", "m", "variant", "solver", "order", "eps", "solved", "neutral", "status", "iterations",
          "time", "setup_time", "loop_time", "factorizations", "rho_changes", "rho_final", "rho_max", "neutral_primal",
          "neutral_dual", "neutral_gap")


# ---------------------------------------------------------------- output
#: the panels of the profiles: a title and which configurations (OSQP itself is drawn in every panel)
PANELS = (("the rules in OSQP's machinery (preset)", lambda k: k[0] == "preset"),
          ("the rules in the textbook loop", lambda k: k[0] == "textbook"),
          ("OSQP's rule (xz): the preset without one piece", lambda k: k[1] == "osqp" and k[2] == "xz"))


def plot_profiles(rows: list[dict], path_stem: Path, metric: str = "iterations") -> list[Path]:
    """Performance profiles of ``metric`` over the neutral successes (rows: accuracies; columns: :data:`PANELS`)
    as PNG and SVG; each panel's ratios are to the best configuration in that panel."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    epss = sorted({r["eps"] for r in rows}, reverse=True)
    keys = config_keys(rows)
    rules = list(dict.fromkeys(k[1] for k in keys if k[1] != OSQP_DIRECT))
    variants = list(dict.fromkeys(k[0] for k in keys if k[1] == "osqp" and k[2] == "xz"))
    styles = {"xz": "-", "zx": "--", "-": "-"}
    fig, axes = plt.subplots(len(epss), len(PANELS), figsize=(6.2 * len(PANELS), 4.4 * len(epss)), squeeze=False)
    for i, eps in enumerate(epss):
        for j, (title, chosen) in enumerate(PANELS):
            ax = axes[i][j]
            panel = [k for k in keys if k[1] == OSQP_DIRECT or chosen(k)]
            if not panel:
                ax.set_axis_off()
                continue
            for key, (taus, frac) in performance_profile(rows, metric, eps, panel).items():
                z = 2
                if key[1] == OSQP_DIRECT:      # OSQP on top; OSQP + polish dotted under it
                    color, width, style = ("black", 2.0, "-") if key[0] == "default" else ("0.5", 2.6, ":")
                    z = 5 if key[0] == "default" else 4
                elif j == 2:
                    color, width, style = plt.cm.tab10(variants.index(key[0]) % 10), 1.5, "-"
                else:
                    color, width, style = plt.cm.tab10(rules.index(key[1]) % 10), 1.4, styles[key[2]]
                ax.step(taus, frac, where="post", color=color, linestyle=style, linewidth=width, zorder=z,
                        label=label(key) if j == 2 or key[1] == OSQP_DIRECT else f"{key[1]} ({key[2]})")
            ax.set_xscale("log", base=2)
            ax.set_ylim(0, 1.02)
            ax.grid(True, which="both", alpha=0.3)
            ax.set_xlabel(f"tau: within tau x the panel's best {metric}")
            ax.set_ylabel("fraction of problems")
            ax.set_title(f"{title}\neps = {eps:g} (absolute), neutral criteria", fontsize=10)
            if i == 0:                      # the curves stay low (a rule solves at most ~60 %): the top is free
                ax.legend(fontsize=7, loc="upper left", ncol=3 if j < 2 else 2, framealpha=0.9)
    fig.suptitle(f"Performance profiles ({metric}) on the Maros-Meszaros QPs; solid: order xz, dashed: zx")
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    paths = []
    for ext in ("png", "svg"):
        p = path_stem.with_suffix(f".{ext}")
        with atomic_path(p) as tmp:
            fig.savefig(tmp, dpi=100)
        paths.append(p)
    plt.close(fig)
    return paths


def _fmt_failures(failures: dict) -> str:
    return ", ".join(f"{k} {v}" for k, v in sorted(failures.items())) or "-"


def markdown(summary: list[dict], skipped: dict[str, str], meta: dict, command: str, n_run: int,
             figures: list[str], kkt_form: dict[str, str] | None = None, per_iteration: dict | None = None) -> str:
    """The report: settings, the targets, one table per accuracy, the KKT-form and skipped problems, the machine."""
    lines = [
        "# Penalty rules on the Maros-Meszaros QPs, with and without OSQP's machinery, and OSQP 1.x",
        "",
        f"Command (from the repository root): `{command}`",
        "",
        f"{n_run} problems run, {len(skipped)} skipped (listed below).  Configurations: `variant/rule (order)`; "
        "variant `preset` is OSQP's machinery (`admmkit.problems.qp.osqp_settings()`), `textbook` admmkit's textbook "
        "loop, `no-scaling`, `uniform-rho`, `alpha-1` the preset without Ruiz scaling, the penalty per row or "
        "over-relaxation, `polish` with polishing; `OSQP` is the osqp package with its defaults.  Every run asks "
        f"for the absolute accuracy eps (eps_abs = eps, eps_rel = 0) from rho_0 = {RHO0:g}, with the iteration "
        f"cap {meta['max_iter']} and the time limit {meta['time_limit']:g} CPU s per run.  "
        "**neutral**: the returned (x, y) meets the neutral criteria (qpbenchmark's infinity-norm primal and dual "
        "residuals and duality gap, each <= eps); **own**: the solver's own test said solved.  Rates, shifted "
        f"geometric means (shift {SHIFT:g}; a failure counts as the cap / the limit) and the profiles use the neutral "
        "judgement.  Times are CPU seconds of the process (setup + solve, BLAS on one thread; every worker solves a small QP with admmkit (its kernels, its preset, Anderson) and with OSQP before its first timed case): the 2-core machine "
        f"was shared (the sweep ran on {meta['workers']}).  Factorisations: of the x-step matrix (OSQP: 1 + rho "
        "updates).  'runaway': runs where rho exceeded 1e20 rho_0.  Per-run data: `results.csv`.",
        "",
    ]
    lines += [f"![performance profiles]({f})" for f in figures] + [""]
    lines += ["## Targets", "", "| eps | polishing | best admmkit configuration | its neutral successes "
              "| OSQP's | met |", "|---|---|---|---|---|---|"]
    for t in target(summary):
        lines.append(f"| {t['eps']:g} | {'yes' if t['polish'] else 'no'} | {t['best']} | {t['best_neutral']}/"
                     f"{t['problems']} | {t['osqp_neutral']}/{t['problems']} | {'yes' if t['met'] else 'NO'} |")
    lines.append("")
    for eps, r in (per_iteration or {}).items():
        lines.append(f"Time per iteration, preset/osqp (xz) / OSQP, mid-sized problems ({MID_SIZE[0]} <= n + m <= "
                     f"{MID_SIZE[1]}, {r['count']} met the neutral criteria in both) at eps = {eps:g}: median "
                     f"{r['median']:.2f}, min {r['min']:.2f}, max {r['max']:.2f} (the loops' wall times; admmkit's loop here "
                     "also tests the looser accuracy every 25 iterations, and both ran beside the other worker: "
                     "`admmkit bench qp-fidelity` measures the ratio alone).")
    lines.append("")
    for eps in sorted({s["eps"] for s in summary}, reverse=True):
        lines += [f"## eps = {eps:g}", "",
                  "| configuration | neutral | own | rate | SGM iterations | SGM time [s] | factorisations mean / max "
                  "| failures (neutral criteria not met) | runaway |",
                  "|---|---|---|---|---|---|---|---|---|"]
        rows = sorted((s for s in summary if s["eps"] == eps), key=lambda s: (-s["rate"], s["sgm_time"]))
        for s in rows:
            lines.append(f"| {label((s['variant'], s['solver'], s['order']))} | {s['neutral']}/{s['problems']} | "
                         f"{s['solved']} | {100 * s['rate']:.1f}% | {s['sgm_iterations']:.1f} | {s['sgm_time']:.3f} "
                         f"| {s['factorizations_mean']:.1f} / {s['factorizations_max']} | "
                         f"{_fmt_failures(s['failures'])} | {s['runaway']} |")
        lines.append("")
    lines += ["## x-step in KKT form (textbook loop)", "",
              "The preset solves OSQP's KKT system; the textbook loop (`xstep=\"auto\"`) solves P + sigma I + "
              "rho A'A, except where a dense row of A makes A'A dense:", ""]
    lines += [f"- {name}: {why}" for name, why in sorted((kkt_form or {}).items())] or ["- none"]
    lines += ["", "## Skipped", ""]
    lines += [f"- {name}: {why}" for name, why in sorted(skipped.items())] or ["- none"]
    lines += ["", "## Machine", ""] + [f"- {k}: {v}" for k, v in meta["machine"].items()]
    lines += [f"- started {meta['started']}, wall time {meta['wall']:.0f} s"
              + (f" for the {meta['cases'] - meta['reused']} of {meta['cases']} cases this invocation ran (the others "
                 "were read from results.jsonl, as --resume asks)" if meta.get("reused") else ""), ""]
    return "\n".join(lines)


_INTS = ("n", "m", "iterations", "factorizations", "rho_changes")
_FLOATS = ("eps", "time", "setup_time", "loop_time", "rho_final", "rho_max", "neutral_primal", "neutral_dual",
           "neutral_gap")


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
            for k in _INTS:
                r[k] = int(r[k])
            for k in _FLOATS:
                r[k] = float(r[k])
            r["solved"], r["neutral"] = _true(r["solved"]), _true(r["neutral"])
            rows.append(r)
    return rows


def write_summary(summary: list[dict], path: Path) -> None:
    """summary.csv: one line per (eps, variant, solver, order), whole or not at all."""
    with atomic_open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["eps", "variant", "solver", "order", "problems", "neutral", "solved", "rate", "sgm_iterations",
                    "sgm_time", "factorizations_mean", "factorizations_max", "failures", "runaway"])
        for s in summary:
            w.writerow([s["eps"], s["variant"], s["solver"], s["order"], s["problems"], s["neutral"], s["solved"],
                        f"{s['rate']:.4f}", f"{s['sgm_iterations']:.2f}", f"{s['sgm_time']:.4f}",
                        f"{s['factorizations_mean']:.2f}", s["factorizations_max"], _fmt_failures(s["failures"]),
                        s["runaway"]])


def write_report(rows: list[dict], out: Path, *, skipped: dict, kkt_form: dict, meta: dict, command: str) -> dict:
    """results.csv, summary.csv, the profiles (iterations, time) and README.md from the per-run rows."""
    rows.sort(key=lambda r: (r["problem"], r["variant"], r["solver"], r["order"], -r["eps"]))
    write_rows(rows, out / "results.csv")
    summary = summarize(rows, meta["max_iter"], meta["time_limit"])
    figures = []
    if rows:
        for metric in ("iterations", "time"):
            figures += plot_profiles(rows, out / f"profiles_{metric}", metric)
    text = markdown(summary, skipped, meta, command, len({r["problem"] for r in rows}),
                    [p.name for p in figures if p.suffix == ".png"], kkt_form, time_per_iteration(rows))
    write_text(out / "README.md", text)
    write_summary(summary, out / "summary.csv")
    return {"summary": summary, "figures": figures, "text": text}
