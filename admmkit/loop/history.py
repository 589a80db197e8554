"""Per-iteration history of a run: columns of numbers, exportable to arrays and CSV.

Two modes (``admmkit.solve(..., history=...)``):

- ``"lean"`` (default) keeps, for each iteration, the norms that were computed
  anyway (those the stopping rule, the policy and the callback read) and NaN
  for the others; the last row is always complete.  It costs nothing beyond
  storing a few numbers.
- ``"full"`` computes every norm of every record, as the eager loop did: all
  columns are filled, at the price of about nine extra vector norms per iteration.

Where a lean row has a number, it is bitwise the number a full row holds.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from ..io import atomic_open
from .record import LAZY_FIELDS, SCALAR_FIELDS, IterationRecord, ratio, relative_change

#: columns of the history, in CSV order
COLUMNS = SCALAR_FIELDS + ("rel_change", "primal_residual_rel", "dual_residual_rel", "rho_next", "rho_changed")
MODES = ("lean", "full")
_NAN = math.nan


class History:
    """One row per iteration: the record's scalars, the next rho and whether it changed."""

    def __init__(self, mode: str = "full") -> None:
        if mode not in MODES:
            raise ValueError(f"history must be 'lean' or 'full', got {mode!r}")
        self.mode = mode
        self._entries: list = []         # rows (k, rho, primal_unit, dual_unit, time, lazy values, rho_next), and
        self._runs = 0                   # ... runs of unread rows (_Unread) not yet written out, ``_runs`` of them
        self._count = 0                  # the rows in all
        #: {k: w}: the row weights a per-row rule set after iteration k (``admmkit.RowPenalties``); its row's
        #: ``rho_changed`` is True (one event), ``rho_next`` its rho
        self.row_weights: dict[int, np.ndarray] = {}

    def append(self, rec: IterationRecord, rho_next) -> None:
        """Add the row of iteration ``rec.k``; ``rho_next`` is the rho the policy chose (or its
        :class:`admmkit.RowPenalties`, whose weights go to :attr:`row_weights`)."""
        if type(rho_next) is not float and isinstance(rho_next, tuple):     # RowPenalties (rho, weights)
            self.row_weights[rec.k] = rho_next.weights
            rho_next = rho_next.rho
        if self.mode == "full":
            rec.complete()
        d, ctx = rec._d, rec._ctx
        self._entries.append((d[0], d[1], ctx.primal_unit, ctx.dual_unit, d[2], rec._vals, rho_next))
        self._count += 1

    def append_unread(self, k: int, count: int, rho: float, ctx, t: float) -> None:
        """Add the rows of iterations k .. k + count - 1 that ran without records (:mod:`admmkit.loop.segments`):
        rho unchanged, no norm computed, ``t`` (seconds since the start) at the segment's end.  Kept as one run,
        written out as rows when the history is first read (a solve that reads none builds none)."""
        self._entries.append(_Unread(k, count, rho, ctx.primal_unit, ctx.dual_unit, t))
        self._runs += 1
        self._count += count

    @property
    def _rows(self) -> list[tuple]:
        """Every row, the unread runs written out (once)."""
        if self._runs:
            rows: list[tuple] = []
            for entry in self._entries:
                if type(entry) is _Unread:
                    rows.extend(entry.rows())
                else:
                    rows.append(entry)
            self._entries, self._runs = rows, 0
        return self._entries

    def replace_last(self, rec: IterationRecord) -> None:
        """Refresh the last row from ``rec`` (the loop completes the last record of a run)."""
        entries = self._entries if type(self._entries[-1]) is not _Unread else self._rows
        k, rho, pu, du, t, _, rho_next = entries[-1]
        entries[-1] = (k, rho, pu, du, t, rec._vals, rho_next)

    def __len__(self) -> int:
        return self._count

    def _row(self, row: tuple) -> tuple:
        k, rho, primal_unit, dual_unit, t, vals, rho_next = row
        v = dict(zip(LAZY_FIELDS, (_NAN if a is None else a for a in vals)))
        scalars = dict(v, k=k, rho=rho, primal_unit=primal_unit, dual_unit=dual_unit, time=t)
        out = tuple(scalars[name] for name in SCALAR_FIELDS)
        return out + (relative_change(v["x_change"], v["x_norm"]) if vals[4] is not None and vals[5] is not None else _NAN,
                      ratio(v["primal_residual"], v["primal_scale"]) if vals[0] is not None and vals[7] is not None else _NAN,
                      ratio(v["dual_residual"], v["dual_scale"]) if vals[1] is not None and vals[8] is not None else _NAN,
                      rho_next, rho_next != rho or (bool(self.row_weights) and k in self.row_weights))

    def __getitem__(self, column: str) -> np.ndarray:
        """The column ``column`` as an array, e.g. ``history["rho"]`` (NaN where a lean row did not compute it)."""
        try:
            j = COLUMNS.index(column)
        except ValueError:
            raise KeyError(f"unknown history column {column!r}; columns are {', '.join(COLUMNS)}") from None
        dtype = bool if column == "rho_changed" else (int if column == "k" else float)
        return np.array([self._row(row)[j] for row in self._rows], dtype=dtype)

    def as_dict(self) -> dict[str, np.ndarray]:
        """All columns as a dict of arrays."""
        rows = [self._row(row) for row in self._rows]
        out = {}
        for j, name in enumerate(COLUMNS):
            dtype = bool if name == "rho_changed" else (int if name == "k" else float)
            out[name] = np.array([row[j] for row in rows], dtype=dtype)
        return out

    def complete_rows(self) -> list[int]:
        """Positions of the rows with every norm computed (a lean history: the iterations whose record was
        completed, e.g. the tested ones when the command line asks for ``--history``, and always the last)."""
        return [i for i, row in enumerate(self._rows) if all(v is not None for v in row[5])]

    def to_csv(self, path: str | Path, rows: str = "all") -> Path:
        """Write the history as CSV (header row, then one row per iteration) and return the path.

        ``rows``: ``"all"`` (default) every iteration, NaN where a lean row did not compute a norm;
        ``"complete"`` only the rows with every norm computed (:meth:`complete_rows`), so no cell is NaN
        for want of a computation.  Written by :mod:`admmkit.io`: whole or not at all, a symbolic link's
        target replaced, a FIFO or ``-`` (standard output) written into (docs/cli.md, "Output files").
        """
        if rows not in ("all", "complete"):
            raise ValueError(f"rows must be 'all' or 'complete', got {rows!r}")
        path = Path(path)
        picked = self._rows if rows == "all" else [self._rows[i] for i in self.complete_rows()]
        with atomic_open(path, "w", newline="") as fh:     # whole or not at all (admmkit/io.py)
            writer = csv.writer(fh)
            writer.writerow(COLUMNS)
            for row in picked:
                writer.writerow([int(v) if isinstance(v, (bool, np.bool_)) else repr(float(v)) if isinstance(v, float) else v
                                 for v in self._row(row)])
        return path

    def to_pandas(self):
        """The history as a ``pandas.DataFrame`` indexed by the iteration ``k`` (pandas is optional).

        Columns as in ``admmkit.loop.history.COLUMNS``; NaN where a lean row did not compute a norm.
        """
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("History.to_pandas() needs pandas: pip install pandas "
                              "(or use History.as_dict() / History.to_csv())") from None
        return pd.DataFrame(self.as_dict()).set_index("k")

    def __repr__(self) -> str:
        if not self._rows:
            return f"History(mode={self.mode!r}, 0 iterations)"
        last = self._row(self._rows[-1])
        rho = self["rho"]
        return (f"History(mode={self.mode!r}, {len(self)} iterations, rho {rho.min():.3g}..{rho.max():.3g}, "
                f"last primal_residual {last[COLUMNS.index('primal_residual')]:.3e}, "
                f"rel_change {last[COLUMNS.index('rel_change')]:.3e})")

    def _repr_html_(self) -> str:
        """Jupyter: the first and last three rows of the main columns in a table."""
        import html
        cols = ("k", "rho", "primal_residual", "dual_residual", "rel_change", "rho_changed")
        n = len(self._rows)
        picked = list(range(min(n, 3))) + (list(range(max(3, n - 3), n)) if n > 3 else [])
        head = "".join(f"<th>{c}</th>" for c in cols)
        body = []
        for i, j in enumerate(picked):
            if i and j != picked[i - 1] + 1:
                body.append(f"<tr><td colspan='{len(cols)}'>... {j - picked[i - 1] - 1} rows ...</td></tr>")
            row = dict(zip(COLUMNS, self._row(self._rows[j])))
            body.append("<tr>" + "".join(f"<td>{_cell(row[c])}</td>" for c in cols) + "</tr>")
        return (f"<div><b>History</b> ({html.escape(self.mode)}, {n} iterations; columns: "
                f"{', '.join(COLUMNS)})<table><tr>{head}</tr>{''.join(body)}</table></div>")


class _Unread:
    """``count`` rows from iteration ``k`` on that ran in a compiled segment: rho unchanged, no norm computed."""

    __slots__ = ("k", "count", "rho", "primal_unit", "dual_unit", "t")

    def __init__(self, k: int, count: int, rho: float, primal_unit: float, dual_unit: float, t: float) -> None:
        self.k, self.count, self.rho, self.primal_unit, self.dual_unit, self.t = k, count, rho, primal_unit, dual_unit, t

    def rows(self):
        """The rows, as :meth:`History.append` writes them (the lazy values all None: one shared list)."""
        vals = [None] * len(LAZY_FIELDS)
        rho, pu, du, t = self.rho, self.primal_unit, self.dual_unit, self.t
        return [(i, rho, pu, du, t, vals, rho) for i in range(self.k, self.k + self.count)]


def _cell(value) -> str:
    """One table cell: integers and booleans as such, other numbers with 4 significant digits."""
    if isinstance(value, (bool, np.bool_, int, np.integer)):
        return str(value)
    return f"{float(value):.4g}"
