"""The work-precision study's summary: time to a target error per method, the charts (error against time per problem) and the README (admmkit bench precision)."""
from __future__ import annotations

from pathlib import Path
from admmkit.io import write_text
from admmkit.benchmarks.fixtures import methods as methods_mod
from admmkit.benchmarks.fixtures.peers import PEERS
from admmkit.benchmarks.runner.machine import machine_info
from admmkit.benchmarks.runner.report import (NOISE_NOTE, fmt, machine_markdown, md_table, pyplot,
                     save_figure, write_csv)
from admmkit.benchmarks.fixtures.families import CONTACT_SCENES, OBSTACLE_SCENES, QP_SCENES, kind_of

TARGETS = (1e-4, 1e-8)
#: errors below this (the reference itself, e.g. PDAS's last step) are drawn at it
ERROR_FLOOR = 1e-15


# ---------------------------------------------------------------- summaries
def _problem_label(case: dict) -> str:
    from admmkit.benchmarks.runner.report import h_label
    return case["scene"] + ("" if case.get("h") is None else f" h={h_label(case['h'])}")


def time_to_error(points: list[dict], target: float) -> float | None:
    """The smallest time among the points whose error is <= target (None if none)."""
    ok = [p["time"] for p in points if p.get("err") is not None and p["err"] <= target]
    return min(ok) if ok else None


def summarise(records: dict, out: Path, *, command: str, wall: float, skipped: list[str], missing: int = 0) -> list[Path]:
    """Write precision.csv, time_to_error.{csv,md}, the figures and README.md from the sweep records."""
    out.mkdir(parents=True, exist_ok=True)
    rows, per_problem, refs, failures = [], {}, {}, []
    for rec in records.values():
        case, res = rec["case"], rec.get("result")
        prob = _problem_label(case)
        if res is None:
            failures.append((prob, case["method"], (rec.get("error") or "").splitlines()[0]))
            continue
        refs.setdefault(prob, (res.get("reference"), res.get("problem"), res.get("floor_rel")))
        per_problem.setdefault(prob, {"case": case, "methods": {}})["methods"][case["method"]] = res
        for p in res["points"]:
            rows.append({"problem": prob, "scene": case["scene"], "h": case.get("h"), "solver": case["solver"],
                         "method": case["method"], "tol": p.get("tol"), "step": p.get("step"), "time_s": p["time"],
                         "wall_s": p.get("wall"),
                         "err": p.get("err"), "err_lam": p.get("err_lam"), "iterations": p.get("iterations"),
                         "status": p.get("status", res.get("status")), "run_status": res.get("status"),
                         "repeats": len(p.get("times", [])), "solver_time_s": p.get("solver_time")})
    files = [write_csv(out / "precision.csv", rows)]

    # time to 1e-4 / 1e-8 and ratios to the fastest, within this run
    ttrows, tables = [], []
    order = _problem_order(per_problem)
    all_methods = _method_order(per_problem)
    for target in TARGETS:
        header = ["method"] + order
        body = []
        best = {}
        for prob in order:
            ts = [time_to_error(r["points"], target) for r in per_problem[prob]["methods"].values()]
            ts = [t for t in ts if t is not None]
            best[prob] = min(ts) if ts else None
        for m in all_methods:
            cells = [m]
            for prob in order:
                r = per_problem[prob]["methods"].get(m)
                if r is None:
                    cells.append("")
                    continue
                t = time_to_error(r["points"], target)
                ratio = t / best[prob] if t is not None and best[prob] else None
                ttrows.append({"target": target, "problem": prob, "method": m, "time_s": t, "ratio_to_fastest": ratio,
                               "run_status": r.get("status")})
                cells.append("not reached" if t is None else f"{ratio:.3g} ({t:.3g} s)")
            body.append(cells)
        tables.append((target, md_table(header, body)))
    files.append(write_csv(out / "time_to_error.csv", ttrows))
    md = [f"# Time to a relative error of {', '.join(f'{t:g}' for t in TARGETS)}", "",
          "Each cell: time / time of the fastest method on the same problem, measured in this run, and the time "
          "in CPU seconds of the process (median of the repeats; one BLAS thread, so this is the work done "
          "whatever the load of the shared machine). The time of a method is that of the loosest tolerance on its "
          "ladder whose answer has a true error at or below the target (the error norms are in README.md). "
          "'not reached': no tolerance of the ladder got there within the iteration cap / time limit.", "",
          NOISE_NOTE, ""]
    for target, table in tables:
        md += [f"## Relative error {target:g}", "", table, ""]
    write_text(out / "time_to_error.md", "\n".join(md))
    files.append(out / "time_to_error.md")

    files += _figures(per_problem, refs, out)
    files.append(_readme(out, per_problem, refs, failures, command, wall, skipped, files, missing))
    return files


def _problem_order(per_problem) -> list[str]:
    def key(prob):
        case = per_problem[prob]["case"]
        scenes = CONTACT_SCENES + OBSTACLE_SCENES + QP_SCENES
        s = case["scene"]
        return (scenes.index(s) if s in scenes else 99, s, -(case.get("h") or 0))
    return sorted(per_problem, key=key)


def _method_order(per_problem) -> list[str]:
    seen = []
    for prob in per_problem.values():
        for m in prob["methods"]:
            if m not in seen:
                seen.append(m)
    admm = methods_mod.admm_methods()
    return [m for m in admm if m in seen] + [m for m in seen if m not in admm and m not in PEERS] + \
        [p for p in PEERS if p in seen]


#: the error norm of each problem family, named on the charts' y axis (README: "error norms")
ERROR_NORMS = {"contact": "energy-norm error of u\n||u - u*||_K / ||u*||_K",
               "obstacle": "lumped L2 error of u\n||u - u*||_M / ||u*||_M",
               "qp": "error of x\n||x - x*||_2 / ||x*||_2"}
#: the left column: the paper's methods and the peers (ADMM1 and ADMM2 drawn apart where they coincide)
PAPER_AND_PEERS = {"admm1": dict(color="tab:blue", marker="o", linestyle="-", linewidth=1.6, markersize=4),
                   "admm2": dict(color="tab:orange", marker="s", linestyle="--", linewidth=1.6, markersize=7,
                                 markerfacecolor="none", markeredgewidth=1.3),
                   "sadmm": dict(color="tab:green", marker="^", linestyle="-", linewidth=2.0, markersize=5),
                   "pdas": dict(color="black", marker="D", linestyle="-", linewidth=1.6, markersize=4),
                   "clarabel": dict(color="0.45", marker="P", linestyle="--", linewidth=1.4, markersize=5),
                   "cvxpy-osqp": dict(color="0.6", marker="v", linestyle=":", linewidth=1.8, markersize=5),
                   "osqp": dict(color="0.25", marker="<", linestyle="-.", linewidth=1.4, markersize=5)}
#: the right column: the other rules, colour = rule, solid = order xz, dashed = order zx
RULE_COLOURS = {"aadmm": "tab:purple", "osqp": "tab:brown", "quantized": "tab:pink",
                "residual_balancing": "tab:olive", "summable": "tab:cyan", "summable_steps": "navy",
                "wohlberg": "goldenrod"}
#: run or point statuses that are failures: the run stopped at the cap or the time limit, or the solver said so
FAILED = ("max_iter", "time_limit", "run time limit reached", "user_limit", "optimal_inaccurate", "solved inaccurate")


def _rule_style(method: str) -> dict:
    rule, _, order = method.partition("/")
    return dict(color=RULE_COLOURS.get(rule, "0.5"), marker="o" if order == "xz" else "s", markersize=3.5,
                linestyle="-" if order == "xz" else "--", linewidth=1.3)


def _failures(res: dict, pts: list[dict]) -> list[dict]:
    """The points to mark as failures: a point the solver flagged, or the last point of a run that hit the cap."""
    bad = [p for p in pts if p.get("status") in FAILED]
    if res.get("status") in FAILED and pts:
        bad.append(pts[-1])
    return bad


def _figures(per_problem, refs, out: Path) -> list[Path]:
    """One chart per scene, readable at the docs' page width: a row per mesh size (or QP), two panels per row:
    the paper's methods with the peers, and the other rules (colour = rule, solid xz, dashed zx)."""
    plt = pyplot()
    from matplotlib.lines import Line2D
    from matplotlib.ticker import NullFormatter
    files = []
    by_scene: dict[str, list[str]] = {}
    for prob in _problem_order(per_problem):
        scene = per_problem[prob]["case"]["scene"]
        by_scene.setdefault("qp" if scene.startswith("qp:") else scene, []).append(prob)
    for scene, probs in by_scene.items():
        kind = kind_of(per_problem[probs[0]]["case"]["scene"])
        fig, axes = plt.subplots(len(probs), 2, figsize=(10, 2.7 * len(probs) + 1.9), squeeze=False,
                                 sharey=True, sharex="row")
        failed_any = False
        for row, prob in zip(axes, probs):
            for m, res in per_problem[prob]["methods"].items():
                pts = sorted((p for p in res["points"] if p.get("err") is not None and p["time"] > 0),
                             key=lambda p: p["time"])
                if not pts:
                    continue
                left = m in PAPER_AND_PEERS
                ax = row[0] if left else row[1]
                style = PAPER_AND_PEERS[m] if left else _rule_style(m)
                ax.loglog([p["time"] for p in pts], [max(p["err"], ERROR_FLOOR) for p in pts], label=m, **style)
                bad = _failures(res, pts)
                if bad:
                    failed_any = True
                    ax.plot([p["time"] for p in bad], [max(p["err"], ERROR_FLOOR) for p in bad], "X", color="red",
                            markersize=9, markeredgecolor="black", markeredgewidth=0.6, zorder=5)
            floor = (refs.get(prob) or (None, None, None))[2]
            for ax in row:
                for target in TARGETS:
                    ax.axhline(target, color="0.75", linewidth=0.8, linestyle=":")
                if floor:
                    ax.axhline(floor, color="tab:red", linewidth=1.0, linestyle="--")
                ax.set_ylim(ERROR_FLOOR / 3, 3)
                ax.grid(True, which="major", alpha=0.3)
                ax.tick_params(labelsize=9)
                ax.xaxis.set_minor_formatter(NullFormatter())
                ax.set_title(prob, fontsize=10)
            row[0].set_ylabel(ERROR_NORMS[kind], fontsize=9)
        for ax in axes[-1]:
            ax.set_xlabel("CPU time [s]", fontsize=10)
        extra = [Line2D([], [], color="0.75", linestyle=":", label="targets 1e-4, 1e-8")]
        if any((refs.get(p) or (None, None, None))[2] for p in probs):
            extra.append(Line2D([], [], color="tab:red", linestyle="--", label="discretisation error"))
        if failed_any:
            extra.append(Line2D([], [], color="red", marker="X", linestyle="none", markersize=8,
                                markeredgecolor="black", label="failed: iteration cap, time limit or inaccurate"))
        left = [m for m in PAPER_AND_PEERS if any(m in per_problem[p]["methods"] for p in probs)]
        handles = [Line2D([], [], label=m, **PAPER_AND_PEERS[m]) for m in left]
        axes[0][0].legend(handles=handles + extra, fontsize=8, ncol=2, loc="lower left", bbox_to_anchor=(0, 1.12),
                          frameon=False, title="the paper's methods and the peers", title_fontsize=9)
        rules = sorted({m.partition("/")[0] for p in probs for m in per_problem[p]["methods"] if m not in PAPER_AND_PEERS})
        handles = [Line2D([], [], color=RULE_COLOURS.get(r, "0.5"), linewidth=2, label=r) for r in rules]
        handles += [Line2D([], [], color="0.3", linestyle="-", marker="o", markersize=3.5, label="order xz"),
                    Line2D([], [], color="0.3", linestyle="--", marker="s", markersize=3.5, label="order zx")]
        axes[0][1].legend(handles=handles, fontsize=8, ncol=3, loc="lower left", bbox_to_anchor=(0, 1.12),
                          frameon=False, title="the other rules: colour = rule, line = order", title_fontsize=9)
        fig.suptitle(f"Work-precision, {scene}: true error against CPU time (median of repeats)", fontsize=11, y=1.0)
        fig.tight_layout()
        fig.text(0.01, -0.005, "ADMM1 (solid, dots) and ADMM2 (dashed, open squares) nearly coincide on most problems: the "
                 "same fixed rho, the x- and z-steps in the other order.", fontsize=8, va="top")
        files += save_figure(fig, out / f"precision_{scene}")
    return files


def _readme(out: Path, per_problem, refs, failures, command, wall, skipped, files, missing=0) -> Path:
    lines = ["# Work-precision: true error against time", "",
             f"Produced by `{command}`; " + (f"wall time of the sweep {wall:.0f} s (this invocation; a resumed "
                                              "sweep reuses the finished cases of earlier invocations, see "
                                              "results.jsonl)." if wall is not None else
                                              "these files were rewritten from results.jsonl (--report-only)."), "",
             "- ADMM methods: every registered penalty policy in both orders (admm1 = fixed/xz, admm2 = fixed/zx, "
             "sadmm = summable/zx with tau = 2, c_max = 100), from rho_0 = E (contact) or 1 (obstacle, QPs); "
             "one run to Boyd's residual test at 1e-10 with the points where the looser tolerances "
             "1e-1 ... 10^-9.5 (half decades) would have stopped it (relative tolerances for the PDE problems, "
             "eps_abs = eps_rel for the QPs); time = problem setup + the iterations + the final recovery of u.",
             "- time: CPU seconds of the process (time.process_time; every solver runs on one thread, BLAS pinned "
             "to one), so the charts measure work, not the momentary load of the shared machine; the wall seconds "
             "are in precision.csv (wall_s).",
             "- peers on the same discrete QP: PDAS (primal-dual active set, one point per Newton step; contact "
             "uses the same boundary Schur complement as condensed ADMM), cvxpy + Clarabel (tolerances 1e-3, "
             "1e-5, 1e-7, 1e-9), cvxpy + OSQP and OSQP called directly (1e-2, 1e-4, 1e-6, 1e-8); two tolerances "
             "each above 150000 unknowns. cvxpy times include building and canonicalising the problem (what a "
             "user pays); the solver's own time is in precision.csv (solver_time_s). cvxpy switches OSQP's "
             "solution polishing on, so cvxpy + OSQP often lands on the exact active set.",
             "- error norms: contact, u in the energy norm ||u - u*||_K / ||u*||_K (err_lam: the pressure in the "
             "lumped boundary-mass norm); obstacle, the lumped L2 norm ||u - u*||_M / ||u*||_M against the discrete "
             "solution (the red dashed line is the discretisation error of the discrete solution against the exact "
             "one, in the same relative units: below it more precision buys nothing); QPs, ||x - x*||_2 / ||x*||_2. "
             "Errors below 1e-15 (PDAS's last step is the reference) are drawn at 1e-15.",
             "- times are medians over the repeats (a case whose first run took over 10 s ran once); ADMM runs "
             "stop at 20000 iterations or after 60 s (wall); so do the OSQP runs.", "", NOISE_NOTE, "", "## Reference solutions", ""]
    body = []
    for prob in _problem_order(per_problem):
        ref, info, floor = refs.get(prob) or ({}, {}, None)
        ref = ref or {}
        cc = ref.get("cross_check") or {}
        diffs = ", ".join(f"{k} {v:.1e}" for k, v in cc.items() if k != "other" and isinstance(v, float))
        kkt = ", ".join(f"{k} {v:.1e}" for k, v in (ref.get("kkt") or {}).items())
        body.append([prob, str((info or {}).get("n", "")), ref.get("solver", ""), kkt,
                     (cc.get("other", "") + (": " + diffs if diffs else "")), fmt(floor, ".2e")])
    lines += [md_table(["problem", "n", "reference", "KKT residuals", "cross-check (relative differences)",
                        "discretisation error (rel.)"], body, "lrllll"), ""]
    if skipped:
        lines += [f"Policies left out (they need constructor arguments): {', '.join(skipped)}.", ""]
    if missing:
        lines += [f"**{missing} cases of the sweep had not finished when these files were written** (written with "
                  "--report-only); they are missing from the tables and charts.", ""]
    if failures:
        lines += ["## Cases that raised", ""] + [f"- {p}, {m}: {e}" for p, m, e in failures] + [""]
    figures = sorted({f.stem for f in files if f.suffix == ".png"})
    if figures:
        lines += ["## Charts", ""] + [f"![{name}]({name}.png)\n" for name in figures]
    lines += ["## Files", "", "- `precision.csv`: one row per point (problem, method, tolerance or Newton step, "
              "median time, errors of u and lam, iterations, status, repeats)",
              "- `time_to_error.{md,csv}`: time to a relative error of 1e-4 and 1e-8, and the ratio to the fastest",
              "- `precision_<scene>.{png,svg}`: the charts", "- `results.jsonl`: the raw sweep records (one JSON line "
              "per finished case; the sweep resumes from it)", ""]
    lines.append(machine_markdown(machine_info(pinned_blas=True)))
    path = out / "README.md"
    write_text(path, "\n".join(lines))
    return path
