"""A sweep's records as one table for pandas: ``<out>/results.parquet`` (or ``.csv`` without pyarrow).

The results file itself loads with ``pandas.read_json(path, lines=True)``
(one record per row, ``case`` and ``result`` as dict columns); this table is
flat: one row per record (or per row a study derives from a record), the
case's keys as ``case.<key>``, the result's as ``result.<key>`` (nested dicts
joined with dots, lists kept as JSON text), and ``id``, ``seconds``,
``error``, ``fault`` (whose failure: ``case`` or ``harness``) and
``worker_peak_mb`` (the worker's peak memory so far).  It is written whole
or not at all (:func:`admmkit.io.atomic_path`).
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Callable, Iterable

from admmkit.benchmarks.runner.jsonable import json_default


def flatten(value, prefix: str = "") -> dict:
    """{"a.b": 1, ...}: nested dicts joined with dots; lists and tuples as JSON text; inf/nan kept."""
    out = {}
    if isinstance(value, dict):
        for k, v in value.items():
            out.update(flatten(v, f"{prefix}.{k}" if prefix else str(k)))
    elif isinstance(value, (list, tuple)):
        out[prefix] = json.dumps(value, default=json_default)
    else:
        out[prefix] = value
    return out


def record_rows(record: dict) -> list[dict]:
    """The default: one flat row per record."""
    row = {"id": record.get("id"), "seconds": record.get("seconds"), "error": record.get("error"),
           "fault": record.get("fault"), "worker_peak_mb": record.get("worker_peak_mb")}
    row.update(flatten(record.get("case") or {}, "case"))
    result = record.get("result")
    row.update(flatten(result, "result") if isinstance(result, dict) else {"result": result})
    return [row]


def _frame(rows: list[dict]):
    import pandas as pd
    frame = pd.DataFrame(rows)
    for col in frame.columns:
        if frame[col].dtype != object:
            continue
        kinds = {type(v) for v in frame[col] if v is not None and not (isinstance(v, float) and math.isnan(v))}
        if len(kinds) > 1 or (kinds and not kinds <= {str}):
            numeric = kinds <= {int, float, bool}
            if numeric:
                frame[col] = pd.to_numeric(frame[col], errors="coerce")
            else:   # mixed kinds: text, so that Parquet takes the column
                frame[col] = [None if v is None else (v if isinstance(v, str) else json.dumps(v, default=str))
                              for v in frame[col]]
    return frame


def write_table(records: Iterable[dict], stem: str | Path, rows: Callable[[dict], list[dict]] | None = None
                ) -> Path | None:
    """Write ``stem``.parquet (pyarrow) or ``stem``.csv atomically; None if pandas is missing or no record."""
    try:
        import pandas  # noqa: F401
    except ImportError:
        return None
    from admmkit.io import atomic_path
    table = [r for rec in records for r in (rows or record_rows)(rec)]
    if not table:
        return None
    frame = _frame(table)
    stem = Path(stem)
    try:
        import pyarrow  # noqa: F401
        path = stem.with_suffix(".parquet")
        with atomic_path(path) as tmp:
            frame.to_parquet(tmp, index=False)
    except ImportError:
        path = stem.with_suffix(".csv")
        with atomic_path(path) as tmp:
            frame.to_csv(tmp, index=False)
    return path
