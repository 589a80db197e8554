"""Study: the condensed mode's set-up (the Schur complement on Gamma_C) by backend, against one factorisation + solve.

    admmkit bench contact-schur [--out docs/results/contact_schur/README.md] [--h 1/40 --h 1/200] [--repeats 3]

For Examples 1 and 2 at each h, in one process with BLAS on one thread:

* ``factor+solve``: ``admmkit.linalg.linsolve.factorize(K, "superlu")`` and one solve
  (the pip-only reference of ``admmkit bench contact``), after a warm-up;
* ``fastest``: the fastest pip-only factor + solve of K among
  ``REFERENCES`` of :mod:`admmkit.benchmarks.contact.schur_candidates` (SuperLU,
  qdldl in its AMD order, admmkit.linalg.ldl in nested dissection order);
* ``SADMM``: the condensed contact problem's set-up + ``admmkit.solve`` (SADMM,
  rho_0 = 1e3, the paper's stop), with the Schur backend ``"auto"`` picks
  (without CHOLMOD: ``ldl`` or ``superlu``, named in the table); its set-up
  split;
* every installed candidate of
  :mod:`admmkit.benchmarks.contact.schur_candidates`: its set-up split and S
  against SADMM's S (largest difference relative to the largest entry).

Each time is the best of ``repeats`` (the machine is shared; the best is the
least disturbed); the references and SADMM alternate repeat by repeat.  ``ratio`` = SADMM / (factor+solve),
``ratio / fastest`` = SADMM / fastest; ``est. ratio`` of a candidate = (SADMM - its Schur set-up + the
candidate's) / (factor+solve).
"""
from __future__ import annotations

import datetime
import inspect
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp

import admmkit
from admmkit import RelativeChange, policies
from admmkit.benchmarks.contact.schur_candidates import CANDIDATES, REFERENCES, installed_candidates
from admmkit.benchmarks.runner.machine import machine_info
from admmkit.benchmarks.runner.report import h_label
from admmkit.loop.blas import limit_blas
from admmkit.io import write_text
from admmkit.problems.contact.model.assembly import assemble
from admmkit.problems.contact.model.scene import example1, example2
from admmkit.problems.contact.solvers.problem import contact_problem

DEFAULT_HS = (1 / 40, 1 / 100, 1 / 200)
EXAMPLES = {"ex1": example1, "ex2": example2}


def _best(fn, repeats):
    """(least wall seconds of fn() over repeats, the last result)."""
    best, out = float("inf"), None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def _sadmm(ops, repeats):
    """Best total and set-up seconds of the condensed contact problem + SADMM, with the set-up split."""
    best = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        problem = contact_problem(ops, mode="condensed", backend="auto")
        t1 = time.perf_counter()
        order, rule = policies.method("sadmm")
        result = admmkit.solve(problem, rho=1e3, policy=rule, order=order, stop=RelativeChange(1e-5), max_iter=20_000)
        total = time.perf_counter() - t0
        if best is None or total < best["total"]:
            best = dict(total=total, setup=t1 - t0, schur=sum(problem.schur.timings.values()),
                        split=dict(problem.schur.timings), iterations=result.iterations, S=problem.schur.S,
                        backend=problem.schur.backend)
    return best


def run_study(out=None, hs=DEFAULT_HS, examples=("ex1", "ex2"), repeats=3, candidates=None, block=64,
              progress=True, command=None) -> list[dict]:
    """Measure; write the Markdown table to ``out`` (if given); return the rows."""
    names = list(candidates or installed_candidates())
    unknown = [c for c in names if c not in CANDIDATES]
    if unknown:
        raise ValueError(f"candidates must be among {sorted(CANDIDATES)}, got {unknown}")
    start, rows = time.perf_counter(), []
    with limit_blas(1):
        for ex in examples:
            for h in hs:
                ops = assemble(EXAMPLES[ex](h))
                K = sp.csc_matrix(ops.K)
                X = ops.dof_coordinates()
                refs = {name: float("inf") for name in installed_candidates(REFERENCES)}
                for name in refs:   # a warm-up: the first factorisations in a process run slower
                    REFERENCES[name][0](K, ops.f, X)
                _sadmm(ops, 1)
                sadmm = None
                for _ in range(repeats):   # interleaved, so that a burst of load hits all alike
                    for name in refs:
                        refs[name] = min(refs[name], _best(lambda: REFERENCES[name][0](K, ops.f, X), 1)[0])
                    run = _sadmm(ops, 1)
                    sadmm = run if sadmm is None or run["total"] < sadmm["total"] else sadmm
                contact = np.unique(sp.csr_matrix(ops.B).indices)
                inner = np.setdiff1d(np.arange(K.shape[0]), contact)
                ref, fastest = refs["superlu"], min(refs, key=refs.get)
                row = dict(example=ex, h=h, n=K.shape[0], m=contact.size, ref=ref, refs=refs, fastest=fastest,
                           sadmm=sadmm, candidates={})
                for name in names:
                    fn = CANDIDATES[name][0]
                    extra = {"coordinates": X} if "coordinates" in inspect.signature(fn).parameters else {}
                    res = min((fn(K, ops.B, inner, contact, block, **extra) for _ in range(repeats)),
                              key=lambda r: r["setup"])
                    S = res.pop("S")
                    res["error"] = (None if S is None else
                                    float(np.abs(S - sadmm["S"][:, :S.shape[1]]).max() / np.abs(sadmm["S"]).max()))
                    res["est_ratio"] = (sadmm["total"] - sadmm["schur"] + res["setup"]) / ref
                    row["candidates"][name] = res
                    if progress:
                        print(f"{ex} h={h_label(h)} {name}: set-up {res['setup']:.3f} s, est. ratio "
                              f"{res['est_ratio']:.2f}", file=sys.stderr, flush=True)
                if progress:
                    print(f"{ex} h={h_label(h)}: factor+solve {ref:.3f} s, SADMM ({sadmm['backend']}) "
                          f"{sadmm['total']:.3f} s, ratio {sadmm['total'] / ref:.2f}, over the fastest ({fastest}) "
                          f"{sadmm['total'] / refs[fastest]:.2f}", file=sys.stderr, flush=True)
                rows.append(row)
    if out:
        write_markdown(Path(out), rows, repeats, block, time.perf_counter() - start,
                       command or f"admmkit bench contact-schur --out {out}")
    return rows


def write_markdown(path: Path, rows, repeats, block, wall, command) -> Path:
    """The ratio table, the set-up split per candidate, the command and the machine."""
    lines = ["# Contact without CHOLMOD: the Schur complement's set-up by backend", "",
             f"Produced by `{command}` on {datetime.date.today().isoformat()} (total {wall:.1f} s). "
             f"Best of {repeats} (wall seconds, BLAS on one thread); see "
             "`benchmarks/contact/schur_study.py` for the definitions.", "",
             "## SADMM / (factorisation + solve): the Schur backend \"auto\" picks (contact dofs last, inner dofs "
             "in nested dissection order)", "",
             "`ratio`: over SuperLU's factor+solve (the reference of `admmkit bench contact`); `ratio / fastest`: "
             "over the fastest pip-only factor+solve of K (next table).", "",
             "| example | h | n | n_c dofs | factor+solve (s) | SADMM (s) | backend | of which Schur set-up | "
             "ordering | factorisation | schur | iterations | ratio | ratio / fastest |",
             "|---|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        s = r["sadmm"]
        lines.append(f"| {r['example']} | {h_label(r['h'])} | {r['n']} | {r['m']} | {r['ref']:.3f} | "
                     f"{s['total']:.3f} | {s['backend']} | {s['schur']:.3f} | {s['split']['ordering']:.3f} | "
                     f"{s['split']['factorisation']:.3f} | {s['split']['schur']:.3f} | {s['iterations']} | "
                     f"**{s['total'] / r['ref']:.2f}** | **{s['total'] / r['refs'][r['fastest']]:.2f}** |")
    names = list(rows[0]["refs"]) if rows else []
    lines += ["", "## Pip-only factorisation + solve of K (s)", "",
              "| example | h | " + " | ".join(names) + " | fastest |", "|---|---|" + "---:|" * len(names) + "---|"]
    for r in rows:
        lines.append(f"| {r['example']} | {h_label(r['h'])} | " + " | ".join(f"{r['refs'][k]:.3f}" for k in names)
                     + f" | {r['fastest']} |")
    lines += ["", "## Candidates: Schur set-up (s), its steps, S against SADMM's, estimated ratio", "",
              "| example | h | candidate | set-up (s) | steps (s) | max diff of S (rel.) | est. ratio |",
              "|---|---|---|---:|---|---:|---:|"]
    for r in rows:
        for name, c in r["candidates"].items():
            steps = ", ".join(f"{k} {v:.3f}" for k, v in c["steps"].items())
            err = "-" if c["error"] is None else f"{c['error']:.1e}"
            lines.append(f"| {r['example']} | {h_label(r['h'])} | {name} | {c['setup']:.3f}"
                         f"{' (extrapolated)' if c['extrapolated'] else ''} | {steps} | {err} | "
                         f"{c['est_ratio']:.2f} |")
    lines += ["", f"Block solves: {block} columns a block; `extrapolated`: the first blocks timed and scaled to "
              "all n_c columns.", "", "## Machine", ""] + [f"- {k}: {v}" for k, v in machine_info().items()]
    lines += ["", "Other processes shared the machine (see the load average).", ""]
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text(path, "\n".join(lines))
    return path
