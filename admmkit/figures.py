"""Figures: one way to get pyplot and one way to save, for plug-ins and benchmarks alike."""
from __future__ import annotations

import os
from pathlib import Path

from .io import atomic_path


def pyplot():
    """``matplotlib.pyplot``, on the non-interactive Agg backend unless MPLBACKEND chooses another."""
    import matplotlib
    if not os.environ.get("MPLBACKEND"):
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def save_figure(fig, path: str | Path, formats: tuple[str, ...] = ("png", "svg"), dpi: int = 130) -> list[Path]:
    """Save ``fig`` under ``path``'s stem in each format (written whole or not at all), close it, return the paths."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    written = []
    for ext in formats:
        target = path.with_suffix("." + ext)
        with atomic_path(target) as tmp:
            fig.savefig(tmp, dpi=dpi, bbox_inches="tight", format=ext)
        written.append(target)
    pyplot().close(fig)
    return written
