"""``admmkit bench scale``: Example 1 with the iterative x-step from 1e3 to 1e6 unknowns.

Each size runs in its own process (:func:`admmkit.benchmarks.contact.scale_runs.run_in_subprocess`),
so the peak resident memory (ru_maxrss) belongs to that size.  Writes
``scale.md``, ``scale.csv`` and the log-log growth chart ``scale_growth.png/svg``
(time, SADMM and CG iterations and peak memory against the unknowns, with the
ideal linear slope), and checks the issue's target at the largest size: at most
60 s and 8 GB for more than 1e6 unknowns.

Next to the algebraic stop it reports, for every size, what the computed
displacement u_h is worth (measured after the clock and the peak memory were
read, :func:`admmkit.benchmarks.contact.scale_runs.accuracy_at_stop`): the ZZ
estimate of the discretisation error relative to ||u_h||_a, the last relative
change, the algebraic error against a tight reference of the same discrete
problem up to 2e5 unknowns, and the energy error against the finest run.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

from admmkit.figures import pyplot, save_figure
from admmkit.io import write_text

from admmkit.benchmarks.runner.machine import machine_info
from admmkit.benchmarks.runner.report import write_csv
from admmkit.benchmarks.contact import scale_runs

#: 1.7e3, 6.6e3, 2.6e4, 1.0e5, 4.1e5 and 1.0e6 free unknowns on Example 1 (P1)
DEFAULT_HS = (1 / 20, 1 / 40, 1 / 80, 1 / 160, 1 / 320, 1 / 500)
QUICK_HS = (1 / 10, 1 / 20)
TARGET_SECONDS, TARGET_BYTES, TARGET_N = 60.0, 8e9, 1_000_000
#: the energy error against the finest run is given for sizes whose h is at least this many times the finest h
FINEST_RATIO = 3.0
#: the size of the untimed warm-up process that compiles (or loads) the kernels before the measured sizes
WARM_UP_H = 1 / 10
#: the runs that the stopping rule ended: charted and checked against the target (the table gives each status)
FINISHED = ("converged", "converged_inaccurate")


def process_s(r: dict) -> float:
    """The process's wall time without the accuracy measurements made after the run."""
    return r["wall_s"] - r.get("accuracy_s", 0.0)


def run_in_subprocess(example: str, h: float, mode: str, timeout: float = 1800.0, rho: float = 1e3) -> dict:
    """One size in its own process (:func:`admmkit.benchmarks.contact.scale_runs.run_in_subprocess`), with the
    accuracy of the computed solution measured after the run."""
    return scale_runs.run_in_subprocess(example, h, mode, timeout=timeout, rho=rho, accuracy=True)


def h_label(h: float) -> str:
    """1/N for h = 1/N, else the number."""
    inv = 1 / h
    return f"1/{round(inv)}" if abs(inv - round(inv)) < 1e-9 else f"{h:g}"


def run_scale_bench(out="out/scale", hs=DEFAULT_HS, example="ex1", mode="iterative",
                    command="admmkit bench scale", timeout=1800.0) -> list[dict]:
    """Run the sizes, print one line each, write the table and the chart."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    start = time.perf_counter()
    # one untimed process first: it compiles numba's kernels (or loads them from its cache), so that no
    # measured size pays for that (a fresh install would otherwise put it on the first size)
    print(f"warm-up: {example} h = {h_label(WARM_UP_H)} (untimed; compiles or loads the kernels) ...", flush=True)
    run_in_subprocess(example, WARM_UP_H, mode, timeout=timeout)
    for i, h in enumerate(hs, 1):
        print(f"[{i}/{len(hs)}] {example} h = {h_label(h)} mode {mode} ...", flush=True)
        row = run_in_subprocess(example, h, mode, timeout=timeout)
        rows.append(row)
        print("        " + _line(row), flush=True)
    wall = time.perf_counter() - start
    _error_vs_finest(rows)
    write_csv(out / "scale.csv", [_flat(r) for r in rows], COLUMNS, float_format=".6g")
    _write_markdown(out / "scale.md", rows, example, mode, command, wall)
    done = [r for r in rows if r.get("status") in FINISHED]
    if len(done) >= 2:
        _figure(out / "scale_growth.png", done, example, mode)
    return rows


def _line(r: dict) -> str:
    if r.get("status") in ("refused", "timeout", "failed"):
        return f"{r['status']}: {r.get('message', '')}"
    c = r.get("counters", {})
    return (f"n = {r['n_free']:8d}  {r['status']}  {r['iterations']} iterations, {c.get('cg_iterations', '-')} CG  "
            f"assemble {r['assemble_s']:.2f} s  setup {r['setup_s']:.2f} s  SADMM {r['solve_s']:.2f} s  "
            f"total {r['total_s']:.2f} s (process {process_s(r):.1f} s)  peak {r['peak_rss_bytes'] / 1e9:.2f} GB "
            f"(estimate {r['estimate_bytes'] / 1e9:.2f} GB)  ZZ rel. {_e(r.get('zz_rel'))}  "
            f"last change {_e(r.get('last_change'))}  algebraic error {_e(r.get('alg_error'))}")


def _e(v) -> str:
    """A number as 1.23e-04, or '-' when it was not measured."""
    return "-" if v is None or not math.isfinite(v) else f"{v:.2e}"


def _error_vs_finest(rows) -> None:
    """energy_error_rel = sqrt(2 (J(u_h) - J(u_fine))) / ||u_fine||_a for the rows at least FINEST_RATIO times
    coarser than the finest row with an energy (J(u_h) - J(u) >= ||u_h - u||_a^2 / 2)."""
    have = [r for r in rows if math.isfinite(r.get("energy", math.nan))]
    if not have:
        return
    fine = min(have, key=lambda r: r["h"])
    for r in have:
        if r["h"] >= FINEST_RATIO * fine["h"] * (1 - 1e-9):
            r["energy_error_rel"] = math.sqrt(2 * max(r["energy"] - fine["energy"], 0.0)) / fine["u_energy"]


COLUMNS = ["h", "n_free", "n_c", "status", "iterations", "rho_changes", "cg_iterations", "amg_setups",
           "amg_refreshes", "assemble_s", "setup_s", "amg_setup_s", "amg_refresh_s", "cg_s", "solve_s", "total_s",
           "wall_s", "peak_rss_bytes", "estimate_bytes", "penetration", "stationarity", "last_change", "alg_error",
           "zz", "u_energy", "zz_rel", "energy", "energy_error_rel", "zz_s", "reference_s", "accuracy_s"]


def _flat(r: dict) -> dict:
    return r | {k: r.get("counters", {}).get(k) for k in ("cg_iterations", "amg_setups", "amg_refreshes")}


def _slope(rows, key) -> float:
    """Least-squares slope of log(key) against log(n) over the runs with n >= 1e4."""
    pts = [(math.log(r["n_free"]), math.log(r[key])) for r in rows if r["n_free"] >= 1e4 and r.get(key)]
    if len(pts) < 2:
        return math.nan
    mx = sum(p[0] for p in pts) / len(pts)
    my = sum(p[1] for p in pts) / len(pts)
    return sum((x - mx) * (y - my) for x, y in pts) / sum((x - mx) ** 2 for x, _ in pts)


def _write_markdown(path: Path, rows, example, mode, command, wall) -> None:
    info = machine_info()
    lines = [f"# Scale: Example {example[-1]} with the {mode} x-step, 1e3 to 1e6 unknowns", "",
             f"Produced by `{command}` ({wall:.0f} s in all). SADMM (tau = 2, c_max = 100), rho_0 = 1e3, the paper's "
             "stopping rule (relative change 1e-5 in the energy norm), P1 on the paper's structured mesh. Each size "
             f"ran in its own process ({scale_runs.environment_text()}), after an untimed one at "
             f"h = {h_label(WARM_UP_H)} that compiled or loaded the compiled kernels; `peak` is that process's ru_maxrss "
             "(Python, NGSolve and "
             "the solvers included); `estimate` is what the memory check (`admmkit.problems.contact.model.memory.memory_need`) "
             "predicted before anything was assembled. `total` = assembly + setup + SADMM inside the process; "
             "`process` adds the interpreter start and imports (not the accuracy measurements made after the "
             "run, below). Growth, chart and target take every run that the stopping rule ended, "
             "`converged_inaccurate` included (see the note below the accuracy table).", "",
             "| h | unknowns | contact nodes | status | SADMM it. | CG it. | AMG setups / refreshes | assemble (s) | "
             "AMG setup (s) | SADMM (s) | total (s) | process (s) | peak (GB) | estimate (GB) |",
             "|---|---:|---:|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        if r.get("status") in ("refused", "timeout", "failed"):
            lines.append(f"| {h_label(r['h'])} | | | {r['status']}: {r.get('message', '')} | | | | | | | | | | |")
            continue
        c = r.get("counters", {})
        lines.append(f"| {h_label(r['h'])} | {r['n_free']} | {r['n_c']} | {r['status']} | {r['iterations']} | "
                     f"{c.get('cg_iterations', '')} | {c.get('amg_setups', '')} / {c.get('amg_refreshes', '')} | "
                     f"{r['assemble_s']:.2f} | {r.get('amg_setup_s', r['setup_s']):.2f} | {r['solve_s']:.2f} | "
                     f"{r['total_s']:.2f} | {process_s(r):.1f} | {r['peak_rss_bytes'] / 1e9:.2f} | "
                     f"{r['estimate_bytes'] / 1e9:.2f} |")
    done = [r for r in rows if r.get("status") in FINISHED]
    if done:
        big = max(done, key=lambda r: r["n_free"])
        ok_t, ok_m = big["total_s"] <= TARGET_SECONDS, big["peak_rss_bytes"] <= TARGET_BYTES
        lines += ["", f"Growth exponents (log-log least squares over the sizes >= 1e4; 1 is linear): total time "
                  f"{_slope(done, 'total_s'):.2f}, SADMM time {_slope(done, 'solve_s'):.2f}, peak memory "
                  f"{_slope(done, 'peak_rss_bytes'):.2f}.", "",
                  f"Target (issue #8): more than 1e6 unknowns in at most {TARGET_SECONDS:.0f} s and 8 GB. "
                  f"Largest run: {big['n_free']} unknowns, total {big['total_s']:.1f} s "
                  f"({'met' if ok_t else 'MISSED'}), process {process_s(big):.1f} s, peak {big['peak_rss_bytes'] / 1e9:.2f} GB "
                  f"({'met' if ok_m else 'MISSED'})" + ("" if big["n_free"] > TARGET_N else
                                                         " -- below 1e6 unknowns, so the target was not tested") + ".",
                  "", "Chart: `scale_growth.png` (log-log)."]
    lines += _accuracy_section(rows)
    lines += ["", "Machine (shared with other engineers during the run, so times are noisy; the load average "
              "says how busy it was):", ""] + [f"- {k}: {v}" for k, v in info.items()]
    write_text(path, "\n".join(lines) + "\n")


def _ratio(a, b) -> float:
    return a / b if a is not None and b and math.isfinite(a) and math.isfinite(b) else math.nan


def _accuracy_section(rows) -> list[str]:
    """The table of what the computed solution is worth at the stop, and how to read it."""
    runs = [r for r in rows if "zz_rel" in r]
    if not runs:
        return []
    lines = ["", "## Accuracy at the stop", "",
             "Measured after the run (not in its times or peak memory), on the displacement u_h it returned. "
             "`last change`: ||x^k - x^(k-1)|| / ||x^k|| at the last iteration, the paper's stopping quantity "
             "(tolerance 1e-5). `algebraic error`: ||u_h - u*||_K / ||u*||_K against a tight solution u* of the "
             "same discrete problem (cvxpy + Clarabel at 1e-10, cross-checked by SADMM to Boyd residuals 1e-12: "
             "the paper reproduction's reference, `admmkit.problems.contact.validation.reference`; `IPM` in the "
             f"`reference` column) up to {scale_runs.REFERENCE_MAX_N:,} unknowns, above that against the same run "
             f"continued from its stop (warm start) to a relative change of {scale_runs.TIGHT_CHANGE:g} "
             "(`continued`; at 1.0e5 unknowns the two gave 7.4286e-05 and 7.4240e-05). "
             "`ZZ rel.`: the gradient-recovery (ZZ) estimate of "
             "the discretisation error ||u - u_h||_a (`zz_estimate` of `admmkit.problems.contact.solvers.estimate`) "
             "over ||u_h||_a; an estimate, not a bound (on Example 1, P1, its effectivity was 0.73-0.98 at h = "
             "1/5 ... 1/40, `admmkit bench estimators`). `error vs finest`: sqrt(2 (J(u_h) - J(u_f))) / ||u_f||_a, "
             "with J(v) = v'Kv/2 - f'v and u_f the finest run of this table standing in for the exact solution "
             f"(J(u_h) - J(u) >= ||u_h - u||_a^2 / 2), for sizes at least {FINEST_RATIO:g} times coarser; the "
             "finest run's own error makes it somewhat small (by the factor sqrt(1 - (h_f/h)^(2s)) if the error "
             "falls like h^s).", "",
             "| h | unknowns | status | last change | algebraic error | ZZ rel. | error vs finest | "
             "ZZ / error vs finest | algebraic / ZZ rel. | reference | ZZ (s) | reference (s) |",
             "|---|---:|---|---:|---:|---:|---:|---:|---:|---|---:|---:|"]
    for r in runs:
        lines.append(f"| {h_label(r['h'])} | {r['n_free']} | {r['status']} | {_e(r['last_change'])} | "
                     f"{_e(r['alg_error'])} | {_e(r['zz_rel'])} | {_e(r.get('energy_error_rel'))} | "
                     f"{_f(_ratio(r['zz_rel'], r.get('energy_error_rel')))} | "
                     f"{_e(_ratio(r['alg_error'], r['zz_rel']))} | {_ref_label(r.get('reference'))} | "
                     f"{r['zz_s']:.2f} | "
                     f"{'-' if not math.isfinite(r['reference_s']) else format(r['reference_s'], '.2f')} |")
    alg = [_ratio(r["alg_error"], r["zz_rel"]) for r in runs if math.isfinite(r["alg_error"])]
    per_change = [_ratio(r["alg_error"], r["last_change"]) for r in runs if math.isfinite(r["alg_error"])]
    lines += ["", "The iterative mode has no guaranteed bound of the algebraic error: the bound (B) of "
              "`admmkit.problems.contact.solvers.estimate` (`CondensedGap`) needs the condensed mode's "
              "C = B K^-1 B' and exact x-steps, and the last relative change is the size of the last step, not a "
              "bound on the distance to u*."]
    ok = [r["alg_error"] for r in runs if r["status"] == "converged" and math.isfinite(r["alg_error"])]
    for r in runs:
        if r["status"] != "converged":
            why = r.get("message", "").split(", but ")[-1]
            lines += ["", f"h = {h_label(r['h'])} is `{r['status']}` because {why} (the KKT check of "
                      f"`admmkit.solve`). Its algebraic error is {_e(r['alg_error'])}"
                      + (f" (the converged runs: {_e(min(ok))} to {_e(max(ok))})" if ok else "")
                      + f", its ZZ estimate {_e(r['zz_rel'])}."]
    if alg:
        lines += ["", f"The algebraic error was {min(per_change):.1f}-"
                  f"{max(per_change):.1f} times the last relative change and {min(alg):.1e}-{max(alg):.1e} times "
                  "the ZZ estimate" + (": the discretisation error dominates." if max(alg) < 0.1 else ".")]
    return lines


def _ref_label(ref) -> str:
    return "-" if not ref else ("IPM" if ref.startswith("cvxpy") else "continued")


def _f(v) -> str:
    return "-" if not math.isfinite(v) else f"{v:.2f}"


def _figure(path: Path, rows, example, mode) -> None:
    plt = pyplot()
    n = [r["n_free"] for r in rows]
    fig, (ax1, ax2, ax3, ax4) = plt.subplots(1, 4, figsize=(20, 4.4))
    for key, label, style in (("total_s", "total (assembly + setup + SADMM)", "o-"), ("solve_s", "SADMM loop", "s-"),
                              ("assemble_s", "assembly", "^-")):
        ax1.loglog(n, [r[key] for r in rows], style, label=label)
    ref = rows[-1]["total_s"]
    ax1.loglog(n, [ref * x / n[-1] for x in n], "k:", label="linear")
    ax1.axhline(TARGET_SECONDS, color="r", ls="--", lw=1, label="target 60 s")
    ax1.set_xlabel("unknowns"); ax1.set_ylabel("seconds"); ax1.set_title("wall time")
    ax2.semilogx(n, [r["iterations"] for r in rows], "o-", label="SADMM iterations")
    ax2.semilogx(n, [r.get("counters", {}).get("cg_iterations", math.nan) for r in rows], "s-",
                 label="CG iterations (all x-steps)")
    ax2.set_ylim(bottom=0); ax2.set_xlabel("unknowns"); ax2.set_title("iterations")
    ax3.loglog(n, [r["peak_rss_bytes"] / 1e9 for r in rows], "o-", label="peak RSS")
    ax3.loglog(n, [r["estimate_bytes"] / 1e9 for r in rows], "s--", label="estimate (memory check)")
    ax3.axhline(TARGET_BYTES / 1e9, color="r", ls="--", lw=1, label="target 8 GB")
    ax3.set_xlabel("unknowns"); ax3.set_ylabel("GB"); ax3.set_title("memory")
    for key, label, style in (("zz_rel", "ZZ estimate / ||u_h||", "o-"),
                              ("energy_error_rel", "energy error vs finest run", "D--"),
                              ("alg_error", "algebraic error (vs reference)", "s-"),
                              ("last_change", "last relative change (the stop)", "^:")):
        pts = [(r["n_free"], r.get(key)) for r in rows if r.get(key) is not None and math.isfinite(r[key])]
        if pts:
            ax4.loglog(*zip(*pts), style, label=label)
    ax4.set_xlabel("unknowns"); ax4.set_ylabel("relative, energy norm"); ax4.set_title("accuracy at the stop")
    for ax in (ax1, ax2, ax3, ax4):
        ax.grid(alpha=0.3, which="both")
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
    fig.suptitle(f"Example {example[-1]}, SADMM with the {mode} x-step: growth with the number of unknowns")
    fig.tight_layout()
    save_figure(fig, path)
