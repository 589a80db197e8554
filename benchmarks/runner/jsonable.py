"""JSON for the runner's records and cases: numpy scalars and arrays, and paths, as plain values."""
from __future__ import annotations

from pathlib import Path


def json_default(value):
    """numpy scalars and arrays, paths -> JSON."""
    import numpy as np
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")
