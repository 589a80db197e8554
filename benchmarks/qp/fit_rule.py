"""Fit the rule ``fitted`` (:class:`admmkit.policies.fitted.FittedRowwise`) on the training split, then check it on the test split.

    python -m admmkit.benchmarks.qp.fit_rule --data /work/shared/data/maros_meszaros --out docs/results/qp_fitted

The split is qp_rules' (:func:`admmkit.benchmarks.qp.qp_rules_report.split` of
qpbenchmark's class, :func:`~admmkit.benchmarks.qp.qp_rules_report.qp_class`:
86 convex problems with n + m <= 3000, sorted by name, every other one from
the first for training, 43 each).

1. The fit: every configuration of :data:`GRID` (alpha, beta, interval,
   tolerance of the rule; the first is ``rowwise``'s own constants) on the
   training problems only, in admmkit's preset (``admmkit_settings()``:
   OSQP's machinery, cap 100,000, polishing during the run), with the harness
   of ``admmkit bench rules`` (:func:`admmkit.benchmarks.qp.maros_meszaros_runs.run_admmkit`:
   eps_abs = eps, eps_rel = 0, 5 CPU s, one run per eps since the preset
   polishes, success by qpbenchmark's criteria).  Score: problems solved over
   both eps, then the shifted geometric mean (shift 10) of iterations over the
   runs every configuration solved.  The best is ``chosen``.
2. The check: ``chosen`` on the test problems only, beside ``rowwise`` (the
   preset's rule, as ``solve_qp`` runs it) and OSQP's rule in the same preset.

Every rule runs on OSQP's normalisation of the scaled QP and OSQP's clamp of
rho, as the preset's runs it (:func:`RuleBuilder`).  Writes to ``--out``:
``grid.csv``, ``grid.md`` (the fit), ``test.csv``, ``test.md`` (the check),
each whole (a temporary file, then ``os.replace``), and the runs in
``grid_runs/results.jsonl`` and ``test_runs/results.jsonl`` (a sweep: an
interrupted fit resumes where it stopped).  It prints the progress and the
tables.  The command changes no default: the constants in policies/fitted.py
are written there by hand from ``grid.md``.
"""
from __future__ import annotations

import argparse
import csv
import io
import math
import sys
from dataclasses import dataclass
from pathlib import Path

from admmkit.io import write_text
from admmkit.benchmarks.qp.maros_meszaros_stats import SHIFT, shifted_geometric_mean
from admmkit.benchmarks.qp.qp_rules_report import qp_class, split
from admmkit.benchmarks.qp.maros_meszaros_runs import DATA_ENV

#: the grid: name -> (alpha, beta, interval, tolerance); one constant moved at a time from ``rowwise``'s (the first)
GRID = {
    "rowwise": (0.5, 0.5, 50, 5.0),
    "beta=0.25": (0.5, 0.25, 50, 5.0),
    "beta=0.75": (0.5, 0.75, 50, 5.0),
    "beta=1": (0.5, 1.0, 50, 5.0),
    "alpha=0.35": (0.35, 0.5, 50, 5.0),
    "alpha=0.7": (0.7, 0.5, 50, 5.0),
    "tolerance=3": (0.5, 0.5, 50, 3.0),
    "tolerance=10": (0.5, 0.5, 50, 10.0),
    "interval=25": (0.5, 0.5, 25, 5.0),
    "interval=100": (0.5, 0.5, 100, 5.0),
}
PARAMS = ("alpha", "beta", "interval", "tolerance")
EPS = (1e-3, 1e-6)
TIME_LIMIT = 5.0


@dataclass(frozen=True)
class RuleBuilder:
    """A rule made for each run's QP, as ``solve_qp`` makes its named ones (OSQP's normalisation and clamp).

    ``kind``: "fitted" (:class:`FittedRowwise` with ``params``), "rowwise" (the preset's rule) or "osqp"
    (OSQP's rule, one rho).  Called by :func:`admmkit.benchmarks.qp.maros_meszaros_runs.run_admmkit`.
    """

    name: str
    kind: str
    params: tuple = ()

    def __call__(self, qp, settings):
        """The policy for a run on ``qp`` (the scaled QP the run iterates on) with ``settings``."""
        from admmkit.problems.qp.solve import RHO_MAX, RHO_MIN, default_policy
        from admmkit.problems.qp.termination import osqp_relative_residuals
        if self.kind == "rowwise":
            return default_policy(qp, settings, "rowwise")
        if self.kind == "osqp":
            return default_policy(qp, settings.replace(adaptive_rho="interval"), "osqp")
        from admmkit.policies.fitted import FittedRowwise
        return FittedRowwise(**dict(zip(PARAMS, self.params)), rho_min=RHO_MIN, rho_max=RHO_MAX,
                             residuals=osqp_relative_residuals(qp))


# ---------------------------------------------------------------- the split
def split_of(data: Path) -> dict[str, list[str]]:
    """{"train": [...], "test": [...]}: qpbenchmark's class in ``data``, sorted by name, split as qp_rules' was."""
    halves = split(qp_class(Path(data)))
    return {part: sorted(n for n, p in halves.items() if p == part) for part in ("train", "test")}


def build_cases(problems, configs: dict[str, RuleBuilder], eps=EPS, time_limit: float = TIME_LIMIT) -> list[dict]:
    """One case per (problem, configuration); a problem's cases form a group (it is loaded once)."""
    return [{"group": p, "problem": p, "file": f"{p}.mat", "config": name, "kind": b.kind, "params": list(b.params),
             "eps": list(eps), "time_limit": time_limit} for p in problems for name, b in configs.items()]


def run_case(case: dict) -> dict:
    """Worker entry point: one configuration on one problem, in admmkit's preset; {"rows": one per eps}."""
    from admmkit.benchmarks.qp.maros_meszaros_runs import case_qp, run_admmkit, warm_qp_kernels
    warm_qp_kernels()
    rule = RuleBuilder(case["config"], case["kind"], tuple(case["params"]))
    rows = run_admmkit(case_qp(case["file"]), "admmkit", rule, "xz", tuple(case["eps"]), None, case["time_limit"])
    return {"rows": [{"problem": case["problem"], "config": case["config"], "eps": r["eps"],
                      "solved": bool(r["solved"]) and bool(r["neutral"]), "status": str(r["status"]),
                      "iterations": int(r["iterations"]), "time": float(r["time"])} for r in rows]}


def sweep(cases: list[dict], data: Path, folder: Path, workers: int, progress: bool) -> list[dict]:
    """Run ``cases`` (resuming ``folder/results.jsonl``) and return their rows; a failed case fails at every eps."""
    from admmkit.benchmarks.runner.sweep import run_sweep
    records = run_sweep(cases, f"{__name__}:run_case", folder / "results.jsonl", workers=workers, progress=progress,
                        env={DATA_ENV: str(Path(data).resolve()), "OMP_NUM_THREADS": "1"}, table=False,
                        label=lambda c: f"{c['config']} {c['problem']}")
    rows = []
    for rec in records.values():
        if rec.get("result") is not None:
            rows += rec["result"]["rows"]
        else:
            c = rec["case"]
            rows += [{"problem": c["problem"], "config": c["config"], "eps": e, "solved": False,
                      "status": (rec.get("error") or "error").split(":")[0], "iterations": math.nan,
                      "time": c["time_limit"]} for e in c["eps"]]
    return rows


# ---------------------------------------------------------------- the score
def solved_sets(rows: list[dict]) -> dict[str, dict[float, set[str]]]:
    """{config: {eps: problems solved}}."""
    out: dict[str, dict[float, set[str]]] = {}
    for r in rows:
        out.setdefault(r["config"], {}).setdefault(float(r["eps"]), set())
        if r["solved"]:
            out[r["config"]][float(r["eps"])].add(r["problem"])
    return out


def score_table(rows: list[dict], configs: list[str], eps=EPS, reference: str | None = None) -> list[dict]:
    """A line per configuration: solved per eps and in all, the shifted geometric mean of iterations over the runs
    every configuration solved, and the problems lost and gained against ``reference`` (default: the first)."""
    solved = solved_sets(rows)
    reference = reference or configs[0]
    common = {e: set.intersection(*(solved.get(c, {}).get(e, set()) for c in configs)) for e in eps}
    iters = {(r["config"], float(r["eps"]), r["problem"]): r["iterations"] for r in rows}
    table = []
    for c in configs:
        line = {"config": c}
        for e in eps:
            line[f"solved {e:g}"] = len(solved.get(c, {}).get(e, set()))
        line["solved"] = sum(line[f"solved {e:g}"] for e in eps)
        runs = [iters[(c, e, p)] for e in eps for p in common[e]]
        line["iterations (sgm)"] = shifted_geometric_mean(runs, SHIFT)
        line["common runs"] = len(runs)
        lost, gained = [], []
        for e in eps:
            mine, ref = solved.get(c, {}).get(e, set()), solved.get(reference, {}).get(e, set())
            lost += [f"{p} ({e:g})" for p in sorted(ref - mine)]
            gained += [f"{p} ({e:g})" for p in sorted(mine - ref)]
        line[f"lost vs {reference}"] = ", ".join(lost) or "none"
        line[f"gained vs {reference}"] = ", ".join(gained) or "none"
        table.append(line)
    return table


def best(table: list[dict]) -> str:
    """The configuration with the most solved runs, then the fewest iterations (shifted geometric mean); a tie
    keeps the earlier line (the first is ``rowwise``: a constant moves only where it pays)."""
    return min(table, key=lambda line: (-line["solved"], line["iterations (sgm)"]))["config"]


# ---------------------------------------------------------------- the files
def markdown(table: list[dict]) -> str:
    """The table as Markdown."""
    keys = list(table[0])
    cell = lambda v: f"{v:.4g}" if isinstance(v, float) else str(v)    # noqa: E731
    lines = ["| " + " | ".join(keys) + " |", "| " + " | ".join("---" for _ in keys) + " |"]
    lines += ["| " + " | ".join(cell(line[k]) for k in keys) + " |" for line in table]
    return "\n".join(lines) + "\n"


#: the pages' titles (a results page without a "# " title is not built by the docs, and a link to it breaks them)
TITLES = {"grid": "The fit of `fitted` on the training split", "test": "The check of `fitted` on the test split"}


def write_table(out: Path, stem: str, table: list[dict], heading: str) -> None:
    """``out/stem.csv`` and ``out/stem.md`` (titled from :data:`TITLES`), each written whole."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(table[0]), lineterminator="\n")
    w.writeheader()
    w.writerows(table)
    write_text(out / f"{stem}.csv", buf.getvalue())
    title = TITLES.get(stem, stem)
    write_text(out / f"{stem}.md", f"# {title}\n\n{heading}\n\n" + markdown(table))


def params_text(name: str) -> str:
    """"alpha=0.5, beta=0.5, interval=50, tolerance=5" of a grid configuration."""
    return ", ".join(f"{k}={v:g}" for k, v in zip(PARAMS, GRID[name]))


# ---------------------------------------------------------------- the command
def fit(data: Path, out: Path, *, grid=None, problems=None, confirm: bool = True, workers: int = 2,
        time_limit: float = TIME_LIMIT, progress: bool = True) -> dict:
    """The fit on the training split, then (``confirm``) the check on the test split; returns the tables and choice.

    ``grid``: names of :data:`GRID` (default all); ``problems``: a subset of the training split (default all of
    it; a test problem is refused).
    """
    halves = split_of(data)
    train = halves["train"]
    if problems is not None:
        bad = sorted(set(problems) - set(train))
        if bad:
            raise ValueError(f"problems must be of the training split, got {', '.join(bad)} "
                             f"(training: {', '.join(train)})")
        train = sorted(problems)
    names = list(GRID) if grid is None else list(grid)
    unknown = [n for n in names if n not in GRID]
    if unknown or not names:
        raise ValueError(f"grid must name configurations among {', '.join(GRID)}, got {', '.join(unknown) or 'none'}")
    out.mkdir(parents=True, exist_ok=True)
    configs = {n: RuleBuilder(n, "fitted", GRID[n]) for n in names}
    rows = sweep(build_cases(train, configs, time_limit=time_limit), data, out / "grid_runs", workers, progress)
    assert not {r["problem"] for r in rows} - set(train)          # the fit saw training problems only
    grid_table = [{"config": n, **dict(zip(PARAMS, GRID[n]))} | line for n, line in zip(names, score_table(rows, names))]
    chosen = best(grid_table)
    write_table(out, "grid", grid_table, f"The fit: {len(train)} training problems, eps {', '.join(f'{e:g}' for e in EPS)}, "
                                         f"admmkit's preset, {time_limit:g} CPU s a run; chosen: `{chosen}` "
                                         f"({params_text(chosen)})")
    print(f"\nfit on {len(train)} training problems; chosen: {chosen} ({params_text(chosen)})\n")
    print(markdown(grid_table))
    result = {"grid": grid_table, "chosen": chosen, "train": train}
    if confirm:
        test = halves["test"]
        check = {"fitted": RuleBuilder("fitted", "fitted", GRID[chosen]), "rowwise": RuleBuilder("rowwise", "rowwise"),
                 "osqp": RuleBuilder("osqp", "osqp")}
        rows = sweep(build_cases(test, check, time_limit=time_limit), data, out / "test_runs", workers, progress)
        test_table = score_table(rows, list(check), reference="rowwise")
        write_table(out, "test", test_table, f"The check: {len(test)} test problems, `fitted` = `{chosen}` "
                                             f"({params_text(chosen)}), beside the preset's rule `rowwise` and "
                                             f"OSQP's rule `osqp`, all in admmkit's preset")
        print(f"\ncheck on {len(test)} test problems\n")
        print(markdown(test_table))
        result |= {"test": test_table}
    return result


def main(argv=None) -> int:
    """The command line: ``python -m admmkit.benchmarks.qp.fit_rule --data DIR --out DIR``."""
    p = argparse.ArgumentParser(prog="python -m admmkit.benchmarks.qp.fit_rule", description=__doc__.split("\n")[0])
    p.add_argument("--data", required=True, type=Path, help="the folder of Maros-Meszaros MAT files")
    p.add_argument("--out", required=True, type=Path, help="the folder of the tables and runs")
    p.add_argument("--grid", default=None, help=f"comma-separated configurations (default all: {', '.join(GRID)})")
    p.add_argument("--problems", default=None, help="comma-separated training problems (default: the whole split)")
    p.add_argument("--no-confirm", action="store_true", help="fit only; do not run the test split")
    p.add_argument("--workers", type=int, default=2, help="local worker processes, 1 or 2 (default 2)")
    p.add_argument("--time-limit", type=float, default=TIME_LIMIT, help=f"CPU seconds a run (default {TIME_LIMIT:g})")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    args = p.parse_args(argv)
    split_list = lambda s: None if s is None else [x.strip() for x in s.split(",") if x.strip()]   # noqa: E731
    try:
        if not Path(args.data).is_dir():
            raise ValueError(f"--data must be a folder of MAT files, got {str(args.data)!r}")
        if args.workers not in (1, 2):
            raise ValueError(f"--workers must be 1 or 2 (a shared 2-core machine), got {args.workers}")
        if not (math.isfinite(args.time_limit) and args.time_limit > 0):
            raise ValueError(f"--time-limit must be a finite number of seconds > 0, got {args.time_limit:g}")
        fit(args.data, args.out, grid=split_list(args.grid), problems=split_list(args.problems),
            confirm=not args.no_confirm, workers=args.workers, time_limit=args.time_limit, progress=not args.quiet)
    except ValueError as err:
        print(f"admmkit: error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
