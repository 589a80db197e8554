"""The results page of admmkit's QP preset against OSQP 1.x (docs/results/qp_rules): counts, targets, profiles.

    python -m admmkit.benchmarks.qp.qp_rules_report docs/results/qp_rules/bench_qp/results.csv docs/results/qp_rules

reads the per-run rows of ``admmkit bench qp --policies osqp --orders xz
--variants preset,admmkit`` (admmkit's preset ``admmkit/osqp``, OSQP's preset
``preset/osqp`` and OSQP 1.x itself, at eps = 1e-3 and 1e-6, eps_rel = 0) and
writes README.md with:

- successes by qpbenchmark's criteria (the neutral ones: primal residual,
  dual residual and duality gap each <= eps, :mod:`admmkit.problems.qp.residuals`)
  on all the Maros-Meszaros problems run and on qpbenchmark's class
  (n + m <= 3000, bound rows not counted, :func:`admmkit.benchmarks.rules.study.qp_size`),
  each split into the training and the test half (:func:`split`);
- the issue's targets on the class: successes, problems lost against OSQP's
  preset, false ``converged`` (own test solved, neutral criteria missed), and
  the shifted geometric mean (shift 10 s) of whole-solve time over the
  problems both admmkit's preset and OSQP 1.x solve;
- Dolan-More performance profiles of iterations and of whole-solve time
  (rows: eps; columns: all problems, the class), as PNG.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from admmkit.io import atomic_path, write_text
from admmkit.benchmarks.qp.maros_meszaros_report import read_rows
from admmkit.benchmarks.qp.maros_meszaros_stats import SHIFT, shifted_geometric_mean
from admmkit.benchmarks.runner.profiles import cost_table, profile

#: the configurations compared: (variant, solver) -> label
CONFIGS = {("admmkit", "osqp"): "admmkit_settings", ("preset", "osqp"): "osqp_settings",
           ("default", "OSQP"): "OSQP 1.1 (C)"}
STYLE = {"admmkit_settings": dict(color="tab:red", linewidth=2.0), "osqp_settings": dict(color="tab:blue", linewidth=1.4),
         "OSQP 1.1 (C)": dict(color="black", linewidth=1.6, linestyle="--")}
ADMMKIT, PRESET, OSQP = CONFIGS.values()


def split(names) -> dict[str, str]:
    """The fixed training / test split: the problems sorted by name, every other one from the first is "train"."""
    return {name: ("train" if i % 2 == 0 else "test") for i, name in enumerate(sorted(names))}


def qp_class(data: Path) -> set[str]:
    """qpbenchmark's class in the folder ``data``: the convex problems with n + m <= 3000, bound rows not counted
    (the qp family of ``admmkit bench rules``, :func:`admmkit.benchmarks.rules.study.qp_files`)."""
    from admmkit.benchmarks.rules.study import qp_files
    return {path.stem for path in qp_files(data, quick=False)}


def labelled(rows: list[dict]) -> list[dict]:
    """The rows of the compared configurations, each with its ``config`` label and ``ok`` (neutral success)."""
    out = []
    for r in rows:
        name = CONFIGS.get((r["variant"], r["solver"]))
        if name is not None:
            out.append(r | {"config": name, "ok": bool(r["solved"]) and bool(r["neutral"])})
    return out


def counts(rows: list[dict], eps: float, problems: set[str]) -> dict[str, dict]:
    """Per configuration: neutral successes, false "converged" and the set solved, on ``problems`` at ``eps``."""
    out = {}
    for name in CONFIGS.values():
        mine = [r for r in rows if r["config"] == name and r["eps"] == eps and r["problem"] in problems]
        out[name] = {"solved": {r["problem"] for r in mine if r["ok"]},
                     "false": sorted(r["problem"] for r in mine if r["solved"] and not r["neutral"]),
                     "runs": len(mine)}
    return out


def time_sgm(rows: list[dict], eps: float, problems: set[str], a: str, b: str) -> tuple[float, float, int]:
    """Shifted geometric means (shift 10 s) of whole-solve time of ``a`` and ``b`` over the problems both solve."""
    by = {(r["config"], r["problem"]): r for r in rows if r["eps"] == eps}
    both = [p for p in sorted(problems) if by.get((a, p), {}).get("ok") and by.get((b, p), {}).get("ok")]
    return (shifted_geometric_mean([by[(a, p)]["time"] for p in both], SHIFT),
            shifted_geometric_mean([by[(b, p)]["time"] for p in both], SHIFT), len(both))


def plot(rows: list[dict], sets: dict[str, set[str]], metric: str, path: Path) -> Path:
    """Performance profiles of ``metric`` (rows: eps; columns: the problem sets), neutral successes only."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    epss = sorted({r["eps"] for r in rows}, reverse=True)
    names = list(CONFIGS.values())
    fig, axes = plt.subplots(len(epss), len(sets), figsize=(6.0 * len(sets), 4.2 * len(epss)), squeeze=False)
    taus = np.logspace(0, 3, 400)
    for i, eps in enumerate(epss):
        for j, (title, problems) in enumerate(sets.items()):
            ax = axes[i][j]
            mine = [r for r in rows if r["eps"] == eps and r["problem"] in problems]
            table = cost_table(mine, names, metric, config=lambda r: r["config"], solved=lambda r: r["ok"])
            _, fractions = profile(table, taus)
            for k, name in enumerate(names):
                ax.step(taus, fractions[:, k], where="post", label=name, **STYLE[name])
            ax.set_xscale("log", base=10)
            ax.set_ylim(0, 1.02)
            ax.set_xlabel(f"tau (within a factor tau of the best {'iterations' if metric == 'iterations' else 'time'})")
            ax.set_ylabel("fraction of problems")
            ax.set_title(f"{title}, eps = {eps:g}")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(loc="lower right", fontsize=9)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
    return path


def report(results: Path, out: Path, data: Path) -> Path:
    """Write README.md and the two profile PNGs to ``out`` (made if missing); return the README's path."""
    rows = labelled(read_rows(results))
    out.mkdir(parents=True, exist_ok=True)
    everything = {r["problem"] for r in rows}
    klass = qp_class(data)
    halves = split(klass)
    sets = {f"all {len(everything)} run": everything, f"qpbenchmark's class ({len(klass)})": klass}
    figures = [plot(rows, sets, m, out / f"profiles_{name}.png") for m, name in (("iterations", "iterations"),
                                                                                 ("time", "time"))]
    from admmkit.problems.qp.mat import list_problems
    missing = sorted({path.stem for path in list_problems(data)} - everything)
    lines = ["# admmkit's QP preset against OSQP 1.x on Maros-Meszaros", "",
             "Made by `python -m admmkit.benchmarks.qp.qp_rules_report docs/results/qp_rules/bench_qp/results.csv "
             "docs/results/qp_rules` from the runs of `bench_qp/` (their command and machine: "
             "[bench_qp/README.md](bench_qp/README.md)).", "",
             "Configurations: `admmkit_settings` = `admmkit.problems.qp.admmkit_settings()` (OSQP's machinery, "
             "the rule rowwise (a penalty per row), the cap raised to 100,000 iterations, polishing during the run); `osqp_settings` = admmkit's "
             "re-implementation of OSQP 1.x (`osqp_settings()`, cap 4000); `OSQP 1.1 (C)` = the osqp package 1.1.3 "
             "with its defaults (cap 4000).  Every run asks for eps_abs = eps, eps_rel = 0 and has 5 CPU s; a "
             "success is qpbenchmark's: the returned (x, y) has primal residual, dual residual and duality gap "
             "each <= eps (inf-norms, the user's problem).  Times are whole solves (setup, scaling, "
             "factorisations, polishing), CPU seconds, on a shared 2-core machine.", "",
             f"qpbenchmark's class: n + m <= 3000 counting the rows of A with more than one entry (single-entry "
             f"rows are bounds, qpbenchmark's lb <= x <= ub): {len(klass)} convex problems (VALUES, not convex, "
             f"is refused).  Training split: the class sorted by name, every other problem from the first "
             f"({sum(v == 'train' for v in halves.values())} problems); test split: the others "
             f"({sum(v == 'test' for v in halves.values())}).  The preset was chosen on the training split only.", "",
             f"\"all\": the {len(everything)} problems every configuration ran; not in this run "
             f"({len(missing)} of the {len(everything) + len(missing)} MAT files; EXDATA is not in the folder): "
             f"{', '.join(missing) or 'none'}.", ""]
    for eps in sorted({r["eps"] for r in rows}, reverse=True):
        lines += [f"## eps = {eps:g}", "",
                  "| configuration | all | class | class, train | class, test | false converged (class) |",
                  "| --- | ---: | ---: | ---: | ---: | --- |"]
        c_all, c_cls = counts(rows, eps, everything), counts(rows, eps, klass)
        for name in CONFIGS.values():
            s = c_cls[name]["solved"]
            train = sum(halves[p] == "train" for p in s)
            lines.append(f"| {name} | {len(c_all[name]['solved'])}/{len(everything)} | {len(s)}/{len(klass)} | "
                         f"{train}/{sum(v == 'train' for v in halves.values())} | {len(s) - train}/"
                         f"{sum(v == 'test' for v in halves.values())} | {', '.join(c_cls[name]['false']) or 'none'} |")
        ours, preset, osqp = (c_cls[n]["solved"] for n in (ADMMKIT, PRESET, OSQP))
        t_ours, t_osqp, both = time_sgm(rows, eps, klass, ADMMKIT, OSQP)
        lines += ["", f"On the class: lost against `osqp_settings`: {', '.join(sorted(preset - ours)) or 'none'}; "
                      f"against OSQP 1.1: {', '.join(sorted(osqp - ours)) or 'none'}; gained against OSQP 1.1: "
                      f"{', '.join(sorted(ours - osqp)) or 'none'}.  Shifted geometric mean (shift {SHIFT:g} s) of "
                      f"whole-solve time over the {both} problems both solve: admmkit_settings {t_ours:.4f} s, "
                      f"OSQP 1.1 {t_osqp:.4f} s.", ""]
    lines += ["## The same comparison as a ranking, and how the preset was chosen", "",
              "`admmkit bench rules --families qp --rules osqp --presets osqp,admmkit --acceleration none` ranks "
              "OSQP's rule in OSQP's preset (`osqp`) against admmkit's preset (`osqp@admmkit`) on the class, in one "
              "command: [ranking/README.md](ranking/README.md).  What was tried on the training split, and why the "
              "preset is what it is: [choice.md](choice.md).", "",
              "## Performance profiles (Dolan-More)", "",
              "Fraction of problems solved within a factor tau of the best configuration on each problem "
              "(a failure never counts).", "", "![iterations](profiles_iterations.png)", "",
              "![time](profiles_time.png)", ""]
    readme = out / "README.md"
    write_text(readme, "\n".join(lines))
    return readme


if __name__ == "__main__":
    print(report(Path(sys.argv[1]), Path(sys.argv[2]),
                 Path(sys.argv[3]) if len(sys.argv) > 3 else Path("../shared/data/maros_meszaros")))
