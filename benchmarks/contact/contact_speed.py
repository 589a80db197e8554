"""Speed benchmark: SADMM against one sparse factorisation + solve of K.

    admmkit bench contact [--out docs/results/contact_speed.md] [--h 1/40 --h 1/200] [--repeats 3]

For Examples 1 and 2 at each h, and for each sparse backend world measured in
the same run:

* ``cholmod`` (when scikit-sparse is installed): the reference factorisation
  and the condensed set-up both use CHOLMOD;
* ``superlu`` (what a fresh machine with only pip has): both use SuperLU;

the benchmark times ``admmkit.linalg.linsolve.factorize(K, backend)`` followed by one
``solve(f)`` (what one linear elastic solve without contact costs), and SADMM
(rho_0 = 1e3, the paper's stopping rule): contact-problem set-up +
``admmkit.solve``, median of ``repeats`` runs each building a fresh contact
problem, in the condensed and the full mode, the two measured in alternation
round by round (:func:`interleaved`).  The ratio SADMM / (factor +
solve) says how many linear solves the contact problem costs.  The condensed
set-up is split with :attr:`admmkit.problems.contact.solvers.schur.BoundarySchur.timings`.

A warm process is measured: numba's kernels are loaded before the first timing
(:func:`load_kernels`), so the condensed set-up orders by the compiled nested
dissection (``compiled="auto"`` takes the kernels once numba is imported; the
same order as its numpy twin, which a fresh process of a small body runs) and
the iterations run the compiled steps and segments
(``problems/contact/solvers/condensed_segment.py``).  A fresh process's
start-up is ``admmkit bench first-call``'s.
"""
from __future__ import annotations

import datetime
import statistics
import sys
import time
from pathlib import Path

import admmkit
from admmkit import policies
from admmkit import RelativeChange
from admmkit.loop.blas import limit_blas
from admmkit.linalg.linsolve import available_backends, factorize
from admmkit.io import write_text

from admmkit.problems.contact.model.assembly import assemble
from admmkit.problems.contact.solvers.problem import contact_problem
from admmkit.benchmarks.runner.machine import machine_info
from admmkit.benchmarks.runner.report import h_label
from admmkit.problems.contact.model.scene import example1, example2
from admmkit.problems.contact.solvers.schur import available_schur_backends

DEFAULT_HS = (1 / 40, 1 / 200)
EXAMPLES = {"ex1": example1, "ex2": example2}
#: issue #49's target for the condensed-mode ratio SADMM / (factor + solve), both sizes (the first issue's were 2 and 3)
TARGETS = {1 / 40: 1.3, 1 / 200: 1.3}
#: the parts of the condensed set-up, in the order they run
SETUP_STEPS = ["ordering", "factorisation", "schur", "u0 + compliance"]


def backend_worlds() -> list[str]:
    """Backends to compare, each used for both the reference and the contact problem."""
    both = set(available_backends()) & set(available_schur_backends())
    return [b for b in ("cholmod", "superlu") if b in both]


def load_kernels(ops) -> None:
    """Import numba and load the condensed mode's kernels once (nothing if numba is not installed): the set-up's
    ordering, and the iterations' steps and segment (one SADMM run, untimed; with numba imported its set-up's
    ``compiled="auto"`` takes the kernels)."""
    from admmkit.problems.contact.solvers.dissection import use_kernels
    if use_kernels(ops.n_free, True):
        import numba  # noqa: F401  (admmkit.kernels.compiled_now: "auto" runs compiled once numba is imported)
        sadmm_once(ops, "condensed", "superlu")


def factor_solve_once(K, f, backend="auto") -> tuple[float, float]:
    """(wall, CPU) seconds of one factorize(K, backend) + one solve(f)."""
    t0, c0 = time.perf_counter(), time.process_time()
    factorize(K, backend=backend)(f)
    return time.perf_counter() - t0, time.process_time() - c0


def time_factor_solve(K, f, backend="auto", repeats=3):
    """Median (wall, CPU) seconds of factorize(K, backend) + one solve(f), after one untimed
    warm-up (the first factorisations in a process were up to 2x slower)."""
    factor_solve_once(K, f, backend)
    runs = [factor_solve_once(K, f, backend) for _ in range(repeats)]
    return statistics.median(r[0] for r in runs), statistics.median(r[1] for r in runs)


def sadmm_once(ops, mode, backend="auto", rho=1e3) -> dict:
    """One contact_problem(ops, mode, backend) + admmkit.solve (SADMM): seconds (total, CPU, set-up), the result
    and, in the condensed mode, the set-up split (:attr:`BoundarySchur.timings` and the rest)."""
    t0, c0 = time.perf_counter(), time.process_time()
    problem = contact_problem(ops, mode=mode, backend=backend)
    t1 = time.perf_counter()
    sadmm_order, sadmm_rule = policies.method("sadmm")   # policies/paper_methods.py
    result = admmkit.solve(problem, rho=rho, policy=sadmm_rule, order=sadmm_order,
                           stop=RelativeChange(1e-5), max_iter=20_000)
    t2, c2 = time.perf_counter(), time.process_time()
    run = {"total": t2 - t0, "cpu": c2 - c0, "setup": t1 - t0, "result": result}
    if mode == "condensed":
        split = dict(problem.schur.timings)
        split["u0 + compliance"] = (t1 - t0) - sum(split.values())
        run["split"] = split
    return run


def summary(runs: list[dict]) -> dict:
    """The medians of :func:`sadmm_once`'s runs and the last run's counts."""
    last = runs[-1]["result"]
    out = {"total": statistics.median(r["total"] for r in runs), "cpu": statistics.median(r["cpu"] for r in runs),
           "setup": statistics.median(r["setup"] for r in runs), "iterations": last.iterations,
           "status": last.status.value, "factorizations": last.factorizations, "rho_changes": last.rho_changes}
    if "split" in runs[-1]:
        out["split"] = {k: statistics.median(r["split"][k] for r in runs) for k in SETUP_STEPS}
    return out


def time_sadmm(ops, mode, backend="auto", rho=1e3, repeats=3):
    """Median seconds of contact_problem(ops, mode, backend) + admmkit.solve (SADMM), with the set-up split."""
    return summary([sadmm_once(ops, mode, backend, rho) for _ in range(repeats)])


#: a reference factorisation + solve shorter than SHORT_SECONDS is measured in at least SHORT_ROUNDS rounds: at
#: h = 1/40 one round of 3 moved the ratio by 0.2-0.3 on the loaded machine (29 November), and 15 rounds cost 6-10 s
SHORT_SECONDS, SHORT_ROUNDS = 0.1, 15


def rounds_for(seconds: float, repeats: int) -> int:
    """The rounds of a size whose reference took ``seconds`` once: ``repeats``, at least SHORT_ROUNDS if short."""
    return max(repeats, SHORT_ROUNDS) if seconds < SHORT_SECONDS else repeats


def interleaved(ops, modes, backend="auto", rho=1e3, repeats=3) -> tuple[tuple[float, float], dict[str, dict]]:
    """((wall, CPU) of factor + solve, {mode: SADMM summary}), measured round by round: each round one
    factor + solve, then one SADMM run per mode, after one untimed factor + solve (as before: the first
    factorisations in a process were up to 2x slower). A change of load on the shared machine then hits the
    reference and SADMM alike; measured one after the other, a ratio at h = 1/40 read 1.29 in one run and 2.07
    in the next (CPU, Example 2, 28 November, load 5-7).  ``repeats`` rounds, at least SHORT_ROUNDS where the
    warm-up's factor + solve took under SHORT_SECONDS (:func:`rounds_for`)."""
    warm, _ = factor_solve_once(ops.K, ops.f, backend)
    base, runs = [], {mode: [] for mode in modes}
    for _ in range(rounds_for(warm, repeats)):
        base.append(factor_solve_once(ops.K, ops.f, backend))
        for mode in modes:
            runs[mode].append(sadmm_once(ops, mode, backend, rho))
    wall, cpu = statistics.median(b[0] for b in base), statistics.median(b[1] for b in base)
    return (wall, cpu), {mode: summary(r) for mode, r in runs.items()}


def run_bench(out=None, hs=DEFAULT_HS, repeats=3, examples=("ex1", "ex2"), modes=("condensed", "full"),
              rho=1e3, worlds=None, progress=True, command=None, blas_threads: int | None = 1) -> list[dict]:
    """Run the benchmark; write a Markdown table to ``out`` (if given); return the rows.

    Everything (reference, set-up, solve) runs with BLAS pinned to
    ``blas_threads`` threads, the condition admmkit.solve itself runs in by
    default: on a loaded 2-core machine CHOLMOD with 2 OpenBLAS threads took
    0.7-1.9 s instead of 0.04 s for one factorisation of Example 2's K at h = 1/40.
    """
    worlds = list(worlds or backend_worlds())
    start = time.perf_counter()
    rows = []
    with limit_blas(blas_threads):
        for ex in examples:
            for h in hs:
                ops = assemble(EXAMPLES[ex](h))
                if not rows:
                    load_kernels(ops)
                row = {"example": ex, "h": h, "n_free": ops.n_free, "n_c": ops.n_c, "worlds": {}}
                for backend in worlds:
                    (base, base_cpu), sadmm = interleaved(ops, modes, backend, rho, repeats)
                    w = {"factor_solve": base, "factor_solve_cpu": base_cpu, "modes": {}}
                    for mode in modes:
                        s = sadmm[mode]
                        s["ratio"] = s["total"] / base
                        s["ratio_cpu"] = s["cpu"] / base_cpu
                        w["modes"][mode] = s
                        if progress:
                            print(f"{ex} h={h_label(h)} {backend:8s} {mode:9s}: SADMM {s['total']:.3f} s "
                                  f"(setup {s['setup']:.3f}), factor+solve {base:.3f} s, ratio {s['ratio']:.2f} "
                                  f"(CPU {s['ratio_cpu']:.2f}), {s['iterations']} it", file=sys.stderr, flush=True)
                    row["worlds"][backend] = w
                rows.append(row)
    if out:
        write_markdown(Path(out), rows, repeats, rho, time.perf_counter() - start,
                       command or f"admmkit bench contact --out {out}", blas_threads)
    return rows


def _target(h):
    return next((v for k, v in TARGETS.items() if abs(k - h) < 1e-12), None)


def write_markdown(path: Path, rows, repeats, rho, wall, command, blas_threads=1) -> Path:
    """The benchmark tables with the command and the machine."""
    worlds = list(rows[0]["worlds"]) if rows else []
    modes = list(rows[0]["worlds"][worlds[0]]["modes"]) if worlds else []
    lines = ["# Contact speed: SADMM against one factorisation + solve of K", "",
             f"Produced by `{command}` on {datetime.date.today().isoformat()} (total {wall:.1f} s).", "",
             "`factor+solve`: `admmkit.linalg.linsolve.factorize(K, backend)` then one `solve(f)`, median of "
             f"{repeats} rounds ({SHORT_ROUNDS} where one takes under {SHORT_SECONDS:g} s) after a warm-up. `SADMM`: contact-problem set-up + `admmkit.solve` with rho_0 = {rho:g}, "
             "tau = 2, c_max = 100 and the paper's stop (||u^{k+1}-u^k||_K <= 1e-5 ||u^{k+1}||_K), median of "
             f"the same rounds, a fresh contact problem each repeat. The two are measured in alternation, round by round, "
             "so that a change of load hits both. `ratio` = SADMM / (factor+solve), both with the "
             "same backend: `cholmod` (scikit-sparse, needs SuiteSparse headers to install) and `superlu` "
             "(scipy, what a machine with only pip has). The condensed set-up factorises K once, contact dofs "
             "last, and reads the Schur complement off the factor (`problems/contact/solvers/schur.py`); the full mode "
             "factorises K + rho B'M_cB once per rho. Target (condensed mode, issue #49): ratio <= 1.3 at h = 1/40 "
             f"and 1/200. BLAS threads pinned to {blas_threads}. `it / fact.`: iterations / factorisations "
             "(dense n_c x n_c Cholesky in condensed mode, sparse in full mode). `CPU ratio`: the same ratio in CPU "
             "seconds of the process (`time.process_time`), which a loaded machine distorts less than wall time "
             "(BLAS runs on one thread here).", ""]
    for backend in worlds:
        lines += [f"## Backend `{backend}`", "",
                  "| example | h | n_free | n_c | factor+solve (s) | "
                  + " | ".join(f"SADMM {m} (s) | ratio {m} | CPU ratio {m} | it / fact. {m}" for m in modes)
                  + " | target met (wall / CPU) |",
                  "|---|---|---:|---:|---:|" + "---:|---:|---:|---:|" * len(modes) + "---|"]
        for r in rows:
            w = r["worlds"][backend]
            cells = [r["example"], h_label(r["h"]), str(r["n_free"]), str(r["n_c"]), f"{w['factor_solve']:.4f}"]
            for m in modes:
                s = w["modes"][m]
                cells += [f"{s['total']:.4f}", f"**{s['ratio']:.2f}**", f"{s['ratio_cpu']:.2f}",
                          f"{s['iterations']} / {s['factorizations']}"
                          + ("" if s["status"] == "converged" else f" ({s['status']})")]
            target = _target(r["h"])
            if target is not None and "condensed" in w["modes"]:
                c = w["modes"]["condensed"]
                cells.append(" / ".join("yes" if c[k] <= target else "no" for k in ("ratio", "ratio_cpu"))
                             + f" (<= {target:g})")
            else:
                cells.append("-")
            lines.append("| " + " | ".join(cells) + " |")
        if "condensed" in modes:
            lines += ["", f"Condensed set-up with `{backend}`, split (seconds, medians), and the ADMM iterations:", "",
                      "| example | h | " + " | ".join(SETUP_STEPS) + " | iterations | factor+solve |",
                      "|---|---|" + "---:|" * (len(SETUP_STEPS) + 2)]
            for r in rows:
                w = r["worlds"][backend]
                s = w["modes"]["condensed"]
                lines.append(f"| {r['example']} | {h_label(r['h'])} | "
                             + " | ".join(f"{s['split'][k]:.4f}" for k in SETUP_STEPS)
                             + f" | {s['total'] - s['setup']:.4f} | {w['factor_solve']:.4f} |")
        lines.append("")
    lines += ["## Machine", ""] + [f"- {k}: {v}" for k, v in machine_info().items()]
    lines += ["", "Other processes may share the machine (see the load average); small times are noisy.", ""]
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text(path, "\n".join(lines))
    return path
