"""Dörfler marking and the checks of an adaptive loop: the pieces every adaptive finite element plug-in reuses.

Dörfler (1996): given error indicators eta_T, mark the smallest set M of
cells with sum_{T in M} eta_T^2 >= theta sum_T eta_T^2 (the cells of the
largest indicators first).
"""
from __future__ import annotations

import math

import numpy as np


def dorfler_mark(indicators, theta: float) -> np.ndarray:
    """The smallest set of cells whose eta_T^2 sum to at least theta x the total (a boolean mask)."""
    eta2 = np.asarray(indicators, dtype=float) ** 2
    order = np.argsort(-eta2, kind="stable")
    count = int(np.searchsorted(np.cumsum(eta2[order]), theta * eta2.sum())) + 1
    mask = np.zeros(eta2.size, dtype=bool)
    mask[order[:min(count, eta2.size)]] = True
    return mask


def check_adaptive(target, theta, gamma, max_levels, max_unknowns) -> None:
    """Refuse parameters of an adaptive loop outside their ranges, naming the parameter and the range."""
    for name, value, ok, accepted in [("target", target, lambda v: 0 < v < 1, "(0, 1)"),
                                      ("theta", theta, lambda v: 0 < v < 1, "(0, 1)"),
                                      ("gamma", gamma, lambda v: 0 < v <= 1, "(0, 1]")]:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or not ok(value):
            raise ValueError(f"{name} = {value!r} is outside the accepted range {accepted}")
    for name, value in [("max_levels", max_levels), ("max_unknowns", max_unknowns)]:
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"{name} = {value!r} is outside the accepted range: an integer >= 1")
