"""The stability study's summary: the outcomes per case, heatmaps over rho_0 and the mesh, the failures and the tables (admmkit bench stability)."""
from __future__ import annotations

import math
from pathlib import Path
import numpy as np
from admmkit.io import write_text
from admmkit.benchmarks.fixtures import methods as methods_mod
from admmkit.benchmarks.runner.machine import machine_info
from admmkit.benchmarks.runner.report import NOISE_NOTE, fmt, machine_markdown, md_table, pyplot, save_figure, write_csv
from admmkit.benchmarks.fixtures.families import problem_key

MAX_ITER = 20_000
FALSE_CONVERGENCE_ERROR = 1e-3
OUTCOMES = ("converged", "false_convergence", "max_iter", "diverged", "stalled", "time_limit")
MARKS = {"false_convergence": "F", "max_iter": "M", "diverged": "D", "stalled": "S", "time_limit": "T"}


# ---------------------------------------------------------------- summaries
def _rows(records) -> list[dict]:
    rows = []
    for rec in records.values():
        case, res = rec["case"], rec.get("result")
        row = {k: case.get(k) for k in ("sweep", "scene", "h", "nu", "p", "method", "rho_scale")}
        if res is None:
            row.update(outcome="error", error=(rec.get("error") or "").splitlines()[0])
        else:
            row.update({k: res.get(k) for k in ("outcome", "status", "iterations", "err", "err_lam", "rho0",
                                                "final_rho", "rho_changes", "seconds", "n_free", "n_c", "stopped_by")})
        rows.append(row)
    return rows


def _heatmap(ax, grid_iter, grid_out, row_labels, col_labels, title, value_label="iterations", log=True,
             vmin=None, vmax=None):
    """Colour = log10(value) with the value written in the cell; failures hatched grey with a letter
    (M max_iter, D diverged, S stalled, T time limit); false convergence: the value's colour, a red box and "F"."""
    plt = pyplot()
    values = np.array([[np.nan if v is None else v for v in row] for row in grid_iter], dtype=float)
    shown = np.log10(np.maximum(values, 1e-300)) if log else values
    cmap = plt.get_cmap("viridis").with_extremes(bad="0.85")
    im = ax.imshow(np.ma.masked_invalid(shown), aspect="auto", cmap=cmap, vmin=vmin, vmax=vmax, interpolation="nearest")
    norm = im.norm
    for i in range(values.shape[0]):
        for j in range(values.shape[1]):
            out, v = grid_out[i][j], values[i, j]
            dark = np.isfinite(shown[i, j]) and norm(shown[i, j]) < 0.55          # viridis: white text on the dark half
            if out in MARKS and out != "false_convergence":
                ax.add_patch(plt.Rectangle((j - 0.5, i - 0.5), 1, 1, facecolor="0.82", edgecolor="0.55",
                                           hatch="///", linewidth=0.3))
                ax.text(j, i, MARKS[out], ha="center", va="center", fontsize=9, color="black", fontweight="bold")
            elif out == "false_convergence":
                ax.add_patch(plt.Rectangle((j - 0.44, i - 0.42), 0.88, 0.84, fill=False, edgecolor="red", linewidth=1.6))
                text = "F" if not np.isfinite(v) or value_label != "iterations" else f"F{int(v)}"
                ax.text(j, i, text, ha="center", va="center", fontsize=7.5, fontweight="bold",
                        color="white" if dark else "black")
            elif out is None:
                ax.text(j, i, "?", ha="center", va="center", fontsize=8, color="0.4")
            elif np.isfinite(v) and value_label == "iterations":
                ax.text(j, i, f"{int(v)}", ha="center", va="center", fontsize=7.5, color="white" if dark else "black")
            elif np.isfinite(v):
                mantissa, exponent = f"{v:.0e}".split("e")
                ax.text(j, i, f"{mantissa}e{int(exponent)}", ha="center", va="center", fontsize=7.5,
                        color="white" if dark else "black")
    ax.set_yticks(range(len(row_labels)))
    ax.set_yticklabels(row_labels, fontsize=9)
    ax.set_xticks(range(len(col_labels)))
    ax.set_xticklabels(col_labels, fontsize=9)
    ax.tick_params(length=2)
    ax.set_title(title, fontsize=10.5)
    return im


def _legend_text(what: str = "iterations") -> str:
    return ("Cells: " + ("iterations to the paper's rule" if what == "iterations" else
                         "the true error ||u - u*||_K / ||u*||_K at the stop (colour: its log10)") +
            ". Red box F: false convergence (the rule fired with a true error > 1e-3). "
            "Grey hatched: a failure, M = 20 000 iterations reached, D = diverged, S = stalled, T = time limit.")


def _method_order(rows) -> list[str]:
    seen = {r["method"] for r in rows}
    admm = methods_mod.admm_methods()
    return [m for m in admm if m in seen] + sorted(seen - set(admm))


def _rho_label(s: float) -> str:
    e = math.log10(s)
    return f"1e{round(e)}" if abs(e - round(e)) < 1e-9 else f"{s:g}"


def _h_label(h: float) -> str:
    from admmkit.benchmarks.runner.report import h_label
    return h_label(h)


def figure_rho(rows, out: Path) -> list[Path]:
    """Heat maps of iterations against rho_0/E, one panel per example, stacked (readable at the docs' page width)."""
    plt = pyplot()
    rho_rows = [r for r in rows if r["sweep"] == "rho"]
    if not rho_rows:
        return []
    examples = sorted({r["scene"] for r in rho_rows})
    scales = sorted({r["rho_scale"] for r in rho_rows})
    meths = _method_order(rho_rows)
    fig, axes = plt.subplots(len(examples), 1, figsize=(10, (0.3 * len(meths) + 1.3) * len(examples) + 1.4),
                             squeeze=False)
    index = {(r["scene"], r["method"], r["rho_scale"]): r for r in rho_rows}
    im = None
    for ax, ex in zip(axes[:, 0], examples):
        it = [[(index.get((ex, m, s)) or {}).get("iterations") for s in scales] for m in meths]
        oc = [[(index.get((ex, m, s)) or {}).get("outcome") for s in scales] for m in meths]
        im = _heatmap(ax, it, oc, meths, [_rho_label(s) for s in scales],
                      f"{ex}, h = {_h_label(rho_rows[0]['h'])}, P1: iterations against rho_0 / E",
                      vmin=0, vmax=math.log10(MAX_ITER))
        ax.set_xlabel("rho_0 / E", fontsize=10)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    cax = fig.add_axes((0.3, 0.035, 0.4, 0.012))
    cb = fig.colorbar(im, cax=cax, orientation="horizontal")
    cb.set_label("log10 iterations", fontsize=9)
    fig.text(0.01, 0.0, _legend_text(), fontsize=8, va="top", wrap=True)
    return save_figure(fig, out / "rho_sweep")


def figure_mesh(rows, out: Path, what: str = "iterations") -> list[Path]:
    """Heat maps over (nu, h) for each (example, P), stacked: iterations or the error at the stop."""
    plt = pyplot()
    mesh_rows = [r for r in rows if r["sweep"] == "mesh"]
    if not mesh_rows:
        return []
    panels = sorted({(r["scene"], r["p"]) for r in mesh_rows})
    cols = [(nu, -mh) for nu, mh in sorted({(r["nu"], -r["h"]) for r in mesh_rows})]
    meths = _method_order(mesh_rows)
    fig, axes = plt.subplots(len(panels), 1, figsize=(10, (0.27 * len(meths) + 1.5) * len(panels) + 1.2),
                             squeeze=False)
    index = {(r["scene"], r["p"], r["method"], r["nu"], r["h"]): r for r in mesh_rows}
    im = None
    for ax, (ex, p) in zip(axes[:, 0], panels):
        vals = [[(index.get((ex, p, m, nu, h)) or {}).get("iterations" if what == "iterations" else "err")
                 for nu, h in cols] for m in meths]
        oc = [[(index.get((ex, p, m, nu, h)) or {}).get("outcome") for nu, h in cols] for m in meths]
        labels = [_h_label(h) for _, h in cols]
        if what == "iterations":
            im = _heatmap(ax, vals, oc, meths, labels, f"{ex}, P{p}, rho_0 = E: iterations",
                          vmin=0, vmax=math.log10(MAX_ITER))
        else:
            im = _heatmap(ax, vals, oc, meths, labels, f"{ex}, P{p}, rho_0 = E: true error at the stop",
                          value_label="error", vmin=-10, vmax=0)
        nus = [nu for nu, _ in cols]
        for nu in sorted(set(nus)):                 # the nu groups: a white rule between, the value above
            js = [j for j, v in enumerate(nus) if v == nu]
            ax.text((js[0] + js[-1]) / 2, -0.75, f"nu = {nu:g}", ha="center", va="bottom", fontsize=9)
            if js[0] > 0:
                ax.axvline(js[0] - 0.5, color="white", linewidth=2.5)
        ax.set_xlabel("mesh size h (grouped by nu)", fontsize=10)
        ax.set_title(ax.get_title(), fontsize=10.5, pad=17)
    fig.tight_layout(rect=(0, 0.045, 1, 1), h_pad=1.5)
    cax = fig.add_axes((0.3, 0.025, 0.4, 0.008))
    cb = fig.colorbar(im, cax=cax, orientation="horizontal")
    cb.set_label("log10 iterations" if what == "iterations" else "log10 ||u - u*||_K / ||u*||_K", fontsize=9)
    fig.text(0.01, 0.0, _legend_text(what), fontsize=8, va="top", wrap=True)
    return save_figure(fig, out / ("mesh_sweep" if what == "iterations" else "mesh_error"))


def failures_md(rows) -> str:
    """Which methods failed where: counts per outcome, then the list of failing cases per method."""
    meths = _method_order(rows)
    lines = ["# Which methods failed where", "",
             "Outcome of every run of the stability sweeps (the paper's stopping rule, relative change 1e-5 in the "
             f"energy norm, at most {MAX_ITER} iterations). false_convergence = the rule fired while the true error "
             f"||u - u*||_K / ||u*||_K was above {FALSE_CONVERGENCE_ERROR:g}.", ""]
    body = []
    for m in meths:
        mine = [r for r in rows if r["method"] == m]
        counts = [sum(1 for r in mine if r["outcome"] == o) for o in OUTCOMES]
        body.append([m, str(len(mine))] + [str(c) if c else "" for c in counts]
                    + [str(sum(1 for r in mine if r["outcome"] == "error") or "")])
    lines += [md_table(["method", "runs"] + list(OUTCOMES) + ["error"], body), ""]
    lines += ["## Failing runs by method", ""]
    for m in meths:
        bad = [r for r in rows if r["method"] == m and r["outcome"] != "converged"]
        if not bad:
            lines.append(f"- **{m}**: no failure")
            continue
        parts = []
        for r in sorted(bad, key=lambda r: (r["sweep"], r["scene"], r.get("p") or 0, r.get("nu") or 0, -r["h"],
                                            r["rho_scale"])):
            where = (f"{r['scene']} rho0/E={_rho_label(r['rho_scale'])}" if r["sweep"] == "rho"
                     else f"{r['scene']} P{r['p']} nu={r['nu']:g} h={_h_label(r['h'])}")
            extra = f" (err {r['err']:.1e})" if r.get("err") is not None else ""
            parts.append(f"{where}: {r['outcome']}{extra}")
        lines.append(f"- **{m}** ({len(bad)}): " + "; ".join(parts))
    return "\n".join(lines) + "\n"


def mesh_table(rows) -> str:
    """Iterations / error at the stop of the mesh sweep, one table per example and P."""
    mesh_rows = [r for r in rows if r["sweep"] == "mesh"]
    meths = _method_order(mesh_rows)
    out = []
    for ex, p in sorted({(r["scene"], r["p"]) for r in mesh_rows}):
        cols = sorted({(r["nu"], r["h"]) for r in mesh_rows if r["scene"] == ex and r["p"] == p},
                      key=lambda c: (c[0], -c[1]))
        index = {(r["method"], r["nu"], r["h"]): r for r in mesh_rows if r["scene"] == ex and r["p"] == p}
        body = []
        for m in meths:
            cells = [m]
            for nu, h in cols:
                r = index.get((m, nu, h))
                if r is None:
                    cells.append("")
                else:
                    mark = "" if r["outcome"] == "converged" else f" {MARKS.get(r['outcome'], r['outcome'])}"
                    cells.append(f"{r.get('iterations', '')}{mark} / {fmt(r.get('err'), '.1e')}")
            body.append(cells)
        out += [f"### {ex}, P{p} (iterations / error at the stop)", "",
                md_table(["method"] + [f"nu={nu:g} h={_h_label(h)}" for nu, h in cols], body), ""]
    return "\n".join(out)


def summarise(records, out: Path, *, command: str, wall: float, skipped, missing: int = 0) -> list[Path]:
    """Write stability.csv, failures.md, the figures and README.md."""
    out.mkdir(parents=True, exist_ok=True)
    rows = _rows(records)
    files = [write_csv(out / "stability.csv", rows)]
    write_text(out / "failures.md", failures_md(rows))
    files.append(out / "failures.md")
    files += figure_rho(rows, out)
    files += figure_mesh(rows, out, "iterations")
    files += figure_mesh(rows, out, "error")
    refs = {}
    for rec in records.values():
        res = rec.get("result") or {}
        c = rec["case"]
        refs.setdefault(problem_key(c), (res.get("reference"), res.get("n_free"), res.get("n_c")))
    lines = ["# Stability: where the methods converge and how they fail", "",
             f"Produced by `{command}`; " + (f"wall time of this invocation {wall:.0f} s." if wall is not None
                                              else "these files were rewritten from results.jsonl (--report-only)."),
             "",
             "- every ADMM method (every registered policy in both orders; admm1 = fixed/xz, admm2 = fixed/zx, "
             "sadmm = summable/zx), each run stopped by the paper's rule ||u^{k+1} - u^k||_K <= 1e-5 ||u^{k+1}||_K "
             f"or after {MAX_ITER} iterations; contact problems in the boundary-condensed mode.",
             "- rho sweep: rho_0 = s E, s = 1e-6 ... 1e6, Examples 1 and 2, h = 1/40, P1: `rho_sweep.png`.",
             "- mesh sweep: rho_0 = E, h = 1/10 ... 1/160, nu in {0.3, 0.49, 0.499}, P1 and P2: `mesh_sweep.png` "
             "(iterations), `mesh_error.png` (true error at the stop) and the tables below.",
             "- true error: ||u - u*||_K / ||u*||_K against the primal-dual active set solution of the same "
             "discrete problem (KKT-verified; cross-checked by cvxpy + Clarabel up to 50000 unknowns, "
             "see stability.csv / results.jsonl for the differences).",
             f"- outcome: false_convergence when the rule fired with true error > {FALSE_CONVERGENCE_ERROR:g} (F, red "
             "box in the figures); M = max_iter, D = diverged, S = stalled, T = time limit (60 s wall).",
             "", "Iteration counts are deterministic; the seconds in stability.csv are noisy. " + NOISE_NOTE, "",
             "![rho sweep](rho_sweep.png)", "", "![mesh sweep](mesh_sweep.png)", "", "![error at the stop](mesh_error.png)",
             "", "## Mesh sweep tables", "", mesh_table(rows), "## Reference solutions", ""]
    body = []
    for key, (ref, n, nc) in sorted(refs.items()):
        ref = ref or {}
        cc = ref.get("cross_check") or {}
        diffs = ", ".join(f"{k} {v:.1e}" for k, v in cc.items() if k != "other" and isinstance(v, float))
        kkt = max((v for v in (ref.get("kkt") or {}).values()), default=float("nan"))
        body.append([key, str(n), str(nc), ref.get("solver", ""), fmt(kkt, ".1e"),
                     cc.get("other", "") + (": " + diffs if diffs else "")])
    lines += [md_table(["problem", "n_free", "n_c", "reference", "max KKT residual", "cross-check"], body, "lrrlll"), ""]
    if skipped:
        lines += [f"Policies left out (they need constructor arguments): {', '.join(skipped)}.", ""]
    if missing:
        lines.insert(3, f"**{missing} cases of the sweep had not finished when these files were written "
                        "(--report-only); they are blank ('?') in the figures and missing from the tables.**\n")
    lines.append(machine_markdown(machine_info(pinned_blas=True)))
    write_text(out / "README.md", "\n".join(lines))
    files.append(out / "README.md")
    return files
