"""Parameter checks shared by the policies (clear errors at construction)."""
from __future__ import annotations

import math


def check_number(name: str, value, *, low: float, low_open: bool = True, high: float = math.inf) -> float:
    """Return float(value) if low < value (or <=) and value < high, else raise ValueError naming it."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    ok = math.isfinite(v) and (v > low if low_open else v >= low) and v < high
    if not ok:
        lo = "(" if low_open else "["
        hi = "inf)" if math.isinf(high) else f"{high:g})"
        raise ValueError(f"{name} must be a finite number in {lo}{low:g}, {hi}, got {value!r}")
    return v


def check_int(name: str, value, *, low: int) -> int:
    """Return value if it is an integer >= low, else raise ValueError naming it."""
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    return value
