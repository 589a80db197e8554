"""Fixed penalty: rho_k = rho_0 for every k (the paper's ADMM1 and ADMM2)."""
from __future__ import annotations

import sys

from admmkit import IterationRecord, Policy


class Fixed(Policy):
    """Keep rho at its initial value."""

    def update(self, rec: IterationRecord) -> float:
        """Return rho_k unchanged."""
        return rec.rho

    def unchanged_until(self, k: int) -> int:
        """Never reads a record."""
        return sys.maxsize
