"""The discrete obstacle problem of a scene in the elements asked for: P1 (problem.py) or P2 (p2.py)."""
from __future__ import annotations

from .p2 import ObstacleProblemP2
from .problem import DEFAULT_BACKEND, ObstacleProblem
from .scene import Scene

#: the accepted polynomial orders
FE_ORDERS = (1, 2)


def check_fe_order(fe_order) -> int:
    """``fe_order`` if it is 1 or 2, else ValueError naming it and the accepted values."""
    if fe_order not in FE_ORDERS or isinstance(fe_order, bool):
        raise ValueError(f"fe_order = {fe_order!r}; accepted: 1 or 2")
    return fe_order


def make_problem(scene: Scene, *, backend: str = DEFAULT_BACKEND, fe_order: int = 1, mesh=None) -> ObstacleProblem:
    """Assemble the discrete obstacle problem of the scene in P1 or P2 elements (``fe_order``), on the scene's
    structured mesh or on ``mesh`` (an adapted mesh of its box)."""
    check_fe_order(fe_order)
    return (ObstacleProblemP2 if fe_order == 2 else ObstacleProblem)(scene, backend=backend, mesh=mesh)


__all__ = ["make_problem", "check_fe_order", "FE_ORDERS"]
