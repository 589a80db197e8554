"""Every penalty rule through every family, ranked: ``admmkit bench rules``.

    admmkit bench rules [--rules osqp,summable,path/to/my_rule.py:MyRule] [--acceleration none,anderson]
                        [--families qp,contact,obstacle,friction,framework,stability] [--quick]
                        [--data ../shared/data/maros_meszaros] [--out out/rules] [--workers 2 | --dask-workers 8]

A study is a grid, a case runner and a summary.  The grid (:func:`build_cases`)
puts each rule, with and without acceleration, in the setting where it
belongs, one family at a time:

- ``qp``: Maros-Meszaros with n + m <= 3000 (qpbenchmark's count: bound rows
  are not constraints; 86 convex problems) under OSQP's machinery, eps 1e-3
  and 1e-6 (quick: 6 small problems at 1e-3); ``--presets osqp,admmkit`` runs
  each rule in admmkit's preset too (``rule@admmkit``);
- ``contact``: Examples 1 and 2 (h = 1/20), rho_0 = 1e-4 ... 1e8, both
  orders (quick: h = 1/10, 3 rho_0);
- ``obstacle``: the radial obstacle (h = 1/16), rho_0 = 1e-6 ... 1e6, both
  orders (quick: h = 1/4, 3 rho_0);
- ``friction``: Example 1 with Tresca friction (h = 1/20), rho_0 as contact
  (quick: h = 1/10, 3 rho_0);
- ``framework``: LASSO, weighted box LS, consensus, TV, rho_0 = 1e-3, 1, 1e3,
  both orders (quick: the same);
- ``stability``: the paper's examples, rho_0/E = 1e-6 ... 1e6 (h = 1/40), and
  h, nu, P1/P2 (quick: Ex. 1, h = 1/10, 3 rho_0).

The case runner is :mod:`admmkit.benchmarks.rules.cases` (each family's
truthful "solved"), the summary :mod:`admmkit.benchmarks.rules.report`
(performance profiles, solved counts, robustness across rho_0, what
acceleration does, every failure).  The cases run on the one sweep runner
(``admmkit.benchmarks.runner.sweep``: local processes or Dask, resumable),
one results file for the whole suite.
"""
from __future__ import annotations

from pathlib import Path

import admmkit
from admmkit.loop.acceleration import ACCELERATORS
from admmkit.benchmarks.policies import study as policies_fe
from admmkit.benchmarks.stability import study as stability
from admmkit.benchmarks.fixtures.methods import method_label, per_row, policy_version
from admmkit.benchmarks.rules.cases import DATA_ENV
from admmkit.benchmarks.runner.sweep import Executor, run_or_report

FAMILIES = ("qp", "contact", "obstacle", "friction", "framework", "stability")
#: the Maros-Meszaros problems of the quick grid (small, solved by OSQP in a few hundred iterations or less)
QUICK_QP = ("HS21", "HS35", "HS118", "QAFIRO", "DUAL1", "QPCBLEND")
#: the full grid's Maros-Meszaros problems have n + m at most this
QP_MAX_SIZE = 3000
QP_EPS, QUICK_QP_EPS = (1e-3, 1e-6), (1e-3,)
QP_MAX_ITER, QP_TIME_LIMIT = 4000, 5.0
#: the QP settings presets of the option --presets, OSQP's (with OSQP's cap QP_MAX_ITER) and admmkit's own
#: (``admmkit.problems.qp.admmkit_settings``, with its own cap); a rule in a preset other than OSQP's is ranked
#: as ``rule@preset``
QP_PRESETS = ("osqp", "admmkit")
FRAMEWORK = ("lasso", "box_ls_weighted", "consensus_8", "tv_2d")
FRAMEWORK_RHO0 = (1e-3, 1.0, 1e3)
FRAMEWORK_MAX_ITER = 10_000
#: the default data folder of the qp family (beside the repository, as the README says)
DEFAULT_DATA = Path("../shared/data/maros_meszaros")


def accelerations(names) -> list[str | None]:
    """The acceleration labels ("none", "anderson", "fast") as solve() takes them (None for "none")."""
    out = []
    for name in names:
        key = str(name).strip().lower()
        if key not in ("none", *ACCELERATORS):
            raise ValueError(f"--acceleration: unknown {name!r}; choose among none, {', '.join(ACCELERATORS)}")
        out.append(None if key == "none" else key)
    if not out or len(set(out)) != len(out):
        raise ValueError(f"--acceleration: give each of none, {', '.join(ACCELERATORS)} at most once, at least one; "
                         f"got {list(names)!r}")
    return out


def qp_size(P, A) -> int:
    """n + m as qpbenchmark counts a Maros-Meszaros problem: the rows of A with one entry are bounds on a variable
    (qpbenchmark's lb <= x <= ub), not constraints."""
    import numpy as np
    import scipy.sparse as sp
    return int(P.shape[0] + np.count_nonzero(np.diff(sp.csr_matrix(A).indptr) > 1))


def qp_files(data: Path, quick: bool) -> list[Path]:
    """The Maros-Meszaros files of the grid: the quick six, or every convex one with n + m <= QP_MAX_SIZE (qpbenchmark's
    count, :func:`qp_size`: 86 problems, VALUES left out as not convex)."""
    from admmkit.benchmarks.qp.maros_meszaros import skip_reason
    from admmkit.problems.qp.mat import list_problems, read_matrices
    if quick:
        return [data / f"{name}.mat" for name in QUICK_QP if (data / f"{name}.mat").exists()]
    files = []
    for path in list_problems(data):
        try:
            P, A = read_matrices(path)
        except ValueError:
            continue                                   # unreadable: bench qp lists it
        if qp_size(P, A) <= QP_MAX_SIZE and skip_reason(path) is None:
            files.append(path)
    return files


def build_cases(rules, accel, families=FAMILIES, *, quick: bool = False, data: Path | None = None,
                presets=("osqp",)) -> list[dict]:
    """One case per (family, problem, rule, acceleration, order, rho_0) (and QP preset); a problem's cases form a
    group."""
    cases = []
    versions = {rule: policy_version(method_label(rule, "zx")) for rule in rules}
    for family in families:
        takes = rules if family == "qp" else [r for r in rules if not per_row(r)]    # one rho outside the QPs
        for base in _problem_cases(family, takes, quick, data, presets):
            for a in accel:
                cases.append(base | {"family": family, "acceleration": a, "policy_version": versions[base["rule"]],
                                     "group": f"{family}:{base['group']}"})
    return cases


def _problem_cases(family: str, rules, quick: bool, data: Path | None, presets=("osqp",)) -> list[dict]:
    """The family's cases for every rule, without acceleration (its own study's grid where it has one)."""
    if family in ("contact", "obstacle", "friction"):
        problems = {"contact": ("contact", "contact_ex2"), "obstacle": ("obstacle",), "friction": ("tresca",)}[family]
        return policies_fe.build_cases(tuple(rules), quick=quick, problems=problems)
    if family == "stability":
        labels = {method_label(r, o): (r, o) for r in rules for o in ("xz", "zx")}
        grid = ({"examples": ("ex1",), "rho_scales": (1e-3, 1.0, 1e3), "rho_h": 1 / 10, "mesh_hs": (), "max_iter": 5000}
                if quick else {"mesh_hs": (1 / 20, 1 / 80), "nus": (0.3, 0.499)})
        cases = stability.build_cases(list(labels), **grid)
        return [c | {"rule": labels[c["method"]][0], "order": labels[c["method"]][1]} for c in cases]
    if family == "framework":
        return [{"problem": p, "rule": r, "order": o, "rho0": rho0, "max_iter": FRAMEWORK_MAX_ITER, "group": p}
                for p in FRAMEWORK for r in rules for o in ("xz", "zx") for rho0 in FRAMEWORK_RHO0]
    if family == "qp":
        eps = list(QUICK_QP_EPS if quick else QP_EPS)
        return [{"problem": f.stem, "file": f.name, "rule": r, "order": "xz", "eps": eps,
                 "max_iter": QP_MAX_ITER if p == "osqp" else None, "time_limit": QP_TIME_LIMIT, "group": f.stem}
                | ({} if p == "osqp" else {"preset": p}) for f in qp_files(data, quick) for r in rules for p in presets]
    raise ValueError(f"--families: unknown {family!r}; choose among {', '.join(FAMILIES)}")


def check_rules(rules) -> list[str]:
    """The rules as the cases name them, each built once here: a broken rule is refused before any case runs."""
    from admmkit.policy import canonical_spec, is_spec
    out = [canonical_spec(r) if is_spec(r) else r for r in rules]
    unknown = [r for r in out if not is_spec(r) and r not in admmkit.policy_names()]
    if unknown or not out:
        raise ValueError(f"--rules: unknown {unknown}; known: {', '.join(admmkit.policy_names())}, or "
                         f"module:Class or path/to/file.py:Class")
    for rule in out:
        try:
            admmkit.make_policy(rule)
        except (TypeError, ValueError) as err:
            raise ValueError(f"--rules: {err}") from None
    return out


def case_cost(case: dict) -> float:
    """A rough cost, so that the cheap families run (and report) first."""
    if "h" in case:
        return 1.0 / case["h"] ** 2
    return 50.0 if case["family"] == "qp" else 10.0


def label(case: dict) -> str:
    """The progress line's name of a case."""
    where = case.get("rho0", case.get("rho_scale", ""))
    return (f"{case['family']} {case.get('problem', case.get('scene', ''))} {case['rule']}/{case['order']} "
            f"{case['acceleration'] or ''} {where}")


def check_presets(presets) -> list[str]:
    """The QP presets of --presets, each known and given once; ValueError naming the option otherwise."""
    out = [str(p).strip().lower() for p in presets]
    if not out or len(set(out)) != len(out) or any(p not in QP_PRESETS for p in out):
        raise ValueError(f"--presets: give each of {', '.join(QP_PRESETS)} at most once, at least one; "
                         f"got {list(presets)!r}")
    return out


def run(out="out/rules", *, rules=None, acceleration=("none", "anderson"), families=FAMILIES, quick: bool = False,
        data=None, presets=("osqp",), command: str = "admmkit bench rules", progress: bool = True, report_only: bool = False,
        executor: Executor | None = None) -> list[Path]:
    """Build the grid, run (or resume) it, and write the ranking (returns the files written)."""
    from admmkit.benchmarks.rules.report import summarise
    out = Path(out)
    rules = check_rules(rules if rules is not None else admmkit.policy_names())
    accel = accelerations(acceleration)
    presets = check_presets(presets)
    families = list(families)
    if not families:
        raise ValueError(f"--families: give at least one of {', '.join(FAMILIES)}")
    for f in families:
        if f not in FAMILIES:
            raise ValueError(f"--families: unknown {f!r}; choose among {', '.join(FAMILIES)}")
    notes = []
    data_dir = Path(data) if data is not None else DEFAULT_DATA
    if "qp" in families and not data_dir.is_dir():
        if data is not None:
            raise ValueError(f"--data: folder of Maros-Meszaros MAT files not found: {data_dir}")
        families.remove("qp")
        notes.append(f"qp left out: no Maros-Meszaros folder at {DEFAULT_DATA} (give --data DIR)")
    rows_only = [r for r in rules if per_row(r)]
    if rows_only and any(f != "qp" for f in families):
        notes.append(f"{', '.join(rows_only)}: a penalty per row, run on the qp family only (the other families' "
                     "problems take one rho)")
    cases = build_cases(rules, accel, families, quick=quick, data=data_dir.resolve(), presets=presets)
    records, wall = run_or_report(cases, "admmkit.benchmarks.rules.cases:run_case", out, report_only=report_only,
                                  env={DATA_ENV: str(data_dir.resolve()), stability.CACHE_ENV: str(out / "cache")},
                                  executor=executor or Executor(), progress=progress, cost=case_cost, label=label)
    if not records:
        raise ValueError(f"--report-only: {out / 'results.jsonl'} holds no finished case of this grid; run the "
                         "same command without --report-only first")
    return summarise(records, out, command=command, wall=wall, notes=notes, missing=len(cases) - len(records),
                     families=families)
