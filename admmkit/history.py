"""Per-iteration history of a run: columns of numbers, exportable to arrays and CSV."""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from .record import SCALAR_FIELDS, IterationRecord

#: columns of the history, in CSV order
COLUMNS = SCALAR_FIELDS + ("rel_change", "primal_residual_rel", "dual_residual_rel", "rho_next", "rho_changed")


class History:
    """One row per iteration: the record's scalars, the next rho and whether it changed."""

    def __init__(self) -> None:
        self._rows: list[tuple] = []

    def append(self, rec: IterationRecord, rho_next: float) -> None:
        """Add the row of iteration ``rec.k``; ``rho_next`` is the rho the policy chose."""
        row = tuple(getattr(rec, name) for name in SCALAR_FIELDS)
        row += (rec.rel_change, rec.primal_residual_rel, rec.dual_residual_rel, rho_next, rho_next != rec.rho)
        self._rows.append(row)

    def __len__(self) -> int:
        return len(self._rows)

    def __getitem__(self, column: str) -> np.ndarray:
        """The column ``column`` as an array, e.g. ``history["rho"]``."""
        try:
            j = COLUMNS.index(column)
        except ValueError:
            raise KeyError(f"unknown history column {column!r}; columns are {', '.join(COLUMNS)}") from None
        dtype = bool if column == "rho_changed" else (int if column == "k" else float)
        return np.array([row[j] for row in self._rows], dtype=dtype)

    def as_dict(self) -> dict[str, np.ndarray]:
        """All columns as a dict of arrays."""
        return {name: self[name] for name in COLUMNS}

    def to_csv(self, path: str | Path) -> Path:
        """Write the history as CSV (header row, one row per iteration) and return the path."""
        path = Path(path)
        with path.open("w", newline="") as fh:
            writer = csv.writer(fh)
            writer.writerow(COLUMNS)
            for row in self._rows:
                writer.writerow([int(v) if isinstance(v, (bool, np.bool_)) else repr(float(v)) if isinstance(v, float) else v for v in row])
        return path
