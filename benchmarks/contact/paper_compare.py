"""The paper side by side: our ADMM1 / ADMM2 / SADMM times and iterations beside Tables 1-2.

    admmkit bench paper-compare [--out docs/results/bench/paper] [--repeats 3] [--workers 2]

Runs the paper's grid (Examples 1-2 x ADMM1, ADMM2, SADMM x rho_0 in {1, ...,
1e4} x h in {1/10, ..., 1/40}, the paper's stopping rule) through the sweep
runner, timed as the reproduction times it (``admmkit reproduce paper``:
contact problem setup + solve, median of ``repeats``) but in CPU seconds of
the process, as the paper's tables are (wall seconds are kept in times.csv;
the machine is shared), and writes

- ``times.{md,csv}``: the paper's CPU seconds (Tables 1-2,
  ``benchmarks/data/paper_tables.json``), ours, and paper / ours;
- ``speedups.{md,csv}``: the machine-free comparison: time(ADMM1) / time(SADMM)
  and time(ADMM2) / time(SADMM) in the paper and in this run (both ratios
  within one run on one machine), and our iteration ratio;
- ``iterations.{md,csv}``: our iteration counts beside those of the committed
  reproduction (``docs/results/paper/iterations_ex*.csv``, a determinism
  check).  The paper gives iteration counts only as figures (Figs 2 and 4),
  which did not survive in its text, so there is no paper column;
- ``speedups.{png,svg}``: paper's speed-up against ours, log-log, with the diagonal.
"""
from __future__ import annotations

import csv
import statistics
import time
from pathlib import Path

from admmkit.io import write_text

from admmkit.benchmarks.runner.machine import machine_info
from admmkit.benchmarks.runner.report import NOISE_NOTE, fmt, machine_markdown, md_table, pyplot, save_figure, write_csv
from admmkit.benchmarks.runner.harness import check_harness, check_something_left, without_harness_failures
from admmkit.benchmarks.runner.sweep import Executor, finished, run_sweep

METHODS = ("admm1", "admm2", "sadmm")
LABELS = {"admm1": "ADMM1", "admm2": "ADMM2", "sadmm": "SADMM"}
REPRODUCTION = Path("docs/results/paper")


def build_cases(repeats: int = 3, hs=None, rhos=None, examples=("ex1", "ex2")) -> list[dict]:
    """The paper's grid."""
    from admmkit.benchmarks.contact.paper_data import PAPER_HS, PAPER_RHOS

    from admmkit.benchmarks.fixtures.methods import policy_version
    versions = {m: policy_version(m) for m in METHODS}
    cases = []
    for ex in examples:
        for h in hs or PAPER_HS:
            for m in METHODS:
                for rho in rhos or PAPER_RHOS:
                    cases.append({"target": "paper", "scene": ex, "h": h, "method": m, "rho": rho,
                                  "policy_version": versions[m],
                                  "repeats": repeats, "group": f"{ex}_h{h:.6g}"})
    return cases


_OPS: dict = {}


def run_case(case: dict) -> dict:
    """Worker entry point: one paper run, timed as the reproduction times it (setup + solve)."""
    from admmkit.problems.contact import assemble, example1, example2, solve_scene
    key = case["group"]
    if key not in _OPS:
        _OPS.clear()
        _OPS[key] = assemble({"ex1": example1, "ex2": example2}[case["scene"]](h=case["h"]))
    ops = _OPS[key]
    walls, cpus, sol = [], [], None
    for _ in range(case["repeats"]):
        c0, t0 = time.process_time(), time.perf_counter()
        sol = solve_scene(ops, case["method"], case["rho"])
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    r = sol.result
    return {"time": statistics.median(walls), "cpu_time": statistics.median(cpus), "times": walls,
            "iterations": r.iterations, "status": r.status.value, "rho_changes": r.rho_changes,
            "factorizations": r.factorizations, "mode": sol.mode}


def _reproduction_iterations(folder: Path) -> dict:
    out = {}
    for ex in ("ex1", "ex2"):
        path = folder / f"iterations_{ex}.csv"
        if not path.exists():
            continue
        with path.open() as fh:
            for row in csv.DictReader(fh):
                out[(row["example"], row["method"], row["h"], float(row["rho"]))] = int(row["iterations"])
    return out


def summarise(records: dict, out: Path, *, command: str, wall: float, reproduction: Path = REPRODUCTION) -> list[Path]:
    """Write the three tables, the figure and README.md."""
    from admmkit.benchmarks.contact.paper_data import paper_time
    from admmkit.benchmarks.runner.report import h_label, rho_label
    out.mkdir(parents=True, exist_ok=True)
    runs = {}
    for rec in records.values():
        c, r = rec["case"], rec.get("result")
        if r is not None:
            runs[(c["scene"], c["method"], h_label(c["h"]), float(c["rho"]))] = (c, r)
    keys = sorted({(ex, hl, rho) for ex, _, hl, rho in runs}, key=lambda k: (k[0], k[2], _h_value(k[1])))
    hs = sorted({hl for _, hl, _ in keys}, key=_h_value)

    time_rows, speed_rows, iter_rows = [], [], []
    repro = _reproduction_iterations(reproduction)
    for ex, hl, rho in keys:
        for m in METHODS:
            item = runs.get((ex, m, hl, rho))
            if item is None:
                continue
            c, r = item
            p = paper_time(ex, m, rho, c["h"])
            time_rows.append({"example": ex, "method": m, "rho": rho, "h": hl, "paper_s": p, "ours_s": r["cpu_time"],
                              "paper_over_ours": p / r["cpu_time"] if p else None, "ours_wall_s": r["time"],
                              "iterations": r["iterations"],
                              "status": r["status"], "repeats": len(r["times"])})
            rep = repro.get((ex, m, hl, rho))
            iter_rows.append({"example": ex, "method": m, "rho": rho, "h": hl, "ours": r["iterations"],
                              "reproduction": rep, "same": (rep == r["iterations"]) if rep is not None else None,
                              "paper": None})
        s = runs.get((ex, "sadmm", hl, rho))
        if s is None:
            continue
        for m in ("admm1", "admm2"):
            a = runs.get((ex, m, hl, rho))
            if a is None:
                continue
            ps, pa = paper_time(ex, "sadmm", rho, s[0]["h"]), paper_time(ex, m, rho, s[0]["h"])
            speed_rows.append({"example": ex, "method": m, "rho": rho, "h": hl,
                               "paper_speedup": pa / ps if pa and ps else None,
                               "our_speedup": a[1]["cpu_time"] / s[1]["cpu_time"],
                               "our_iteration_ratio": a[1]["iterations"] / s[1]["iterations"]})
    files = [write_csv(out / "times.csv", time_rows), write_csv(out / "speedups.csv", speed_rows),
             write_csv(out / "iterations.csv", iter_rows)]

    # times.md: one table per example, rows (method, rho), per h: paper | ours | ratio
    md = ["# Our times beside the paper's Tables 1-2", "",
          "Paper: CPU seconds of FreeFEM++ on the authors' machine (Tables 1 and 2). Ours: CPU seconds of the "
          "process for contact problem setup + admmkit.solve (boundary-condensed mode, one BLAS thread), median "
          "of the repeats, this run (the wall seconds are in times.csv). "
          "paper/ours is a machine-and-implementation ratio; see speedups.md for the ratios that compare methods.",
          "", NOISE_NOTE, ""]
    index = {(r["example"], r["method"], r["h"], r["rho"]): r for r in time_rows}
    for ex in sorted({k[0] for k in keys}):
        rhos = sorted({k[2] for k in keys if k[0] == ex})
        header = ["method", "rho_0"] + [f"h={hl} paper / ours / ratio" for hl in hs]
        body = []
        for m in METHODS:
            for rho in rhos:
                cells = [LABELS[m], rho_label(rho)]
                for hl in hs:
                    r = index.get((ex, m, hl, rho))
                    cells.append("" if r is None else f"{fmt(r['paper_s'], '.3f')} / {r['ours_s']:.4f} / "
                                 f"{fmt(r['paper_over_ours'], '.0f')}")
                body.append(cells)
        md += [f"## {'Table 1, Example 1' if ex == 'ex1' else 'Table 2, Example 2'}", "",
               md_table(header, body, "ll" + "r" * len(hs)), ""]
    write_text(out / "times.md", "\n".join(md))
    files.append(out / "times.md")

    sidx = {(r["example"], r["method"], r["h"], r["rho"]): r for r in speed_rows}
    md = ["# Speed-up of SADMM over ADMM1 and ADMM2: the paper and this run", "",
          "CPU time(ADMM) / CPU time(SADMM) at the same example, rho_0 and h: in the paper (its Tables 1-2) and "
          "here (both times from this run). Each ratio is taken within one run on one machine, so the machines cancel. "
          "The last number is our iteration ratio iterations(ADMM) / iterations(SADMM).", ""]
    for ex in sorted({k[0] for k in keys}):
        rhos = sorted({k[2] for k in keys if k[0] == ex})
        for m in ("admm1", "admm2"):
            header = ["rho_0"] + [f"h={hl} paper / ours / iter." for hl in hs]
            body = []
            for rho in rhos:
                cells = [rho_label(rho)]
                for hl in hs:
                    r = sidx.get((ex, m, hl, rho))
                    cells.append("" if r is None else f"{fmt(r['paper_speedup'], '.2f')} / {r['our_speedup']:.2f} / "
                                 f"{r['our_iteration_ratio']:.2f}")
                body.append(cells)
            md += [f"## {ex}: {LABELS[m]} / SADMM", "", md_table(header, body, "l" + "r" * len(hs)), ""]
    write_text(out / "speedups.md", "\n".join(md))
    files.append(out / "speedups.md")

    iidx = {(r["example"], r["method"], r["h"], r["rho"]): r for r in iter_rows}
    same = [r["same"] for r in iter_rows if r["same"] is not None]
    md = ["# Iteration counts: this run beside the reproduction", "",
          "The paper reports iteration counts only as figures (Figs 2 and 4, h = 1/20), which did not survive "
          "in its text (only their captions did), so there is no paper column; the paper's time ratios in "
          "speedups.md stand in for them. 'reproduction' is docs/results/paper/iterations_ex*.csv "
          f"(`admmkit reproduce paper`); {sum(same)} of {len(same)} counts are identical.", ""]
    for ex in sorted({k[0] for k in keys}):
        rhos = sorted({k[2] for k in keys if k[0] == ex})
        header = ["method", "rho_0"] + [f"h={hl} ours / repr." for hl in hs]
        body = []
        for m in METHODS:
            for rho in rhos:
                cells = [LABELS[m], rho_label(rho)]
                for hl in hs:
                    r = iidx.get((ex, m, hl, rho))
                    cells.append("" if r is None else f"{r['ours']} / {fmt(r['reproduction'], 'd')}")
                body.append(cells)
        md += [f"## {ex}", "", md_table(header, body, "ll" + "r" * len(hs)), ""]
    write_text(out / "iterations.md", "\n".join(md))
    files.append(out / "iterations.md")

    files += _figure(speed_rows, out)
    readme = ["# The paper side by side", "",
              f"Produced by `{command}`; " + (f"wall time of this invocation {wall:.0f} s." if wall is not None
                                               else "these files were rewritten from results.jsonl (--report-only)."),
              "",
              "- `times.{md,csv}`: our times beside the paper's Tables 1-2, with paper / ours",
              "- `speedups.{md,csv,png,svg}`: time(ADMM1 or ADMM2) / time(SADMM), paper against this run",
              "- `iterations.{md,csv}`: our iteration counts beside the committed reproduction", "",
              "![speed-ups](speedups.png)", "", machine_markdown(machine_info(pinned_blas=True))]
    write_text(out / "README.md", "\n".join(readme))
    files.append(out / "README.md")
    return files


def _h_value(label: str) -> float:
    if "/" in label:
        a, b = label.split("/")
        return -float(a) / float(b)
    return -float(label)


def _figure(speed_rows, out: Path) -> list[Path]:
    rows = [r for r in speed_rows if r["paper_speedup"]]
    if not rows:
        return []
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(5.6, 5.0))
    marks = {("ex1", "admm1"): ("o", "tab:blue"), ("ex1", "admm2"): ("s", "tab:cyan"),
             ("ex2", "admm1"): ("^", "tab:red"), ("ex2", "admm2"): ("v", "tab:orange")}
    for (ex, m), (marker, color) in marks.items():
        sel = [r for r in rows if r["example"] == ex and r["method"] == m]
        if sel:
            ax.scatter([r["paper_speedup"] for r in sel], [r["our_speedup"] for r in sel], marker=marker, color=color,
                       label=f"{ex} {LABELS[m]}/SADMM", s=22)
    values = [v for r in rows for v in (r["paper_speedup"], r["our_speedup"])]
    lo, hi = min(values) / 1.5, max(values) * 1.5
    ax.plot([lo, hi], [lo, hi], color="0.5", linewidth=0.8, linestyle="--", label="equal")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlim(lo, hi)
    ax.set_ylim(lo, hi)
    ax.set_xlabel("paper: time(ADMM) / time(SADMM)")
    ax.set_ylabel("this run: time(ADMM) / time(SADMM)")
    ax.set_title("Speed-up of SADMM, paper against ours\n(each point: one example, rho_0, h)", fontsize=10)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8)
    return save_figure(fig, out / "speedups")


def run(out="out/paper-compare", *, repeats: int = 3, workers: int = 2, quick: bool = False,
        progress: bool = True, command: str = "admmkit bench paper-compare",
        reproduction: Path = REPRODUCTION, report_only: bool = False,
        executor: Executor | None = None) -> list[Path]:
    """Run (or resume) the paper's grid and write the comparison (``executor``: where the cases run)."""
    out = Path(out)
    cases = build_cases(repeats=repeats, hs=(1 / 10,) if quick else None, rhos=(1.0, 1e3) if quick else None)
    t0 = time.perf_counter()
    records = finished(cases, out / "results.jsonl") if report_only else run_sweep(
                        cases, "admmkit.benchmarks.contact.paper_compare:run_case", out / "results.jsonl", workers=workers,
                        executor=executor, progress=progress, cost=lambda c: 1 / c["h"] ** 2,
                        label=lambda c: f"{c['scene']} h={c['h']:.4g} {c['method']} rho={c['rho']:g}")
    kept, failed = without_harness_failures(records)      # a harness failure is no run of a method
    check_something_left(kept, failed, len(cases), out / "results.jsonl", report_only)
    files = summarise(kept, out, command=command, wall=None if report_only else time.perf_counter() - t0,
                      reproduction=reproduction)
    check_harness(failed, len(cases), files, left_out="left out of the comparison")
    return files

