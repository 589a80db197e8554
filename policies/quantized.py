"""Cost-aware penalties: snap a rule's rho to a geometric grid so that factorisations are reused.

For finite element problems every new rho costs a sparse factorisation of
K + rho B'MB (the x-step matrix), while a rho seen before costs nothing: the
plug-ins cache one factorisation per rho value
(``admmkit.linalg.linsolve.CachedFactorization``, 32 most recent values; the
condensed contact mode keeps all).  A rule that wants rho = 3.7 rho_0, then
4.1 rho_0, then 3.9 rho_0 factorises three times; on a grid it factorises once.

    rho' = inner.update(record)                          (the wrapped rule's wish)
    j    = round(per_decade * log10(rho' / rho_0))
    rho_{k+1} = rho_0 10^(j / per_decade)    if that differs from rho_k, else rho_k

The grid is anchored at rho_0, so that returning to the start is free too.
A wish within half a grid step of rho_k leaves rho unchanged, so rules that
make small changes (the tail of the summable rules) stop changing rho; since
this makes the number of changes finite on any bounded run, it does not break
their guarantee.  Default per_decade = 2 (half decades: the grid of the rho_0
sweeps in docs/results/), wrapping the spectral rule (AADMM), whose
estimates are arbitrary reals, so that unwrapped it factorises at nearly
every update (every second iteration).  Deterministic: the grid index is
computed from rho'/rho_0.
"""
from __future__ import annotations

import math

from admmkit import IterationRecord, Policy

from ._checks import check_number
from ._wrap import as_policy


class Quantized(Policy):
    """Round a wrapped rule's rho (default: AADMM's) to the grid rho_0 10^(j/per_decade)."""

    def __init__(self, inner: Policy | str = "aadmm", per_decade: float = 2.0):
        self.inner = as_policy(inner)
        self.per_decade = check_number("per_decade", per_decade, low=0.0)
        self.requires = tuple(self.inner.requires)

    def reset(self, rho0: float) -> None:
        """Reset the wrapped rule; the grid is anchored at rho0."""
        super().reset(rho0)
        self.inner.reset(rho0)
        self.levels: set[int] = {0}     # grid indices visited (each cost one factorisation)

    def index(self, rho: float) -> int:
        """Nearest grid index j of rho: round(per_decade log10(rho / rho_0))."""
        return int(round(self.per_decade * math.log10(rho / self.rho0)))

    def value(self, j: int) -> float:
        """The grid value rho_0 10^(j / per_decade)."""
        return self.rho0 * 10.0 ** (j / self.per_decade)

    def unchanged_until(self, k: int) -> int:
        """The wrapped rule's."""
        return self.inner.unchanged_until(k)

    def update(self, rec: IterationRecord) -> float:
        """The wrapped rule's rho, snapped to the nearest grid value (unchanged if that is rho_k's)."""
        wish = self.inner.update(rec)
        if not (isinstance(wish, (int, float)) and math.isfinite(wish) and wish > 0):
            return wish
        j = self.index(wish)
        if j == self.index(rec.rho):
            return rec.rho
        self.levels.add(j)
        return self.value(j)
