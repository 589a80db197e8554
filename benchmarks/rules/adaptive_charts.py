"""The charts of ``admmkit bench adaptive``: error against unknowns and wall time; effectivity and iterations."""
from __future__ import annotations

from pathlib import Path

from admmkit.figures import pyplot, save_figure

from admmkit.benchmarks.rules.adaptive_compare import GROUPS, comparison, series

STYLE = {"adaptive": ("C3", "-", "o", "adaptive (balanced stop, warm start)"),
         "uniform": ("C0", "--", "s", "uniform (balanced stop)"),
         "a_priori": ("C1", "-.", "D", "a priori local refinement (balanced stop)"),
         "uniform_today": ("C7", ":", "^", "uniform (today's stop, RelativeChange 1e-5)"),
         "uniform_today_amg": ("C8", ":", "v", "uniform (today's stop, AMG-CG x-step)")}


def plot(rows: list[dict], path: Path) -> Path:
    """Error against unknowns (top) and against wall time (bottom), one column per scene, log-log."""
    plt = pyplot()
    comp = {c["scene"]: c for c in comparison(rows)}
    groups = [g for g in GROUPS if series(rows, g[0], g[1], "adaptive")]
    fig, axes = plt.subplots(2, len(groups), figsize=(4.6 * len(groups), 8.4), squeeze=False)
    for col, (scene, order, title) in enumerate(groups):
        for row, key, label in ((0, "unknowns", "unknowns"), (1, "wall_seconds", "wall time [s]")):
            ax = axes[row, col]
            for method, (colour, line, marker, name) in STYLE.items():
                s = series(rows, scene, order, method)
                if s:
                    ax.loglog([r[key] for r in s], [r["true_error"] for r in s], line, color=colour, marker=marker,
                              ms=4, label=name)
            if title in comp:
                ax.axhline(comp[title]["error"], color="grey", lw=0.8, ls="-.", label="common error")
            ax.set_xlabel(label)
            ax.set_ylabel("true relative energy error")
            ax.set_title(title, fontsize=10)
            ax.grid(True, which="both", alpha=0.3)
            ax.xaxis.set_minor_formatter(plt.NullFormatter())
            ax.legend(fontsize=7)
    fig.tight_layout()
    return save_figure(fig, path, ("png",), dpi=100)[0]


def plot_levels(rows: list[dict], path: Path) -> Path:
    """Left: the effectivity per adaptive level; right: the iterations per level (adaptive, and uniform cold)."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for (scene, order, title), colour in zip(GROUPS, ("C2", "C3", "C1", "C4", "C5", "C6", "C9")):
        ad = series(rows, scene, order, "adaptive")
        if not ad:
            continue
        axes[0].semilogx([r["unknowns"] for r in ad], [r["effectivity"] for r in ad], "o-", color=colour, ms=4,
                         label=title)
        axes[1].semilogx([r["unknowns"] for r in ad], [r["iterations"] for r in ad], "o-", color=colour, ms=4,
                         label=f"{title}: adaptive")
        axes[1].semilogx([r["unknowns"] for r in ad], [r["cold_iterations"] for r in ad], "s:", color=colour, ms=4,
                         label=f"{title}: cold start on the same level")
    axes[0].axhline(1.0, color="grey", lw=0.8)
    axes[0].set_title("effectivity = estimate / true error, per adaptive level", fontsize=10)
    axes[1].set_title("ADMM iterations per level", fontsize=10)
    for ax in axes:
        ax.set_xlabel("unknowns")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    return save_figure(fig, path, ("png",), dpi=100)[0]


