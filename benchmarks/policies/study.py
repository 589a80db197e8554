"""Penalty rules on the finite element problems across rho_0: ``admmkit bench policies``.

    admmkit bench policies [--out docs/results/policies_fe] [--quick]

For contact Example 1 (h = 1/20, condensed mode), the same with Tresca friction (slip bound 2, full mode)
and the radial obstacle (h = 1/16), every rule of :data:`RULES` in both orders from rho_0 = 10^j over 12
decades (1e-4 ... 1e8 for contact, whose stiffness E = 2000 puts good penalties near 1e3; 1e-6 ... 1e6
for the obstacle).  ``bench rules`` runs the same cases (and Example 2) with acceleration.

Each run stops when the relative error against a reference solution of the
same discrete problem (cvxpy + Clarabel) is at most 1e-6, in the problem's
x norm (energy norm of u for contact, lumped L2 for the obstacle), or at the
cap: this measures the rules, not a stopping rule.  Reported: those
iterations, the factorisations of the x-step matrix until then, and, from the
same run (a stopping rule does not change the iterates), the iteration at
which the paper's rule (relative change 1e-5) would have fired and the error
there.  Writes README.md (tables), sweep.csv and sweep.png/.svg.

The runs go through the sweep runner (:mod:`admmkit.benchmarks.runner.sweep`): one case per
(problem, rule, order, rho_0), the cases of one problem in one task (the
reference solution is computed once per worker), finished cases kept in
``results.jsonl`` (an interrupted sweep resumes), local processes or Dask.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

import admmkit
from admmkit import RelativeChange

from admmkit.benchmarks.fixtures.methods import method_label, policy_version
from admmkit.benchmarks.runner.harness import check_harness, first_line, harness_failures, is_harness_failure
from admmkit.benchmarks.runner.report import write_csv, write_text
from admmkit.benchmarks.runner.sweep import Executor, run_sweep

#: the rules of this table: the literature rules, the wrappers, and the paper's baselines
RULES = ("fixed", "summable", "wohlberg", "osqp", "aadmm", "summable_steps", "quantized")
ORDERS = ("xz", "zx")
MAX_ITER = 20_000
TOL = 1e-5          # the paper's relative-change tolerance
ORACLE = 1e-6       # the stop: relative error against the reference
FALSE_STOP = 1e-3   # an error above this where the paper's rule fires counts as a false stop


def contact_case(h: float = 1 / 20, example: int = 1):
    """(name, make_problem, relative_error, rho_0 values) for contact Example 1 (or 2) in the condensed mode."""
    from admmkit.problems.contact.model.assembly import assemble
    from admmkit.problems.contact.solvers.problem import contact_problem
    from admmkit.problems.contact.validation.reference import reference_solution
    from admmkit.problems.contact.model.scene import example1, example2
    ops = assemble((example1 if example == 1 else example2)(h))
    ref = reference_solution(ops)
    # the condensed iterate of the reference: u = K^{-1}(f + B'w) with w = -M_c lam (s = 1)
    x_ref = np.concatenate(([1.0], -ops.mc * ref.lam))

    def error(problem, x):
        return problem.x_distance(x, x_ref) / problem.x_norm(x_ref)
    return (f"contact Ex.{example}, h = 1/{round(1 / h)}", lambda: contact_problem(ops, mode="condensed"), error,
            tuple(10.0 ** j for j in range(-4, 9)), "energy norm")


def obstacle_case(h: float = 1 / 16):
    """(name, make_problem, relative_error, rho_0 values) for the radial obstacle."""
    from admmkit.problems.obstacle import make_problem, solve_with_cvxpy
    from admmkit.problems.obstacle.scene import radial
    problem = make_problem(radial(h=h))
    u_ref, _ = solve_with_cvxpy(problem, tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12)
    norm_ref = problem.norm(u_ref)

    def error(problem, x):
        return problem.norm(x - u_ref) / norm_ref
    return (f"radial obstacle, h = 1/{round(1 / h)}", lambda: make_problem(radial(h=h)), error,
            tuple(10.0 ** j for j in range(-6, 7)), "lumped L2 norm")


def tresca_case(h: float = 1 / 20):
    """(name, make_problem, relative_error, rho_0 values) for contact Example 1 with Tresca friction (s = 2).

    Full mode (x = u), the error in the energy norm against an independent
    second-order-cone solve (cvxpy + Clarabel, :mod:`admmkit.problems.contact.solvers.tresca_qp`).
    """
    from admmkit.problems.contact.model.assembly import assemble
    from admmkit.problems.contact.solvers.problem import contact_problem
    from admmkit.problems.contact.model.scene_file import load_scene
    from admmkit.problems.contact.solvers.tresca_qp import tresca_cvxpy
    ops = assemble(load_scene("ex1_tresca", h=h))
    u_ref = tresca_cvxpy(ops)[0]

    def error(problem, x):
        return problem.x_distance(x, u_ref) / problem.x_norm(u_ref)
    return (f"contact Ex.1 + Tresca (s = 2), h = 1/{round(1 / h)}",
            lambda: contact_problem(ops, mode="full"), error, tuple(10.0 ** j for j in range(-4, 9)), "energy norm")


#: the problems of the study: name -> (builder of the (name, make, error, rho_0 values, norm) tuple)
PROBLEMS = {"contact": contact_case, "obstacle": obstacle_case, "tresca": tresca_case,
            "contact_ex2": lambda h: contact_case(h, example=2)}
DEFAULT_H = {"contact": 1 / 20, "obstacle": 1 / 16, "tresca": 1 / 20, "contact_ex2": 1 / 20}
QUICK_H = {"contact": 1 / 10, "obstacle": 1 / 4, "tresca": 1 / 10, "contact_ex2": 1 / 10}
#: the problems of ``bench policies`` (Example 2 is swept by ``bench rules``)
STUDY_PROBLEMS = ("contact", "obstacle", "tresca")


def build_cases(rules=RULES, orders=ORDERS, *, quick: bool = False, max_iter: int = MAX_ITER,
                problems=STUDY_PROBLEMS) -> list[dict]:
    """One case per (problem, rule, order, rho_0); the cases of one problem form a group."""
    unknown = [p for p in problems if p not in PROBLEMS]
    if unknown or not problems:
        raise ValueError(f"problems must be among {', '.join(PROBLEMS)}, got {list(problems)!r}")
    cases = []
    for problem in problems:
        h = (QUICK_H if quick else DEFAULT_H)[problem]
        decades = range(-6, 7) if problem == "obstacle" else range(-4, 9)
        rhos = [10.0 ** j for j in decades]
        if quick:
            rhos = [rhos[0], rhos[6], rhos[-1]]
        for rule in rules:
            for order in orders:
                for rho0 in rhos:
                    cases.append({"target": "policies", "problem": problem, "h": h, "rule": rule, "order": order,
                                  "rho0": rho0, "max_iter": max_iter, "oracle": ORACLE, "tol": TOL,
                                  "policy_version": policy_version(method_label(rule, "zx")),
                                  "group": f"{problem}-h{h:.6g}"})
    return cases


def case_cost(case: dict) -> float:
    """Unknowns of the problem, roughly (the cheaper problem starts first)."""
    return (4.0 if case["problem"] == "obstacle" else 1.0) / case["h"] ** 2


_CASES: dict = {}


def run_case(case: dict) -> dict:
    """Worker entry point: one rule, order and rho_0 on one problem, to the oracle's stop (one row)."""
    key = (case["problem"], case["h"])
    if key not in _CASES:
        _CASES.clear()          # one problem (and its reference) per worker at a time
        _CASES[key] = PROBLEMS[case["problem"]](case["h"])
    name, make, error, _, _ = _CASES[key]
    problem = make()
    paper = {}

    def watch(rec):
        err = error(problem, rec.x)
        if not paper and rec.x_change <= case["tol"] * rec.x_norm:
            paper.update(iterations=rec.k + 1, error=err)
        return err <= case["oracle"]
    start = time.perf_counter()
    res = admmkit.solve(problem, rho=case["rho0"], policy=case["rule"], order=case["order"],
                        stop=RelativeChange(1e-300), max_iter=case["max_iter"], callback=watch,
                        acceleration=case.get("acceleration"))
    seconds = time.perf_counter() - start
    return {"case": name, "rule": case["rule"], "order": case["order"], "rho0": case["rho0"],
            "reached": res.status.value == "stopped", "iterations": res.iterations, "seconds": seconds,
            "status": res.status.value, "factorizations": res.factorizations or 0, "rho_changes": res.rho_changes,
            "rho_final": res.rho, "paper_iterations": paper.get("iterations", math.nan),
            "paper_error": paper.get("error", math.nan)}


def _row(result: dict) -> dict:
    """A result as a table row (JSON keeps NaN; None from other writers becomes NaN)."""
    row = dict(result)
    for k in ("paper_iterations", "paper_error"):
        if row.get(k) is None:
            row[k] = math.nan
    return row


def table(rows: list[dict], key: str) -> list[str]:
    """Markdown table: one line per rule/order, one column per rho_0 (* = error 1e-6 not reached)."""
    rhos = sorted({r["rho0"] for r in rows})
    lines = ["| rule | order | " + " | ".join(f"{x:.0e}" for x in rhos) + " | max |",
             "|---|---|" + "---|" * (len(rhos) + 1)]
    for rule, order in dict.fromkeys((r["rule"], r["order"]) for r in rows):
        sel = {r["rho0"]: r for r in rows if r["rule"] == rule and r["order"] == order}
        cells = ["" if x not in sel else f"{sel[x][key]}" + ("" if sel[x]["reached"] else "*") for x in rhos]
        lines.append(f"| {rule} | {order} | " + " | ".join(cells) + f" | {max(r[key] for r in sel.values())} |")
    return lines


def markdown(results: dict, command: str, max_iter: int = MAX_ITER) -> str:
    """The report: per case, the iteration and factorisation tables and the paper's rule's stop."""
    out = ["# Penalty rules on the finite element problems across rho_0", "",
           f"Command (from the repository root): `{command}`", "",
           f"Each run stops when the relative error against the reference (cvxpy + Clarabel on the same discrete "
           f"problem) is at most {ORACLE:g} in the problem's x norm, or at {max_iter} iterations (* = not reached).  "
           "Each run builds a fresh problem, so the factorisations are those of this run (one per distinct rho: "
           "the plug-ins cache them).  The last table is the paper's stopping rule (relative change "
           f"{TOL:g}) in the same runs: where it would have fired and the error there.  Per-run data in "
           "`sweep.csv`.", "", "![sweep](sweep.png)", ""]
    for name, (rows, norm) in results.items():
        out += [f"## {name}", "", f"**Iterations to a relative error of {ORACLE:g} ({norm})**", ""]
        out += table(rows, "iterations")
        out += ["", "**Factorisations until then**", ""] + table(rows, "factorizations")
        out += ["", f"**The paper's rule (relative change {TOL:g}) in the same runs: how often it would have "
                f"fired with an error above {FALSE_STOP:g}, and the worst case**", "",
                f"| rule | order | fired with error > {FALSE_STOP:g} | worst error | at rho_0 | fired at iteration |",
                "|---|---|---|---|---|---|"]
        for rule, order in dict.fromkeys((r["rule"], r["order"]) for r in rows):
            sel = [r for r in rows if r["rule"] == rule and r["order"] == order]
            fired = [r for r in sel if not math.isnan(r["paper_error"])]
            if not fired:
                out.append(f"| {rule} | {order} | never fired | - | - | - |")
                continue
            worst = max(fired, key=lambda r: r["paper_error"])
            early = sum(1 for r in fired if r["paper_error"] > FALSE_STOP)
            out.append(f"| {rule} | {order} | {early} of {len(sel)} rho_0 | {worst['paper_error']:.1e} | "
                       f"{worst['rho0']:.0e} | {worst['paper_iterations']} |")
        out.append("")
    return "\n".join(out)


def plot(results: dict, stem: Path) -> list[Path]:
    """Iterations and factorisations against rho_0, one row of panels per case (PNG and SVG)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(len(results), 2, figsize=(12, 4.2 * len(results)), squeeze=False)
    for i, (name, (rows, _)) in enumerate(results.items()):
        rules = list(dict.fromkeys(r["rule"] for r in rows))
        for j, key in enumerate(("iterations", "factorizations")):
            ax = axes[i][j]
            for c, rule in enumerate(rules):
                for order, style in (("xz", "-"), ("zx", "--")):
                    sel = sorted((r for r in rows if r["rule"] == rule and r["order"] == order),
                                 key=lambda r: r["rho0"])
                    if sel:
                        ax.loglog([r["rho0"] for r in sel], [max(r[key], 1) for r in sel], style, marker="o",
                                  markersize=3, color=plt.cm.tab10(c % 10), label=f"{rule} ({order})")
            ax.set_xlabel("rho_0")
            ax.set_ylabel(key)
            ax.set_title(f"{name}: {key}")
            ax.grid(True, which="both", alpha=0.3)
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="center right", fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0, 0.83, 1))
    from admmkit.io import atomic_path
    paths = []
    for ext in ("png", "svg"):
        paths.append(stem.with_suffix(f".{ext}"))
        with atomic_path(paths[-1]) as tmp:
            fig.savefig(tmp, dpi=110)
    plt.close(fig)
    return paths


def run(out="out/policies", rules=RULES, quick: bool = False, command: str = "",
        progress: bool = True, max_iter: int = MAX_ITER, *, workers: int = 2, executor: Executor | None = None,
        report_only: bool = False, problems=STUDY_PROBLEMS) -> dict:
    """Run (or resume) the sweep of both problems (``quick``: coarser meshes, three rho_0) and write the report.

    ``problems``: a subset of ("contact", "obstacle", "tresca"); ``executor``: where the cases run.

    Returns {problem name: (rows, norm name)}.
    """
    from admmkit.benchmarks.runner.sweep import finished
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    cases = build_cases(rules, quick=quick, max_iter=max_iter, problems=problems)
    if report_only:
        records = finished(cases, out / "results.jsonl")
    else:
        records = run_sweep(cases, "admmkit.benchmarks.policies.study:run_case", out / "results.jsonl", workers=workers,
                            executor=executor, progress=progress, cost=case_cost,
                            label=lambda c: f"{c['problem']} {c['rule']}/{c['order']} rho0={c['rho0']:g}")
    norms = {"contact": "energy norm", "obstacle": "lumped L2 norm", "tresca": "energy norm"}
    results = {}
    for c in cases:   # the cases' order: problem, rule, order, rho_0
        rec = records.get(_id(c))
        if rec is None or rec.get("result") is None:
            continue
        row = _row(rec["result"])
        results.setdefault(row["case"], ([], norms[c["problem"]]))[0].append(row)
    harness = harness_failures(records)
    failed = [r for r in records.values() if r.get("error") and not is_harness_failure(r)]
    rows = [r for rs, _ in results.values() for r in rs]
    if not rows:
        check_harness(harness, len(cases), left_out="no table written")
        if report_only:
            raise ValueError(f"--report-only: {out / 'results.jsonl'} holds no finished case of this grid; run the "
                             "same command without --report-only first")
        raise RuntimeError(f"no case of the policies sweep finished; see {out / 'results.jsonl'}")
    files = [write_csv(out / "sweep.csv", rows), *plot(results, out / "sweep")]
    text = markdown(results, command, max_iter)
    if failed or len(records) < len(cases):
        text += (f"\n**{len(cases) - len(records)} cases not run, {len(failed)} raised in the rule's own code** "
                 "(their errors are in results.jsonl).\n")
    if harness:
        text += (f"\n**{len(harness)} cases failed in the harness** ({first_line(harness[0]['error'])}): not runs of "
                 "the rules, left out of the tables (the same command runs them again).\n")
    files.append(write_text(out / "README.md", text))
    if progress:
        print(text)
    check_harness(harness, len(cases), files, left_out="left out of the tables")
    return results


def _id(case: dict) -> str:
    from admmkit.benchmarks.runner.sweep import case_id
    return case_id(case)
