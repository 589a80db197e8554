"""The charts of ``admmkit bench adaptive``: error against unknowns and wall time; effectivity and iterations."""
from __future__ import annotations

import csv
import math
from pathlib import Path

from admmkit.figures import pyplot, save_figure

from admmkit.benchmarks.adaptive.compare import GROUPS, comparison, series

STYLE = {"adaptive": ("C3", "-", "o", "adaptive (balanced stop, warm start)"),
         "uniform": ("C0", "--", "s", "uniform (balanced stop)"),
         "a_priori": ("C1", "-.", "D", "a priori local refinement (balanced stop)"),
         "uniform_today": ("C7", ":", "^", "uniform (today's stop, RelativeChange 1e-5)"),
         "uniform_today_amg": ("C8", ":", "v", "uniform (today's stop, AMG-CG x-step)")}


#: the error charts' grid: each scene a pair of panels (against unknowns, against wall time), this many pairs a row
PAIRS_PER_ROW = 2


def error_figure(rows: list[dict]):
    """The figure of :func:`plot` (open; the caller saves or closes it)."""
    plt = pyplot()
    comp = {c["scene"]: c for c in comparison(rows)}
    groups = [g for g in GROUPS if series(rows, g[0], g[1], "adaptive")]
    pairs = min(PAIRS_PER_ROW, max(len(groups), 1))
    nrows = max(math.ceil(len(groups) / pairs), 1)
    fig, axes = plt.subplots(nrows, 2 * pairs, figsize=(4.3 * 2 * pairs, 3.5 * nrows + 0.8), squeeze=False)
    panels = list(axes.flat)
    for i, (scene, order, title) in enumerate(groups):
        for ax, key, label in ((panels[2 * i], "unknowns", "unknowns"),
                               (panels[2 * i + 1], "wall_seconds", "wall time [s] (adaptive: all levels so far)")):
            for method, (colour, line, marker, name) in STYLE.items():
                s = series(rows, scene, order, method)
                if s:
                    ax.loglog([r[key] for r in s], [r["true_error"] for r in s], line, color=colour, marker=marker,
                              ms=4, label=name)
            if title in comp:
                ax.axhline(comp[title]["error"], color="grey", lw=0.8, ls="-.", label="common error of the table")
            ax.set_xlabel(label, fontsize=9)
            ax.set_ylabel("true relative energy error", fontsize=9)
            ax.set_title(f"{title}: error vs {'unknowns' if key == 'unknowns' else 'wall time'}", fontsize=9)
            ax.grid(True, which="both", alpha=0.3)
            ax.xaxis.set_minor_formatter(plt.NullFormatter())
    spare = panels[2 * len(groups):]
    for ax in spare:
        ax.axis("off")
    seen = {}
    for ax in panels[:2 * len(groups)]:
        seen.update(zip(*reversed(ax.get_legend_handles_labels())))
    order = [name for *_, name in STYLE.values()] + ["common error of the table"]
    legend = {name: seen[name] for name in order if name in seen}
    if spare:
        spare[0].legend(legend.values(), legend.keys(), loc="center", fontsize=9, title="method")
        fig.tight_layout()
    else:
        fig.legend(legend.values(), legend.keys(), loc="lower center", fontsize=9, ncol=3)
        fig.tight_layout(rect=(0, 0.08 / nrows, 1, 1))
    return fig


def plot(rows: list[dict], path: Path) -> Path:
    """True error against unknowns and against wall time, log-log: a grid of panels, each scene a pair side by
    side (:data:`PAIRS_PER_ROW` pairs a row), one legend for all."""
    return save_figure(error_figure(rows), path, ("png",), dpi=100)[0]


def plot_levels(rows: list[dict], path: Path) -> Path:
    """Left: the effectivity per adaptive level; right: the iterations per level (adaptive, and uniform cold)."""
    return save_figure(levels_figure(rows), path, ("png",), dpi=100)[0]


def levels_figure(rows: list[dict]):
    """The figure of :func:`plot_levels` (open; the caller saves or closes it): a colour per scene (the legend
    below both panels), on the right solid circles for the adaptive levels and dotted squares for a cold start."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    for (scene, order, title), colour in zip(GROUPS, ("C2", "C3", "C1", "C4", "C5", "C6", "C9")):
        ad = series(rows, scene, order, "adaptive")
        if not ad:
            continue
        n = [r["unknowns"] for r in ad]
        axes[0].semilogx(n, [r["effectivity"] for r in ad], "o-", color=colour, ms=4, label=title)
        axes[1].semilogx(n, [r["iterations"] for r in ad], "o-", color=colour, ms=4)
        axes[1].semilogx(n, [r["cold_iterations"] for r in ad], "s:", color=colour, ms=4)
    axes[0].axhline(1.0, color="grey", lw=0.8)
    axes[0].set_title("effectivity = estimate / true error, per adaptive level", fontsize=10)
    axes[0].set_ylabel("effectivity (estimate / true error)")
    axes[1].set_title("ADMM iterations per level", fontsize=10)
    axes[1].set_ylabel("ADMM iterations")
    axes[1].plot([], [], "ko-", ms=4, label="adaptive level (warm start)")
    axes[1].plot([], [], "ks:", ms=4, label="cold start on the same mesh")
    axes[1].legend(fontsize=8, loc="upper left")
    for ax in axes:
        ax.set_xlabel("unknowns")
        ax.grid(True, which="both", alpha=0.3)
    handles, names = axes[0].get_legend_handles_labels()
    fig.legend(handles, names, loc="lower center", ncol=4, fontsize=8, title="scene (colour)", title_fontsize=8)
    fig.tight_layout(rect=(0, 0.12, 1, 1))
    return fig


def read_rows(path: Path) -> list[dict]:
    """The rows of an adaptive.csv written by the study: numbers back as int or float, empty cells as NaN."""
    def value(cell: str):
        if cell == "":
            return math.nan
        for kind in (int, float):
            try:
                return kind(cell)
            except ValueError:
                pass
        return cell
    with Path(path).open(newline="") as fh:
        return [{k: value(v) for k, v in row.items()} for row in csv.DictReader(fh)]


def redraw(folder: Path) -> list[Path]:
    """Draw adaptive.png and adaptive_levels.png again from the folder's adaptive.csv, running nothing."""
    folder = Path(folder)
    rows = read_rows(folder / "adaptive.csv")
    return [plot(rows, folder / "adaptive.png"), plot_levels(rows, folder / "adaptive_levels.png")]
