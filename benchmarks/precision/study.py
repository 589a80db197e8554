"""Work-precision: true error against time for every method and peer.

    admmkit bench precision [--out docs/results/bench/precision] [--quick] [--workers 2] [--repeats 3]

For each problem (contact Ex. 1 and Ex. 2 and the radial obstacle at h =
1/20 ... 1/160, four QPs) every ADMM method (every registered policy in both
orders, :mod:`admmkit.benchmarks.fixtures.methods`) runs from rho_0 = rho_scale *
rho_unit (rho_unit = E for contact, 1 otherwise) through a ladder of Boyd
residual tolerances 1e-1 ... 1e-10 (:mod:`admmkit.benchmarks.fixtures.admm_runs`), and
every peer (:mod:`admmkit.benchmarks.fixtures.peers`) through its own ladder.  Each
point is (median CPU time of the process, true relative error of the answer
against the reference solution, in the norm of :mod:`admmkit.benchmarks.fixtures.families`).
CPU time, not wall time: the machine is shared, and with one BLAS thread per
process the CPU time is the work done whatever the load (the wall times are in
precision.csv too).

Written to ``out``: ``results.jsonl`` (the sweep's raw records: resumable),
``precision.csv`` (one row per point), ``time_to_error.{csv,md}`` (time to a
relative error of 1e-4 and 1e-8 and its ratio to the fastest method on the
same problem), ``precision_<scene>.{png,svg}`` (log-log error against time,
one curve per method, one panel per mesh size) and ``README.md`` with the
command, the references and the machine.
"""
from __future__ import annotations

import os
from pathlib import Path


from admmkit.benchmarks.fixtures import methods as methods_mod
from admmkit.benchmarks.fixtures.peers import PEERS, applicable, run_peer
from admmkit.benchmarks.fixtures.families import (CACHE_ENV, CONTACT_SCENES, OBSTACLE_SCENES, QP_SCENES, discrete, kind_of, mm_folder,
                       problem_key)
from admmkit.benchmarks.runner.harness import check_harness, check_something_left, without_harness_failures
from admmkit.benchmarks.runner.sweep import Executor, run_or_report
from admmkit.benchmarks.precision.report import _problem_label, summarise

HS = (1 / 20, 1 / 40, 1 / 80, 1 / 160)
QUICK_HS = (1 / 10,)


def build_cases(scenes, hs, admm: list[str], peers=PEERS, *, rho_scale: float = 1.0, repeats: int = 3,
                max_iter: int = 20_000, time_limit: float = 60.0) -> list[dict]:
    """Every (problem, solver) case of the work-precision sweep."""
    cases = []
    for scene in scenes:
        kind = kind_of(scene)
        for h in (hs if kind != "qp" else (None,)):
            base = {"target": "precision", "scene": scene, "h": h, "clock": "cpu"}
            if kind == "qp":
                base["reference"] = "clarabel+polish"     # the QP reference changed: these cases are re-run
            group = problem_key(base)
            common = {"repeats": repeats, "group": group}
            for label in admm:
                cases.append(base | common | {"solver": "admm", "method": label, "rho_scale": rho_scale,
                                              "policy_version": methods_mod.policy_version(label),
                                              "max_iter": max_iter, "time_limit": time_limit})
            for peer in peers:
                if applicable(peer, kind):
                    cases.append(base | common | {"solver": "peer", "method": peer, "max_iter": max_iter,
                                                  "time_limit": time_limit})
    return cases


def case_cost(case: dict) -> float:
    """A rough relative cost (the sweep starts the cheap problems first)."""
    h = case.get("h") or 0.1
    scale = {"contact": 1.0, "obstacle": 8.0, "qp": 0.2}[kind_of(case["scene"])]
    return scale / h**2


def run_case(case: dict) -> dict:
    """Worker entry point: one solver on one problem."""
    from admmkit.benchmarks.fixtures.admm_runs import ladder_run
    d = discrete(case, cache_dir=os.environ.get(CACHE_ENV))
    info = {"n": d.n, "norm": d.norm_name, **{k: v for k, v in d.info.items() if k not in ("n",)}}
    if case["solver"] == "admm":
        out = ladder_run(d, case["method"], case["rho_scale"] * d.rho_unit, max_iter=case["max_iter"],
                         time_limit=case["time_limit"], repeats=case["repeats"])
    else:
        out = run_peer(d, case["method"], repeats=case["repeats"], time_limit=case["time_limit"],
                       max_iter=case["max_iter"])
    out["problem"] = info
    out["reference"] = d.ref_info
    if d.floor is not None and "discretisation_error_L2" in d.ref_info:
        out["floor_rel"] = d.ref_info["discretisation_error_L2"] / max(d.x_norm(d.ref_x), 1e-300)
    return out


def run(out="out/precision", *, quick: bool = False, workers: int = 2, repeats: int = 3,
        scenes=None, hs=None, methods=None, progress: bool = True, command: str = "admmkit bench precision",
        time_limit: float = 60.0, report_only: bool = False, executor: Executor | None = None) -> list[Path]:
    """Build the cases, run (or resume) the sweep, write the summaries; return the files written.

    ``executor``: where the cases run (:class:`admmkit.benchmarks.runner.sweep.Executor`; default ``workers`` local processes).
    """
    out = Path(out)
    if scenes is None:
        scenes = list(CONTACT_SCENES + OBSTACLE_SCENES) + [s for s in QP_SCENES
                                                           if s == "qp:random-mixed" or mm_folder() is not None]
        if quick:
            scenes = ["ex1", "radial", "qp:random-mixed"]
    hs = hs or (QUICK_HS if quick else HS)
    admm = list(methods) if methods is not None else methods_mod.admm_methods()
    cases = build_cases(scenes, hs, admm, repeats=repeats, time_limit=time_limit,
                        max_iter=2000 if quick else 20_000)
    if quick:
        cases = [c for c in cases if c["scene"] != "qp:random-mixed" or c["solver"] == "peer"
                 or c["method"] in ("admm1", "sadmm")]
    records, wall = run_or_report(cases, "admmkit.benchmarks.precision.study:run_case", out, report_only=report_only,
                                  env={CACHE_ENV: str(out / "cache")}, workers=workers, executor=executor,
                                  progress=progress, cost=case_cost, label=lambda c: f"{_problem_label(c)} {c['method']}")
    kept, failed = without_harness_failures(records)      # a harness failure is no outcome of a method
    check_something_left(kept, failed, len(cases), out / "results.jsonl", report_only)
    files = summarise(kept, out, command=command, wall=wall, skipped=methods_mod.skipped_policies(),
                      missing=len(cases) - len(kept))
    check_harness(failed, len(cases), files, left_out="left out of the summary, counted as not run")
    return files

