"""Writing benchmark output: machine and versions, CSV, Markdown tables, PNG + SVG figures."""
from __future__ import annotations

import csv
import math
from fractions import Fraction
from pathlib import Path

import numpy as np

from admmkit.figures import pyplot, save_figure  # noqa: F401  (the one pyplot and save of every study)
from admmkit.io import atomic_open, write_text  # noqa: F401  (every report is written whole or not at all)


#: said in every benchmark README: the machine is shared
NOISE_NOTE = ("The machine (2 cores) is shared with other engineers' jobs while the benchmark runs, so "
              "absolute times are noisy; compare methods by the ratios, which are computed within one run.")


def machine_markdown(info: dict) -> str:
    """The machine section of a README."""
    lines = ["## Machine", ""] + [f"- {k}: {v}" for k, v in info.items()] + ["", NOISE_NOTE, ""]
    return "\n".join(lines)


def write_csv(path: Path, rows: list[dict], columns: list[str] | None = None, float_format: str | None = None) -> Path:
    """Rows of dicts as CSV, written whole or not at all.

    Columns: the given ones, else the union in first-seen order.  Floats are
    written with ``repr`` (exact) unless ``float_format`` (e.g. ".6g") is given;
    None and NaN become empty cells.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    if columns is None:
        columns = []
        for row in rows:
            columns += [k for k in row if k not in columns]
    with atomic_open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=columns, extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: _csv_value(row.get(k), float_format) for k in columns})
    return path


def _csv_value(v, float_format: str | None = None):
    if v is None:
        return ""
    if isinstance(v, float):
        return "" if math.isnan(v) else (format(v, float_format) if float_format else repr(v))
    return v


def md_table(header: list[str], rows: list[list], align: str | None = None) -> str:
    """A Markdown table; ``align`` like "lrr" (default: first column left, the rest right)."""
    align = align or ("l" + "r" * (len(header) - 1))
    sep = ["---:" if a == "r" else ":---" for a in align]
    lines = ["| " + " | ".join(header) + " |", "| " + " | ".join(sep) + " |"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def fmt(v, spec: str = ".3g", missing: str = "-") -> str:
    """Format a number, or ``missing`` for None/nan."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return missing
    return format(v, spec)


def method_styles(names: list[str]) -> dict[str, dict]:
    """Distinct line styles: ADMM methods in colours (tab20) with markers, peers in black/grey."""
    peers = {"pdas": dict(color="black", marker="s", linestyle="-", linewidth=2.2),
             "clarabel": dict(color="0.35", marker="D", linestyle="--", linewidth=2.0),
             "cvxpy-osqp": dict(color="0.55", marker="v", linestyle=":", linewidth=2.0),
             "osqp": dict(color="0.2", marker="^", linestyle="-.", linewidth=2.0)}
    markers = "o^vs<>pPhX*d"
    cmap = pyplot().get_cmap("tab20")
    out, i = {}, 0
    for name in names:
        if name in peers:
            out[name] = peers[name]
            continue
        out[name] = dict(color=cmap(i % 20), marker=markers[i % len(markers)], linestyle="-", linewidth=1.2)
        i += 1
    return out


def median(values) -> float:
    """Median of finite values (nan if none)."""
    vals = [float(v) for v in values if v is not None and math.isfinite(float(v))]
    return float(np.median(vals)) if vals else float("nan")


def h_label(h: float) -> str:
    """1/40 for 0.025, else the number."""
    frac = Fraction(h).limit_denominator(10_000)
    if frac.numerator == 1 and math.isclose(float(frac), h, rel_tol=1e-12):
        return f"1/{frac.denominator}"
    return f"{h:g}"


def rho_label(rho: float) -> str:
    """1, 10, 1e2, 1e3, ..."""
    if rho > 0 and math.isclose(math.log10(rho), round(math.log10(rho)), abs_tol=1e-12):
        e = round(math.log10(rho))
        return "1" if e == 0 else "10" if e == 1 else f"1e{e}"
    return f"{rho:g}"
