"""The reproduction's tables and README: Tables 1-2 with the paper's figures beside ours, iterations, errors."""
from __future__ import annotations

import csv
import datetime
from pathlib import Path

from admmkit.io import atomic_open, write_text

from admmkit.benchmarks.runner.machine import machine_info
from admmkit.benchmarks.contact.paper_data import MAGNIFY, Run, paper_time
from admmkit.policies.paper_methods import LABELS as METHOD_LABELS
from admmkit.benchmarks.runner.report import h_label, rho_label


def _find(runs, ex, h, m, rho) -> Run | None:
    for r in runs:
        if r.example == ex and r.h == h and r.method == m and r.rho == rho:
            return r
    return None


def _md_table(header: list[list[str]], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header[0]) + " |", "|" + "|".join("---:" for _ in header[0]) + "|"]
    for extra in header[1:]:
        lines.append("| " + " | ".join(extra) + " |")
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def _grid(runs, ex, hs, rhos, methods, cell) -> str:
    head = ["rho"] + [f"{METHOD_LABELS[m]} h={h_label(h)}" for m in methods for h in hs]
    rows = []
    for rho in rhos:
        row = [rho_label(rho)]
        for m in methods:
            for h in hs:
                row.append(cell(_find(runs, ex, h, m, rho), m, rho, h))
        rows.append(row)
    return _md_table([head], rows)


def _status_mark(r: Run) -> str:
    return "" if r.status == "converged" else f" ({r.status})"


def write_time_table(base: Path, runs, ex, hs, rhos, methods) -> list[Path]:
    """Table 1 / 2: our seconds, the paper's, and paper / ours."""
    label = "Table 1 (Example 1, g = 0.01)" if ex == "ex1" else "Table 2 (Example 2)"

    def ours(r, m, rho, h):
        return "-" if r is None else f"{r.time:.3f}{_status_mark(r)}"

    def paper(r, m, rho, h):
        p = paper_time(ex, m, rho, h)
        return "-" if p is None else f"{p:.3f}"

    def ratio(r, m, rho, h):
        p = paper_time(ex, m, rho, h)
        return "-" if (p is None or r is None or r.time <= 0) else f"{p / r.time:.0f}"

    def mode_of(r, m, rho, h):
        return "-" if r is None else r.mode

    text = [f"# {label}: time of the three methods", "",
            "Seconds of problem setup + solve per run (wall clock; the condensed mode's setup, one sparse "
            "factorisation of K and the boundary Schur complement, is paid by every run), "
            "paper's stopping rule ||u^{k+1}-u^k||_K <= 1e-5 ||u^{k+1}||_K, max 20000 iterations. "
            "The paper's figures are FreeFEM++ CPU seconds on the authors' machine "
            "(seed text, section 4). A status other than converged is marked.", "",
            "## Ours (s)", "", _grid(runs, ex, hs, rhos, methods, ours), "",
            "## Paper (s)", "", _grid(runs, ex, hs, rhos, methods, paper), "",
            "## Ratio paper / ours", "", _grid(runs, ex, hs, rhos, methods, ratio), ""]
    modes = sorted({r.mode for r in runs if r.example == ex})
    text += [f"Mode used: {', '.join(modes)}.", ""]
    md = base.with_suffix(".md")
    write_text(md, "\n".join(text))
    csv_path = base.with_suffix(".csv")
    with atomic_open(csv_path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["example", "method", "h", "rho", "iterations", "status", "time_s", "cpu_s", "setup_s",
                    "solve_s", "paper_s", "paper_over_ours", "mode", "factorizations", "rho_changes", "final_rho"])
        for m in methods:
            for h in hs:
                for rho in rhos:
                    r = _find(runs, ex, h, m, rho)
                    if r is None:
                        continue
                    p = paper_time(ex, m, rho, h)
                    w.writerow([ex, m, h_label(h), f"{rho:g}", r.iterations, r.status, f"{r.time:.6f}",
                                f"{r.cpu_time:.6f}", f"{r.setup_time:.6f}", f"{r.solve_time:.6f}",
                                "" if p is None else p, "" if p is None else f"{p / r.time:.2f}",
                                r.mode, r.factorizations, r.rho_changes, f"{r.final_rho:.6g}"])
    return [md, csv_path]


def write_iteration_table(base: Path, runs, ex, hs, rhos, methods) -> list[Path]:
    """Iteration counts, same shape as the time tables."""
    def cell(r, m, rho, h):
        return "-" if r is None else f"{r.iterations}{_status_mark(r)}"

    def fac(r, m, rho, h):
        return "-" if r is None else f"{r.rho_changes}/{r.factorizations}"

    text = [f"# Iterations, {'Example 1' if ex == 'ex1' else 'Example 2'}", "",
            "Iterations to the paper's stopping rule (||u^{k+1}-u^k||_K <= 1e-5 ||u^{k+1}||_K), max 20000. "
            "The paper gives iteration counts only as figures (Figs 2 and 4, h = 1/20), which did not "
            "survive in the text.", "",
            _grid(runs, ex, hs, rhos, methods, cell), "",
            "## rho changes / factorisations", "", _grid(runs, ex, hs, rhos, methods, fac), ""]
    md = base.with_suffix(".md")
    write_text(md, "\n".join(text))
    csv_path = base.with_suffix(".csv")
    with atomic_open(csv_path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["example", "method", "h", "rho", "iterations", "status", "rho_changes", "factorizations",
                    "final_rho"])
        for m in methods:
            for h in hs:
                for rho in rhos:
                    r = _find(runs, ex, h, m, rho)
                    if r is not None:
                        w.writerow([ex, m, h_label(h), f"{rho:g}", r.iterations, r.status, r.rho_changes,
                                    r.factorizations, f"{r.final_rho:.6g}"])
    return [md, csv_path]


KKT_KEYS = ("stationarity", "penetration", "negative_pressure", "complementarity")


def write_error_table(base: Path, runs, refs) -> list[Path]:
    """The true error at the stop of every run, and the KKT residuals."""
    head = ["example", "h", "method", "rho", "iterations", "status", "err u (energy)", "err lam (M_c)",
            *KKT_KEYS, "contact force"]
    rows, csv_rows = [], []
    for r in runs:
        kkt = [r.kkt.get(k, float("nan")) for k in KKT_KEYS]
        rows.append([r.example, h_label(r.h), METHOD_LABELS[r.method], rho_label(r.rho), str(r.iterations),
                     r.status, f"{r.errors['err_u_energy']:.2e}", f"{r.errors['err_lam']:.2e}",
                     *(f"{v:.1e}" for v in kkt), f"{r.kkt.get('contact_force', float('nan')):.6g}"])
        csv_rows.append([r.example, h_label(r.h), r.method, f"{r.rho:g}", r.iterations, r.status,
                         f"{r.errors['err_u_energy']:.6e}", f"{r.errors['err_lam']:.6e}",
                         *(f"{v:.6e}" for v in kkt), f"{r.kkt.get('contact_force', float('nan')):.10g}"])
    ref_rows = []
    for (ex, h), ref in refs.items():
        cc = ref.cross_check
        ref_rows.append([ex, h_label(h), ref.solver, f"{ref.seconds:.2f}",
                         *(f"{ref.kkt[k]:.1e}" for k in KKT_KEYS), f"{ref.kkt['contact_force']:.10g}",
                         f"{cc['u_energy_rel_diff']:.1e}" if cc else "-", f"{cc['lam_rel_diff']:.1e}" if cc else "-"])
    text = ["# True error at the stop", "",
            "For every run: the relative error of the displacement in the energy norm, "
            "sqrt(e'Ke)/sqrt(u*'Ku*) with e = u - u*, and of the contact pressure in the M_c norm, "
            "||lam - lam*||_Mc / ||lam*||_Mc, against a reference solution u*, lam* of the same discrete "
            "problem (min 1/2 u'Ku - f'u s.t. Bu <= g) computed once per mesh; and the KKT residuals at "
            "the stop: stationarity ||Ku - f + B'M_c lam||_inf/||f||_inf, penetration max(Bu - g)^+, "
            "negative pressure max(-lam)^+, complementarity max|lam (g - Bu)|.", "",
            "## Reference solutions", "",
            "`diff u` / `diff lam`: relative difference between the reference and an independent SADMM run "
            "to Boyd residuals <= 1e-12 (how accurate the reference is).", "",
            _md_table([["example", "h", "solver", "seconds", *KKT_KEYS, "contact force", "diff u", "diff lam"]],
                      ref_rows), "",
            "## Every run", "", _md_table([head], rows), ""]
    md = base.with_suffix(".md")
    write_text(md, "\n".join(text))
    csv_path = base.with_suffix(".csv")
    with atomic_open(csv_path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["example", "h", "method", "rho", "iterations", "status", "err_u_energy", "err_lam",
                    *KKT_KEYS, "contact_force"])
        w.writerows(csv_rows)
    return [md, csv_path]


def write_readme(out: Path, runs, refs, files, wall, hs, rhos, h_fig, h_fine, rho_fig, repeats, mode,
                 command, blas_threads=1) -> Path:
    """README.md: what each file is, the command, the machine, the wall time."""
    info = machine_info()
    desc = {
        "table1_ex1_time": "Example 1 times (setup + solve) shaped like the paper's Table 1, with the paper's "
                           "CPU seconds and the ratio paper / ours",
        "table2_ex2_time": "Example 2 times shaped like the paper's Table 2, with the paper's figures and the ratio",
        "iterations_ex1": "Example 1 iteration counts (and rho changes / factorisations), same shape",
        "iterations_ex2": "Example 2 iteration counts, same shape",
        "error_at_stop": "true error at the stop of every run (energy-norm error of u, M_c error of lam) "
                         "against a tight reference of the same discrete problem, and the KKT residuals",
        "fig1_deformed_ex1": f"the paper's Fig. 1: Example 1 deformed body (u x{MAGNIFY['ex1']:g}) and the obstacle "
                             f"y = -g(x) (scaled like u), SADMM rho_0 = {rho_label(rho_fig)}, h = {h_label(h_fine)}",
        "fig3_deformed_ex2": f"the paper's Fig. 3: Example 2 deformed body (u x{MAGNIFY['ex2']:g}) and the obstacle, "
                             f"SADMM, h = {h_label(h_fine)}",
        "fig2_iterations_ex1": f"the paper's Fig. 2: Example 1 iterations against rho_0, h = {h_label(h_fig)}",
        "fig4_iterations_ex2": f"the paper's Fig. 4: Example 2 iterations against rho_0, h = {h_label(h_fig)}",
        "pressure_gap_ex1": f"Example 1 contact pressure lam and gap g - u_n along Gamma_C, SADMM, h = {h_label(h_fine)}",
        "pressure_gap_ex2": f"Example 2 contact pressure lam and gap g - u_n along Gamma_C, SADMM, h = {h_label(h_fine)}",
    }
    by_stem: dict[str, list[str]] = {}
    for f in files:
        by_stem.setdefault(Path(f).stem, []).append(Path(f).suffix.lstrip("."))
    lines = ["# Reproduction of the paper's section 4 (Tables 1-2, Figs 1-4)", "",
             f"Produced by `{command}` on {datetime.date.today().isoformat()}.", "",
             f"- examples: {', '.join(sorted({r.example for r in runs}))}; methods ADMM1 (order xz, fixed rho), "
             "ADMM2 (order zx, fixed rho), SADMM (order zx, summable rule tau = 2, c_max = 100)",
             f"- h in {{{', '.join(h_label(h) for h in hs)}}}, rho_0 in {{{', '.join(rho_label(r) for r in rhos)}}}; "
             f"{len(runs)} runs, {repeats} repeat(s) each (median time)",
             "- stopping rule: the paper's ||u^{k+1}-u^k||_K <= 1e-5 ||u^{k+1}||_K (energy norm), max 20000 iterations",
             f"- mode: {mode} (chosen: {', '.join(sorted({r.mode for r in runs}))}); operators assembled once per "
             "(example, h); each run builds a fresh contact problem, and its time is setup + solve; "
             f"BLAS threads pinned to {blas_threads} (threadpoolctl)",
             "- reference solution per mesh: see error_at_stop.md (assembly and reference solves are not timed)",
             f"- total wall time of the reproduction: {wall:.1f} s", "",
             "## Files", ""]
    for stem, exts in by_stem.items():
        lines.append(f"- `{stem}.{{{','.join(exts)}}}`: {desc.get(stem, '')}")
    lines += ["", "## Machine", ""] + [f"- {k}: {v}" for k, v in info.items()]
    lines += ["", "Other processes may share the machine; times of a few milliseconds are noisy.", ""]
    path = out / "README.md"
    write_text(path, "\n".join(lines))
    return path
