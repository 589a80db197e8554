"""Stability: where each method converges, and how it fails, on the paper's contact examples.

    admmkit bench stability [--out docs/results/bench/stability] [--quick] [--workers 2]

Two sweeps, every ADMM method (:mod:`admmkit.benchmarks.rules.methods`), each run
stopped by the paper's rule ||u^{k+1} - u^k||_K <= 1e-5 ||u^{k+1}||_K or the cap
of 20000 iterations:

1. ``rho``: rho_0 = s E for s = 1e-6 ... 1e6 (13 decades), Examples 1 and 2, h = 1/40, P1.
2. ``mesh``: rho_0 = E, h = 1/10 ... 1/160, nu in {0.3, 0.49, 0.499}, P1 and P2, both examples.

Each run ends as one *outcome*: ``converged`` (the rule fired and the true
error is at most 1e-3), ``false_convergence`` (the rule fired while the true
error ||u - u*||_K / ||u*||_K was still above 1e-3), ``max_iter``,
``diverged``, ``stalled`` or ``time_limit``.  u* is the reference solution of
the same discrete problem (:mod:`admmkit.benchmarks.rules.families`).

Written to ``out``: ``results.jsonl`` (resumable raw records),
``stability.csv``, ``failures.md`` (which methods failed where),
``rho_sweep.{png,svg}`` and ``mesh_sweep.{png,svg}`` (iterations as heat-maps
with the failures marked), ``mesh_error.{png,svg}`` (error at the stop) and
``README.md``.
"""
from __future__ import annotations

import math
import os
import time
from pathlib import Path

import numpy as np

from admmkit.io import write_text

from admmkit.benchmarks.rules import methods as methods_mod
from admmkit.benchmarks.runner.report import NOISE_NOTE, fmt, machine_info, machine_markdown, md_table, pyplot, save_figure, write_csv
from admmkit.benchmarks.rules.families import CACHE_ENV, discrete, problem_key
from admmkit.benchmarks.runner.sweep import Executor, clean_float, run_or_report

RHO_SCALES = tuple(10.0 ** k for k in range(-6, 7))
RHO_H = 1 / 40
MESH_HS = (1 / 10, 1 / 20, 1 / 40, 1 / 80, 1 / 160)
NUS = (0.3, 0.49, 0.499)
ORDERS_P = (1, 2)
TOL = 1e-5
MAX_ITER = 20_000
FALSE_CONVERGENCE_ERROR = 1e-3
#: the PDAS reference is cross-checked by Clarabel up to this many unknowns (stability runs only)
CROSS_CHECK_MAX = 50_000
OUTCOMES = ("converged", "false_convergence", "max_iter", "diverged", "stalled", "time_limit")
MARKS = {"false_convergence": "F", "max_iter": "M", "diverged": "D", "stalled": "S", "time_limit": "T"}


def build_cases(admm: list[str], *, examples=("ex1", "ex2"), rho_scales=RHO_SCALES, rho_h=RHO_H, mesh_hs=MESH_HS,
                nus=NUS, orders=ORDERS_P, max_iter: int = MAX_ITER, time_limit: float = 60.0) -> list[dict]:
    """The cases of both sweeps."""
    cases = []
    versions = {m: methods_mod.policy_version(m) for m in admm}
    common = {"target": "stability", "tol": TOL, "max_iter": max_iter, "time_limit": time_limit}
    for ex in examples:
        base = {"scene": ex, "h": rho_h, "nu": None, "p": None}
        for s in rho_scales:
            for m in admm:
                cases.append(common | base | {"sweep": "rho", "method": m, "rho_scale": s,
                                              "policy_version": versions[m],
                                              "group": problem_key(base)})
    for ex in examples:
        for p in orders:
            for nu in nus:
                for h in mesh_hs:
                    base = {"scene": ex, "h": h, "nu": nu, "p": p}
                    for m in admm:
                        cases.append(common | base | {"sweep": "mesh", "method": m, "rho_scale": 1.0,
                                                      "policy_version": versions[m],
                                                      "group": problem_key(base)})
    return cases


def case_cost(case: dict) -> float:
    """Rough relative cost of a case's group share (P2 has four times the unknowns; a rho-sweep problem
    is shared by 13 rho_0 values, so it is counted once per rho_0 and runs early)."""
    share = len(RHO_SCALES) if case.get("sweep") == "rho" else 1
    return (4.0 if case.get("p") == 2 else 1.0) / case["h"] ** 2 / share


_PROBLEMS: dict[str, object] = {}


def run_case(case: dict) -> dict:
    """Worker entry point: one method, one rho_0, one discrete problem, the paper's stopping rule."""
    from admmkit.benchmarks.rules.admm_runs import paper_rule_run
    d = discrete(case, cache_dir=os.environ.get(CACHE_ENV), cross_check_max=CROSS_CHECK_MAX)
    if d.key not in _PROBLEMS:
        _PROBLEMS.clear()
        _PROBLEMS[d.key] = d.make_admm()
    problem = _PROBLEMS[d.key]
    cache = getattr(problem, "_cholesky", None)
    if isinstance(cache, dict):
        cache.clear()      # memory: dense factorisations per rho of the condensed mode (iterates are unchanged)
    rho0 = case["rho_scale"] * d.rho_unit
    t0 = time.perf_counter()
    res = paper_rule_run(problem, case["method"], rho0, tol=case["tol"], max_iter=case["max_iter"],
                         time_limit=case["time_limit"])
    seconds = time.perf_counter() - t0
    out = {"status": res.status.value, "iterations": res.iterations, "stopped_by": res.stopped_by,
           "final_rho": clean_float(res.rho), "rho_changes": res.rho_changes, "seconds": seconds,
           "rho0": rho0, "n_free": d.n, "n_c": d.info.get("n_c"), "E": d.rho_unit, "reference": d.ref_info}
    if res.status.value != "diverged" and np.all(np.isfinite(res.x)):
        errs = d.errors(res.x, res.lam)
        out["err"] = clean_float(errs["err"])
        out["err_lam"] = clean_float(errs.get("err_lam"))
    out["outcome"] = outcome(out)
    return out


def outcome(result: dict) -> str:
    """converged / false_convergence / the failing status (see the module docstring)."""
    status = result["status"]
    if status == "converged":
        err = result.get("err")
        return "false_convergence" if err is None or err > FALSE_CONVERGENCE_ERROR else "converged"
    return status if status in OUTCOMES else "diverged"


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
    lines.append(machine_markdown(machine_info()))
    write_text(out / "README.md", "\n".join(lines))
    files.append(out / "README.md")
    return files


def run(out="out/stability", *, quick: bool = False, workers: int = 2, methods=None,
        progress: bool = True, command: str = "admmkit bench stability", report_only: bool = False,
        executor: Executor | None = None, **grid) -> list[Path]:
    """Build the cases, run (or resume) the sweep, write the summaries (``executor``: where the cases run)."""
    out = Path(out)
    admm = list(methods) if methods is not None else methods_mod.admm_methods()
    if quick:
        grid = {"rho_scales": (1e-3, 1.0, 1e3), "rho_h": 1 / 10, "mesh_hs": (1 / 10,), "nus": (0.3,),
                "orders": (1,), "max_iter": 2000} | grid
    cases = build_cases(admm, **grid)
    records, wall = run_or_report(cases, "admmkit.benchmarks.rules.stability:run_case", out, report_only=report_only,
                                  env={CACHE_ENV: str(out / "cache")}, workers=workers, executor=executor,
                                  progress=progress, cost=case_cost,
                                  label=lambda c: (f"{c['sweep']} {c['scene']} h={_h_label(c['h'])} nu={c['nu']} "
                                                   f"P{c['p']} s={c['rho_scale']:g} {c['method']}"))
    return summarise(records, out, command=command, wall=wall,
                     skipped=methods_mod.skipped_policies(), missing=len(cases) - len(records))
