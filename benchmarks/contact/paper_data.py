"""The paper's grid and its published figures: the (example, h, method, rho) of a run and its record.

The paper's CPU seconds (Tables 1-2) are read from ``data/paper_tables.json``
beside this module.  :mod:`admmkit.benchmarks.contact.paper` runs the grid,
:mod:`admmkit.benchmarks.contact.paper_tables` writes the tables; both read
this module, neither the other.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

METHOD_NAMES = ("admm1", "admm2", "sadmm")
PAPER_HS = (1 / 10, 1 / 20, 1 / 30, 1 / 40)
PAPER_RHOS = (1.0, 10.0, 1e2, 1e3, 1e4)
#: displacement magnification of the paper's Figs 1 and 3
MAGNIFY = {"ex1": 10.0, "ex2": 20.0}
#: the paper's published CPU seconds (Tables 1-2)
PAPER_TABLES = Path(__file__).with_name("data") / "paper_tables.json"


@lru_cache(maxsize=1)
def paper_times() -> dict:
    """PAPER_TIMES[example][method][rho] = CPU seconds at h = 1/10, 1/20, 1/30, 1/40 (from the data file)."""
    data = json.loads(PAPER_TABLES.read_text())
    return {ex: {m: {float(rho): tuple(v) for rho, v in by_rho.items()} for m, by_rho in by_m.items()}
            for ex, by_m in data["cpu_seconds"].items()}


def paper_time(example: str, method: str, rho: float, h: float) -> float | None:
    """The paper's CPU seconds for this run, or None if the paper has no such entry."""
    row = paper_times().get(example, {}).get(method, {}).get(float(rho))
    if row is None:
        return None
    for hp, value in zip(PAPER_HS, row):
        if math.isclose(h, hp, rel_tol=1e-9):
            return value
    return None


@dataclass
class Run:
    """One (example, h, method, rho) run."""

    example: str
    h: float
    method: str
    rho: float
    iterations: int
    status: str
    time: float            # setup + solve, median over repeats (s)
    cpu_time: float        # process time of the same, median (s)
    setup_time: float
    solve_time: float
    mode: str
    factorizations: int | None
    rho_changes: int
    final_rho: float
    kkt: dict
    errors: dict
    n_free: int
    n_c: int
