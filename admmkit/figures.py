"""Figures: one way to get pyplot and one way to save, for plug-ins and benchmarks alike."""
from __future__ import annotations

import os
from pathlib import Path

from .io import atomic_path, is_stream


def pyplot():
    """``matplotlib.pyplot``, on the non-interactive Agg backend unless MPLBACKEND chooses another."""
    import matplotlib
    if not os.environ.get("MPLBACKEND"):
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def save_figure(fig, path: str | Path, formats: tuple[str, ...] = ("png", "svg"), dpi: int = 130) -> list[Path]:
    """Save ``fig`` in each format (written whole or not at all), close it, return the paths.

    Each format goes to ``path`` with that format's extension (``fig`` ->
    ``fig.png``, ``fig.svg``); a ``path`` that already ends in it (any case)
    is kept as it is.  A stream (``-``, a FIFO, a character device; see
    :mod:`admmkit.io`) takes one format, written into it with the format given
    explicitly to matplotlib.
    """
    stream = is_stream(path)
    if stream and len(formats) != 1:
        raise ValueError(f"a figure written to the stream {str(path)!r} takes one format, got {formats}")
    path = Path(path)
    if not stream:
        path.parent.mkdir(parents=True, exist_ok=True)
    written = []
    for ext in formats:
        target = path if stream or path.suffix.lower() == "." + ext else path.with_suffix("." + ext)
        with atomic_path(target) as tmp:
            fig.savefig(tmp, dpi=dpi, bbox_inches="tight", format=ext)
        written.append(target)
    pyplot().close(fig)
    return written
