"""``admmkit bench amg-crossover``: when the iterative x-step beats the direct ones, and when to reuse AMG.

Two measurements, written to ``amg_crossover.md`` (and ``.csv``, ``amg_crossover.png/svg``):

1. **Modes against size.**  Example 1 at each h, SADMM (rho_0 = 1e3, the paper's
   rule) in the modes full (sparse factorisation per rho), condensed (one
   factorisation, dense x-steps on Gamma_C) and iterative (AMG-CG), each run
   in its own process; the time compared is setup + SADMM (the assembly is
   the same for all).  The crossover is the smallest size at which the
   iterative mode is the fastest.
2. **Hierarchy reuse across rho.**  At one size, a hierarchy is built for
   rho_0; for rho = r rho_0 the same system is solved by CG from zero to a
   relative energy error of 1e-6 with that hierarchy kept, after a Galerkin
   refresh, and after a rebuild.  Keeping costs extra CG iterations on every
   solve at the new rho; a refresh or rebuild costs its setup once.  The table
   gives the break-even number of solves: refreshing pays off if more solves
   than that follow at the new rho.
"""
from __future__ import annotations

import csv
import math
import time
from pathlib import Path

import numpy as np

from admmkit.figures import pyplot, save_figure
from admmkit.io import atomic_open, write_text

from admmkit.benchmarks.runner.machine import machine_info
from admmkit.benchmarks.contact.scale_runs import environment_text, print_run, run_in_subprocess
from admmkit.benchmarks.contact.scale import h_label

DEFAULT_HS = (1 / 20, 1 / 40, 1 / 80, 1 / 160, 1 / 320, 1 / 500)
MODES = ("full", "condensed", "iterative")
RATIOS = (1 / 81, 1 / 9, 1 / 3, 1.0, 3.0, 9.0, 81.0, 729.0)


def reuse_table(h: float = 1 / 160, rho0: float = 1e3, ratios=RATIOS, tol: float = 1e-6) -> list[dict]:
    """CG iterations and seconds with a kept / refreshed / rebuilt hierarchy, for rho = r rho0."""
    import scipy.sparse as sp
    from threadpoolctl import threadpool_limits

    from admmkit.blocks.iterative import AMGPreconditioner, PencilMatrix, pcg

    from admmkit.problems.contact.model.assembly import assemble
    from admmkit.problems.contact.solvers.iterative import near_null_space
    from admmkit.problems.contact.model.scene import example1

    ops = assemble(example1(h=h))
    modes, blocks = near_null_space(ops)
    perm = blocks.ravel()
    K = ops.K[perm][:, perm].tocsr()
    D = (ops.B.T @ sp.diags(ops.mc) @ ops.B).tocsr()[perm][:, perm].tocsr()
    pencil = PencilMatrix(K, D)
    bs = blocks.shape[1]
    nns = modes[perm]
    rows = []
    with threadpool_limits(1):
        A0 = pencil.at(rho0)
        base = AMGPreconditioner(A0, nns, blocksize=bs)
        for r in ratios:
            rho = rho0 * r
            A = pencil.at(rho)
            b = ops.f[perm] + rho * (ops.B.T @ (ops.mc * ops.g))[perm]   # the first x-step's rhs with p = g
            row = {"h": h, "n_free": int(ops.n_free), "rho0": rho0, "ratio": r}
            for how in ("keep", "galerkin", "rebuild"):
                t0 = time.perf_counter()
                if how == "keep":
                    M = base
                elif how == "galerkin":
                    M = AMGPreconditioner(A0, nns, blocksize=bs, D=D, rho=rho0)
                    t0 = time.perf_counter()
                    M.refresh(A, rho)
                else:
                    M = AMGPreconditioner(A, nns, blocksize=bs)
                prep = time.perf_counter() - t0
                t1 = time.perf_counter()
                _, its, ratio, _, _ = pcg(A.__matmul__, b, np.zeros_like(b), M, tol=tol, maxiter=2000)
                cg = time.perf_counter() - t1
                row |= {f"{how}_prep_s": prep, f"{how}_its": its, f"{how}_cg_s": cg}
            per_it = row["galerkin_cg_s"] / max(row["galerkin_its"], 1)
            extra = (row["keep_its"] - row["galerkin_its"]) * per_it
            row["break_even_solves"] = row["galerkin_prep_s"] / extra if extra > 0 else math.inf
            rows.append(row)
    return rows


def crossover_size(rows: list[dict]) -> dict:
    """Per size the fastest mode (setup + SADMM) and the smallest size from which the iterative mode wins."""
    by_n: dict[int, dict[str, float]] = {}
    for r in rows:
        if r.get("status") == "converged":
            by_n.setdefault(r["n_free"], {})[r["mode"]] = r["setup_s"] + r["solve_s"]
    winners = {n: min(t, key=t.get) for n, t in sorted(by_n.items())}
    sizes = sorted(winners)
    first = next((n for i, n in enumerate(sizes) if all(winners[m] == "iterative" for m in sizes[i:])), None)
    return {"winners": winners, "iterative_from": first}


def run_crossover(out="out/scale", hs=DEFAULT_HS, modes=MODES, reuse_h=1 / 160,
                  command="admmkit bench amg-crossover", timeout=1800.0) -> dict:
    """Run both measurements, print them and write the files."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    total = len(hs) * len(modes)
    for i, (h, mode) in enumerate(((h, m) for h in hs for m in modes), 1):
        print(f"[{i}/{total}] ex1 h = {h_label(h)} {mode} ...", flush=True)
        r = run_in_subprocess("ex1", h, mode, timeout=timeout)
        rows.append(r)
        print_run(r)
    print(f"hierarchy reuse at h = {h_label(reuse_h)} ...", flush=True)
    reuse = reuse_table(reuse_h)
    for r in reuse:
        print(f"        rho/rho0 = {r['ratio']:g}: CG its keep {r['keep_its']}, refresh {r['galerkin_its']} "
              f"({r['galerkin_prep_s']:.3f} s), rebuild {r['rebuild_its']} ({r['rebuild_prep_s']:.3f} s); "
              f"break-even {r['break_even_solves']:.3g} solves", flush=True)
    summary = crossover_size(rows)
    _write(out, rows, reuse, summary, command)
    return {"runs": rows, "reuse": reuse} | summary


def _write(out: Path, rows, reuse, summary, command) -> None:
    with atomic_open(out / "amg_crossover.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        cols = ["h", "mode", "n_free", "n_c", "status", "iterations", "setup_s", "solve_s", "total_s", "peak_rss_bytes"]
        w.writerow(cols)
        for r in rows:
            w.writerow([r.get(c, "") for c in cols])
    lines = ["# When the iterative x-step wins, and when to reuse the AMG hierarchy", "",
             f"Produced by `{command}`. Example 1 (P1, the paper's mesh), SADMM with rho_0 = 1e3 and the paper's "
             f"stopping rule, every run in its own process ({environment_text()}). Time = setup + SADMM (the "
             "assembly is common to all modes); peak = the process's ru_maxrss.", "",
             "| h | unknowns | n_c | full (s) | condensed (s) | iterative (s) | fastest | peak full / condensed / "
             "iterative (GB) |", "|---|---:|---:|---:|---:|---:|---|---|"]
    by_h: dict[float, dict[str, dict]] = {}
    for r in rows:
        by_h.setdefault(r["h"], {})[r["mode"]] = r
    for h, runs in sorted(by_h.items(), reverse=True):
        any_run = next((r for r in runs.values() if "n_free" in r), {})
        cell = lambda m: (f"{runs[m]['setup_s'] + runs[m]['solve_s']:.2f}" if runs.get(m, {}).get("status") == "converged"  # noqa: E731
                          else runs.get(m, {}).get("status", "-"))
        mem = lambda m: (f"{runs[m]['peak_rss_bytes'] / 1e9:.2f}" if "peak_rss_bytes" in runs.get(m, {}) else "-")  # noqa: E731
        lines.append(f"| {h_label(h)} | {any_run.get('n_free', '')} | {any_run.get('n_c', '')} | {cell('full')} | "
                     f"{cell('condensed')} | {cell('iterative')} | {summary['winners'].get(any_run.get('n_free'), '-')} | "
                     f"{mem('full')} / {mem('condensed')} / {mem('iterative')} |")
    first = summary["iterative_from"]
    lines += ["", "Crossover: " + (f"the iterative mode is the fastest from {first} unknowns on." if first else
                                   "the iterative mode was not the fastest at any measured size (see docs/scale.md "
                                   "for what this means for `mode=\"auto\"`)."), "",
              f"## Reusing the hierarchy across rho (h = {h_label(reuse[0]['h'])}, {reuse[0]['n_free']} unknowns, "
              f"rho_0 = {reuse[0]['rho0']:g})", "",
              "CG from zero to a relative energy error of 1e-6 on (K + rho B'M_c B) u = f + rho B'M_c g. `keep`: the "
              "hierarchy built for rho_0; `refresh`: Galerkin refresh (keep the prolongators; every level becomes R A(rho) P, "
              "computed as A_l + (rho - rho_0) R D P, one axpy per level, then the "
              "smoothers and the coarse LU); `rebuild`: a new setup. Break-even: refreshing costs as much as keeping "
              "does over this many solves at the new rho (infinite: keeping costs nothing extra).", "",
              "| rho / rho_0 | keep: CG it. | refresh: CG it. | refresh (s) | rebuild: CG it. | rebuild (s) | "
              "CG s/it. | break-even solves |", "|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in reuse:
        per_it = r["galerkin_cg_s"] / max(r["galerkin_its"], 1)
        lines.append(f"| {r['ratio']:.4g} | {r['keep_its']} | {r['galerkin_its']} | {r['galerkin_prep_s']:.3f} | "
                     f"{r['rebuild_its']} | {r['rebuild_prep_s']:.3f} | {per_it:.4f} | {r['break_even_solves']:.3g} |")
    lines += ["", "Machine (shared with other engineers during the run):", ""] + \
             [f"- {k}: {v}" for k, v in machine_info().items()]
    write_text(out / "amg_crossover.md", "\n".join(lines) + "\n")

    done = [r for r in rows if r.get("status") == "converged"]
    if not done:
        return
    plt = pyplot()
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.4))
    for mode, style in zip(MODES, ("s-", "^-", "o-")):
        pts = sorted((r["n_free"], r["setup_s"] + r["solve_s"], r["peak_rss_bytes"] / 1e9) for r in done if r["mode"] == mode)
        if pts:
            ax1.loglog([p[0] for p in pts], [p[1] for p in pts], style, label=mode)
            ax2.loglog([p[0] for p in pts], [p[2] for p in pts], style, label=mode)
    ax1.set_xlabel("unknowns"); ax1.set_ylabel("setup + SADMM (s)"); ax1.set_title("Example 1: time by x-step mode")
    ax2.set_xlabel("unknowns"); ax2.set_ylabel("peak RSS (GB)"); ax2.set_title("memory by x-step mode")
    for ax in (ax1, ax2):
        ax.grid(alpha=0.3, which="both"); ax.legend()
    fig.tight_layout()
    save_figure(fig, out / "amg_crossover.png")
