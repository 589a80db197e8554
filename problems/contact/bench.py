"""Speed benchmark: SADMM against one sparse factorisation + solve of K.

    python -m problems.contact.bench [--out docs/results/contact_speed.md] [--h 1/40 --h 1/200] [--repeats 3]
    admmkit bench contact [--out ...]

For Examples 1 and 2 at each h: the time of ``admmkit.linsolve.factorize(K)``
followed by one ``solve(f)`` with the default backend (what one linear
elastic solve without contact costs), and the time of SADMM (rho_0 = 1e3, the
paper's stopping rule): contact problem setup + ``admmkit.solve``, median of
``repeats`` runs each building a fresh contact problem, in the condensed and
the full mode.  The ratio SADMM / (factor + solve) says how many linear solves
the contact problem costs.  For the condensed mode the setup is split into its
pieces by timing the steps of :class:`problems.contact.schur.BoundarySchur`
from outside (same calls, same order).
"""
from __future__ import annotations

import argparse
import datetime
import statistics
import sys
import time
from pathlib import Path

import numpy as np

import admmkit
import policies
from admmkit import RelativeChange
from admmkit.linsolve import available_backends, factorize

from .assembly import assemble
from .problem import contact_problem
from .reproduce import h_label, machine_info
from .scene import example1, example2

DEFAULT_HS = (1 / 40, 1 / 200)
EXAMPLES = {"ex1": example1, "ex2": example2}
#: the issue's targets for the condensed-mode ratio SADMM / (factor + solve)
TARGETS = {1 / 40: 2.0, 1 / 200: 3.0}


#: the timed steps of the condensed setup, in the order they run
SETUP_STEPS = ["ordering", "permute", "factorisation", "Schur extraction", "u0 solve", "compliance"]

def _median_time(fn, repeats):
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def time_factor_solve(K, f, repeats=3):
    """Median seconds of factorize(K) + one solve(f) with the default backend (after one untimed warm-up:
    the first factorisations in a process were up to 2x slower)."""
    def once():
        solve = factorize(K)
        return solve(f)
    once()
    return _median_time(once, repeats)[0]


def time_sadmm(ops, mode, rho=1e3, repeats=3):
    """Median seconds of contact_problem(ops, mode) + admmkit.solve (SADMM), and the last result."""
    setups, totals, results = [], [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        problem = contact_problem(ops, mode=mode)
        t1 = time.perf_counter()
        result = admmkit.solve(problem, rho=rho, policy=policies.Summable(tau=2.0, c_max=100), order="zx",
                               stop=RelativeChange(1e-5), max_iter=20_000)
        t2 = time.perf_counter()
        setups.append(t1 - t0)
        totals.append(t2 - t0)
        results.append(result)
    return {"total": statistics.median(totals), "setup": statistics.median(setups),
            "iterations": results[-1].iterations, "status": results[-1].status.value,
            "factorizations": results[-1].factorizations, "rho_changes": results[-1].rho_changes}


def condensed_setup_split(ops):
    """Seconds of the pieces of the condensed setup (BoundarySchur's steps, timed from outside)."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from . import schur
    K, B = sp.csr_matrix(ops.K), ops.B
    t = {}
    t0 = time.perf_counter()
    contact_dofs = np.unique(sp.csc_matrix(B).nonzero()[1])
    order = schur.contact_last_ordering(K, contact_dofs)
    t["ordering"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    Kp = K[order][:, order].tocsc()
    t["permute"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    lu = spla.splu(Kp, permc_spec="NATURAL", diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))
    t["factorisation"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    m = contact_dofs.size
    S = schur._trailing_block(lu.L, m) @ schur._trailing_block(lu.U, m)
    t["Schur extraction"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    x = lu.solve(np.asarray(ops.f, dtype=float)[order])
    t["u0 solve"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    Bc = sp.csr_matrix(B)[:, contact_dofs].toarray()
    import scipy.linalg as sla
    C = Bc @ sla.cho_solve(sla.cho_factor(0.5 * (S + S.T)), Bc.T)
    t["compliance"] = time.perf_counter() - t0
    t["L+U nnz"] = int(lu.L.nnz + lu.U.nnz)
    t["_S"] = S
    del x, C
    return t


def cholmod_schur_prototype(ops, S_ref=None):
    """What-if: the condensed setup with CHOLMOD instead of pymetis + SuperLU (not used by the solver).

    Order the inner block K_ii with CHOLMOD's AMD (cholmod.analyze), put the contact
    dofs last, factor the permuted K = L L' with CHOLMOD in that (natural) order and
    read S = L_cc L_cc' off the trailing block; then u0 = K^{-1} f and C = B_c S^{-1} B_c'.
    Returns seconds per step, their sum and the relative difference of S against
    ``S_ref`` (BoundarySchur's). None if scikit-sparse is not installed.
    """
    try:
        from sksparse import cholmod
    except ImportError:
        return None
    import scipy.linalg as sla
    import scipy.sparse as sp
    K, B = sp.csr_matrix(ops.K), ops.B
    t = {}
    t0 = time.perf_counter()
    contact_dofs = np.unique(sp.csc_matrix(B).nonzero()[1])
    m = contact_dofs.size
    inner = np.setdiff1d(np.arange(K.shape[0]), contact_dofs)
    analysis = cholmod.analyze(K[inner][:, inner].tocsc(), ordering_method="amd")
    order = np.concatenate([inner[analysis.P()], contact_dofs])
    t["ordering"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    Kp = K[order][:, order].tocsc()
    t["permute"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    factor = cholmod.cholesky(Kp, ordering_method="natural")
    t["factorisation"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    L = sp.csc_matrix(factor.L())
    L_cc = L[:, -m:][-m:, :].toarray()
    S = L_cc @ L_cc.T
    t["Schur extraction"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    u0 = np.empty(K.shape[0])
    u0[order] = factor(np.asarray(ops.f, dtype=float)[order])
    t["u0 solve"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    Bc = sp.csr_matrix(B)[:, contact_dofs].toarray()
    C = Bc @ sla.cho_solve(sla.cho_factor(S), Bc.T)
    t["compliance"] = time.perf_counter() - t0
    t["sum"] = sum(t[k] for k in ("ordering", "permute", "factorisation", "Schur extraction", "u0 solve",
                                  "compliance"))
    t["S rel. diff"] = float(np.abs(S - S_ref).max() / np.abs(S_ref).max()) if S_ref is not None else float("nan")
    t["L nnz"] = int(L.nnz)
    del C
    return t


def run_bench(out=None, hs=DEFAULT_HS, repeats=3, examples=("ex1", "ex2"), modes=("condensed", "full"),
              rho=1e3, split=True, progress=True, command=None, blas_threads: int | None = 1) -> list[dict]:
    """Run the benchmark; write a Markdown table to ``out`` (if given); return the rows.

    Everything (baseline, setup, solve) runs with BLAS pinned to ``blas_threads``
    threads, the condition admmkit.solve itself runs in by default: on a loaded
    2-core machine CHOLMOD with 2 OpenBLAS threads took 0.7-1.9 s instead of
    0.04 s for one factorisation of Example 2's K at h = 1/40.
    """
    from contextlib import nullcontext

    from threadpoolctl import threadpool_limits
    with threadpool_limits(blas_threads, user_api="blas") if blas_threads else nullcontext():
        return _run_bench(out, hs, repeats, examples, modes, rho, split, progress, command, blas_threads)


def _run_bench(out, hs, repeats, examples, modes, rho, split, progress, command, blas_threads):
    start = time.perf_counter()
    rows = []
    backend = available_backends()[0]
    for ex in examples:
        for h in hs:
            t0 = time.perf_counter()
            ops = assemble(EXAMPLES[ex](h))
            t_asm = time.perf_counter() - t0
            base = time_factor_solve(ops.K, ops.f, repeats)
            row = {"example": ex, "h": h, "n_free": ops.n_free, "n_c": ops.n_c, "nnz_K": ops.K.nnz,
                   "assembly": t_asm, "factor_solve": base, "backend": backend, "modes": {}}
            for mode in modes:
                s = time_sadmm(ops, mode, rho, repeats)
                s["ratio"] = s["total"] / base
                row["modes"][mode] = s
                if progress:
                    print(f"{ex} h={h_label(h)} {mode:9s}: SADMM {s['total']:.3f} s (setup {s['setup']:.3f}), "
                          f"factor+solve {base:.3f} s, ratio {s['ratio']:.2f}, {s['iterations']} it",
                          file=sys.stderr, flush=True)
            if split and "condensed" in modes:
                row["split"] = condensed_setup_split(ops)
                proto = cholmod_schur_prototype(ops, row["split"].pop("_S"))
                if proto is not None:
                    cond = row["modes"]["condensed"]
                    proto["estimated ratio"] = (proto["sum"] + cond["total"] - cond["setup"]) / base
                    row["prototype"] = proto
            rows.append(row)
    wall = time.perf_counter() - start
    if out:
        write_markdown(Path(out), rows, repeats, rho, wall, command or f"python -m problems.contact.bench --out {out}",
                       blas_threads)
    return rows


def write_markdown(path: Path, rows, repeats, rho, wall, command, blas_threads=1) -> Path:
    """The benchmark table with the command and the machine."""
    info = machine_info()
    modes = list(rows[0]["modes"]) if rows else []
    lines = ["# Contact speed: SADMM against one factorisation + solve of K", "",
             f"Produced by `{command}` on {datetime.date.today().isoformat()} (total {wall:.1f} s).", "",
             f"`factor+solve`: `admmkit.linsolve.factorize(K)` then one `solve(f)`, default backend "
             f"(`{rows[0]['backend'] if rows else '?'}`), median of {repeats}. `SADMM`: contact problem setup + "
             f"`admmkit.solve` with rho_0 = {rho:g}, tau = 2, c_max = 100, the paper's stop "
             f"(||u^{{k+1}}-u^k||_K <= 1e-5 ||u^{{k+1}}||_K), median of {repeats}, a fresh contact problem each repeat. "
             "`ratio` = SADMM / (factor+solve). Targets (condensed mode): ratio <= 2 at h = 1/40, <= 3 at h = 1/200. "
             f"BLAS threads pinned to {blas_threads} for everything (threadpoolctl; admmkit.solve's default "
             "inside the loop). `setup`: building the contact problem (condensed: ordering, LU, Schur "
             "complement, compliance; full: B'M_cB), included in SADMM. `it / fact.`: iterations / "
             "factorisations (dense n_c x n_c Cholesky in condensed mode, sparse in full mode).",
             "", "| example | h | n_free | n_c | factor+solve (s) | "
             + " | ".join(f"SADMM {m} (s) | setup {m} (s) | ratio {m} | it / fact. {m}" for m in modes)
             + " | target met (condensed) |",
             "|---|---|---:|---:|---:|" + "---:|---:|---:|---:|" * len(modes) + "---|"]
    for r in rows:
        cells = [r["example"], h_label(r["h"]), str(r["n_free"]), str(r["n_c"]), f"{r['factor_solve']:.4f}"]
        for m in modes:
            s = r["modes"][m]
            cells += [f"{s['total']:.4f}", f"{s['setup']:.4f}", f"**{s['ratio']:.2f}**",
                      f"{s['iterations']} / {s['factorizations']}" + ("" if s["status"] == "converged" else f" ({s['status']})")]
        target = next((v for k, v in TARGETS.items() if abs(k - r["h"]) < 1e-12), None)
        if target is not None and "condensed" in r["modes"]:
            ok = r["modes"]["condensed"]["ratio"] <= target
            cells.append(f"{'yes' if ok else 'no'} (<= {target:g})")
        else:
            cells.append("-")
        lines.append("| " + " | ".join(cells) + " |")
    if any("split" in r for r in rows):
        keys = SETUP_STEPS
        lines += ["", "## Condensed setup, split", "",
                  "The steps of `problems/contact/schur.py` `BoundarySchur` and `CondensedContact.__init__`, "
                  "timed from outside (one run, same calls): METIS nested-dissection ordering with the contact "
                  "dofs last, the permutation of K, SuperLU LU in that order (NATURAL, symmetric mode), the "
                  "trailing blocks L_cc U_cc = S, the solve for u0 = K^{-1} f, and C = B_c S^{-1} B_c'. "
                  "Compare `factorisation` with `factor+solve` above (the default backend with its own ordering).",
                  "", "| example | h | " + " | ".join(f"{k} (s)" for k in keys) + " | sum (s) | L+U nnz |",
                  "|---|---|" + "---:|" * (len(keys) + 2)]
        for r in rows:
            if "split" not in r:
                continue
            sp_ = r["split"]
            lines.append(f"| {r['example']} | {h_label(r['h'])} | " + " | ".join(f"{sp_[k]:.4f}" for k in keys)
                         + f" | {sum(sp_[k] for k in keys):.4f} | {sp_['L+U nnz']} |")
    if any("prototype" in r for r in rows):
        keys = SETUP_STEPS
        lines += ["", "## What-if: the condensed setup with CHOLMOD (prototype, not used by the solver)", "",
                  "`cholmod_schur_prototype` in `problems/contact/bench.py`: AMD ordering of the inner block K_ii "
                  "(`cholmod.analyze`), contact dofs last, CHOLMOD L L' of the permuted K in that order "
                  "(`ordering_method=\"natural\"`, CHOLMOD picks simplicial or supernodal), S = L_cc L_cc' from the trailing block of L, "
                  "then u0 and C as above. `est. ratio` = (prototype setup + the condensed SADMM iterations "
                  "measured above) / (factor+solve). One run each.", "",
                  "| example | h | " + " | ".join(f"{k} (s)" for k in keys)
                  + " | sum (s) | vs SuperLU split sum | S rel. diff | L nnz | est. ratio |",
                  "|---|---|" + "---:|" * (len(keys) + 5)]
        for r in rows:
            if "prototype" not in r:
                continue
            pr, sp_ = r["prototype"], r["split"]
            old_sum = sum(sp_[k] for k in keys)
            lines.append(f"| {r['example']} | {h_label(r['h'])} | " + " | ".join(f"{pr[k]:.4f}" for k in keys)
                         + f" | {pr['sum']:.4f} | {old_sum / pr['sum']:.1f}x faster | {pr['S rel. diff']:.1e} | "
                         f"{pr['L nnz']} | {pr['estimated ratio']:.2f} |")
    lines += ["", "## Machine", ""] + [f"- {k}: {v}" for k, v in info.items()]
    lines += ["", "Other processes may share the machine (see the load average); small times are noisy.", ""]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines))
    return path


def main(argv=None) -> int:
    """Command-line entry point."""
    from fractions import Fraction
    p = argparse.ArgumentParser(prog="python -m problems.contact.bench", description=__doc__.split("\n")[0])
    p.add_argument("--out", default="docs/results/contact_speed.md")
    p.add_argument("--h", action="append", default=None, dest="hs", help="mesh size, e.g. 1/40 (repeatable)")
    p.add_argument("--repeats", type=int, default=3)
    a = p.parse_args(argv)
    hs = tuple(float(Fraction(h)) for h in a.hs) if a.hs else DEFAULT_HS
    cmd = "python -m problems.contact.bench --out " + a.out + "".join(f" --h {h}" for h in (a.hs or []))
    run_bench(out=a.out, hs=hs, repeats=a.repeats, command=cmd)
    return 0


if __name__ == "__main__":
    sys.exit(main())
