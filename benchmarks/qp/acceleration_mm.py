"""Plain ADMM against an accelerator on the Maros-Meszaros problems: which problems each solves, gained and lost.

    python -m admmkit.benchmarks.qp.acceleration_mm --out docs/results/fast_cost

Every problem of ``--data`` with n + m <= ``--max-size`` (3000: 78 problems;
VALUES is not convex and ``solve_qp`` refuses it, 77 remain) is solved with
OSQP's preset (``solve_qp``'s defaults, max_iter 4000, a CPU-time limit that
is never reached) at eps_abs = eps_rel = 1e-3 and 1e-6, compiled, once plain
and once with each accelerator of ``--configs``::

    plain                 acceleration=None
    fast                  acceleration=FastADMM()           (the safeguarded default)
    fast:patience=0       acceleration=FastADMM(patience=0) (no back-off: the restarts alone)
    fast:give_up=0        acceleration=FastADMM(give_up=0)  (the back-off without the global fallback (A7))
    anderson:interval=10  acceleration=Anderson(interval=10)

Writes ``maros_meszaros.csv`` (one row per problem, accuracy and configuration:
status, iterations, the accelerator's counts) and ``maros_meszaros.md`` (solved
counts, problems gained and lost against plain, iterations on the problems both
solve) under ``--out``.  One process, BLAS on one thread; the statuses and
iteration counts do not depend on the machine's load.
"""
from __future__ import annotations

import math
import os
import shlex
import sys
import time
from pathlib import Path

#: the accuracies (eps_abs = eps_rel) every configuration is run at
EPS = (1e-3, 1e-6)
#: the configurations run by default: plain, the safeguarded fast ADMM, and fast ADMM without its back-off
CONFIGS = ("plain", "fast", "fast:patience=0")
COLUMNS = ("problem", "n", "m", "eps", "config", "status", "iterations", "seconds", "extrapolated", "restarts",
           "rejected")
#: a solve that converged (the tolerance asked is met)
SOLVED = "solved"


def accelerator(config: str):
    """The ``acceleration`` argument of ``solve_qp`` for a configuration ``name[:key=value,...]`` (see the module
    docstring); a ValueError naming the configuration for anything else."""
    from admmkit.loop.acceleration import ACCELERATORS
    name, _, options = config.partition(":")
    if name == "plain" and not options:
        return None
    if name not in ACCELERATORS:
        raise ValueError(f"configuration {config!r}: the name must be plain or one of {', '.join(ACCELERATORS)}")
    kwargs = {}
    for item in filter(None, options.split(",")):
        key, eq, value = item.partition("=")
        if not eq:
            raise ValueError(f"configuration {config!r}: options are key=value, got {item!r}")
        try:
            kwargs[key.strip()] = float(value) if any(ch in value for ch in ".e") else int(value)
        except ValueError:
            raise ValueError(f"configuration {config!r}: {value!r} is not a number") from None
    try:
        return ACCELERATORS[name](**kwargs)
    except (TypeError, ValueError) as err:
        raise ValueError(f"configuration {config!r}: {err}") from None


def _load_any(path: Path):
    """The QP of a MAT file, a non-convex one too (without the warning: only its size is read from it)."""
    import warnings
    from admmkit.problems.qp import load_mat
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return load_mat(path, allow_nonconvex=True)


def problems(data: Path, max_size: int) -> list[tuple[str, Path]]:
    """(name, path) of the MAT files of ``data`` whose n + m is at most ``max_size``, by name (a non-convex one too:
    :func:`run` reports it refused)."""
    chosen = []
    for path in sorted(data.glob("*.mat")):
        qp = _load_any(path)
        if qp.n + qp.m <= max_size:
            chosen.append((path.stem, path))
    return chosen


def run(path: Path, eps: float, config: str, max_iter: int, time_limit: float) -> dict:
    """One solve: its status (``solved`` when it converged, else its termination), iterations, CPU seconds and the
    accelerator's counts; status ``refused`` with the message where ``solve_qp`` refuses the problem."""
    from admmkit.problems.qp import load_mat, solve_qp
    size = _load_any(path)
    row = {"problem": path.stem, "n": size.n, "m": size.m, "eps": eps, "config": config}
    t0 = time.process_time()
    try:
        res = solve_qp(load_mat(path), eps_abs=eps, eps_rel=eps, max_iter=max_iter, time_limit=time_limit, compiled=True,
                       acceleration=accelerator(config))
    except ValueError as err:
        return {**row, "status": "refused", "iterations": 0, "seconds": 0.0, "note": str(err)}
    counts = res.acceleration or {}
    status = SOLVED if res.converged else (res.termination or str(res.status))
    return {**row, "status": status, "iterations": res.iterations, "seconds": time.process_time() - t0,
            **{k: counts.get(k, "") for k in ("extrapolated", "restarts", "rejected")}}


def geometric_mean(values) -> float:
    """The geometric mean of positive numbers (NaN for none)."""
    values = list(values)
    return math.exp(sum(math.log(v) for v in values) / len(values)) if values else math.nan


def report(rows: list[dict], configs: list[str], eps_list, command: str, max_iter: int = 4000) -> str:
    """The markdown report: solved counts, gained and lost against plain, iterations where both solve."""
    by = {(r["problem"], r["eps"], r["config"]): r for r in rows}
    names = sorted({r["problem"] for r in rows if r["status"] != "refused"})
    refused = sorted({r["problem"] for r in rows if r["status"] == "refused"})
    solved = {(p, e, c): by[(p, e, c)]["status"] == SOLVED for p in names for e in eps_list for c in configs}
    lines = [f"# Plain ADMM against {', '.join(c for c in configs if c != 'plain')} on the Maros-Meszaros problems",
             "", f"Command: `{command}`", "",
             f"{len(names)} problems (refused: {', '.join(refused) or 'none'}), OSQP's preset (`solve_qp` defaults, "
             f"max_iter {max_iter}), eps_abs = eps_rel, compiled; "
             "`maros_meszaros.csv` has every run.", "",
             f"| solved (of {len(names)}) | " + " | ".join(configs) + " |",
             "| --- |" + " --- |" * len(configs)]
    for e in eps_list:
        lines.append(f"| eps {e:g} | " + " | ".join(str(sum(solved[(p, e, c)] for p in names)) for c in configs)
                     + " |")
    lines += ["", "Gained / lost against plain; iterations over plain's on the problems both solve (geometric mean, "
              "total):", "", "| configuration | eps | gained | lost | iterations (geo. mean, total) |",
              "| --- | --- | --- | --- | --- |"]
    for c in configs:
        if c == "plain":
            continue
        for e in eps_list:
            gained = [p for p in names if solved[(p, e, c)] and not solved[(p, e, "plain")]]
            lost = [p for p in names if solved[(p, e, "plain")] and not solved[(p, e, c)]]
            both = [p for p in names if solved[(p, e, "plain")] and solved[(p, e, c)]]
            ratios = [by[(p, e, c)]["iterations"] / by[(p, e, "plain")]["iterations"] for p in both]
            total = (sum(by[(p, e, c)]["iterations"] for p in both)
                     / max(sum(by[(p, e, "plain")]["iterations"] for p in both), 1))
            lines.append(f"| {c} | {e:g} | {', '.join(gained) or 'none'} | {', '.join(lost) or 'none'} | "
                         f"{geometric_mean(ratios):.2f}, {total:.2f} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    """Run the study, print the report and write maros_meszaros.csv and maros_meszaros.md under --out."""
    from admmkit.cli import Parser
    parser = Parser(prog="python -m admmkit.benchmarks.qp.acceleration_mm", description=__doc__.splitlines()[0])
    parser.add_argument("--data", default="../shared/data/maros_meszaros", help="folder of Maros-Meszaros MAT files")
    parser.add_argument("--out", default="out/fast_cost", help="output folder (default ./out/fast_cost/)")
    parser.add_argument("--configs", nargs="+", default=list(CONFIGS),
                        help=f"configurations (default: {' '.join(CONFIGS)}; plain is always run)")
    parser.add_argument("--max-size", type=int, default=3000, help="largest n + m (default 3000)")
    parser.add_argument("--max-iter", type=int, default=4000, help="iteration cap (default 4000, OSQP's)")
    parser.add_argument("--time-limit", type=float, default=20.0, help="CPU seconds per solve (default 20)")
    parser.add_argument("--problems", default=None, help="comma-separated problem names (default: all that fit)")
    args = parser.parse_args(argv)
    configs = list(dict.fromkeys(c.strip() for c in args.configs))
    if "plain" not in configs:
        configs.insert(0, "plain")
    for c in configs:
        try:
            accelerator(c)
        except ValueError as err:
            parser.error(str(err))
    if args.max_size < 1 or args.max_iter < 1 or not args.time_limit > 0:
        parser.error("--max-size and --max-iter must be integers >= 1, --time-limit a positive number")
    data = Path(args.data)
    if not data.is_dir():
        parser.error(f"--data: no folder {data}")
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    from admmkit.io import write_text
    from admmkit.benchmarks.runner.report import write_csv
    chosen = problems(data, args.max_size)
    if args.problems:
        wanted = {p.strip() for p in args.problems.split(",")}
        chosen = [(n, p) for n, p in chosen if n in wanted]
    from admmkit.problems.qp import random_qp, solve_qp
    for config in configs:              # compile (or load) the kernels before the first solve and its time limit
        solve_qp(random_qp(5, 5), eps_abs=1e-3, eps_rel=1e-3, max_iter=100, compiled=True,
                 acceleration=accelerator(config))
    rows = []
    for i, (name, path) in enumerate(chosen):
        for eps in EPS:
            for config in configs:
                rows.append(run(path, eps, config, args.max_iter, args.time_limit))
        line = "; ".join(f"{r['config']} {r['eps']:g} {r['status']} {r['iterations']}"
                         for r in rows if r["problem"] == name)
        print(f"[{i + 1}/{len(chosen)}] {name}: {line}", flush=True)
    command = "python -m admmkit.benchmarks.qp.acceleration_mm " + " ".join(
        shlex.quote(a) for a in (argv if argv is not None else sys.argv[1:]))
    out = Path(args.out)
    write_csv(out / "maros_meszaros.csv", rows, list(COLUMNS), float_format=".6g")
    text = report(rows, configs, EPS, command, args.max_iter)
    write_text(out / "maros_meszaros.md", text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
