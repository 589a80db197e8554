"""Declarative description of an obstacle problem, and the named scenes.

    -Delta u = f in Omega,   u >= psi (side "lower") or u <= psi (side "upper"),
    u = u_D on the boundary,

on a rectangle Omega = (x0, x1) x (y0, y1), meshed with a structured P1 mesh of
cell size h.  ``f``, ``psi`` and ``u_D`` are numbers or callables ``g(x, y)``
that accept numpy arrays.  A :class:`Scene` is validated when it is built, so
bad input fails early with a ``ValueError`` naming the parameter.

Named scenes (:func:`scene`):

* ``"radial"``: Bueler's radial obstacle (used by PETSc's SNES VI examples,
  ex9): Omega = (-2, 2)^2, f = 0, psi = sqrt(1 - r^2) for r <= 1 and -1
  beyond, u_D = the exact solution :func:`radial_exact`.
* ``"pyramid"``: the unit square, a pyramid obstacle (non-smooth along its
  ridges) psi = 0.3 - 1.2 max(|x - 1/2|, |y - 1/2|), load f = -10, u_D = 0.
  No exact solution; checked against cvxpy/Clarabel on the same discrete QP.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

SIDES = ("lower", "upper")

# ---------------------------------------------------------------- the radial obstacle
#: radius of the free boundary: the root of a^2 (1 - ln(a/2)) = 1
A_STAR = 0.697965148223374
#: u = -A ln r + B outside the contact disk (A from u' continuous at a*, B from u(2) = 0)
A_COEF = A_STAR**2 / math.sqrt(1 - A_STAR**2)
B_COEF = A_COEF * math.log(2.0)


def radial_psi(x, y):
    """Bueler's obstacle: sqrt(1 - r^2) for r <= 1, -1 beyond."""
    r2 = np.asarray(x, dtype=float) ** 2 + np.asarray(y, dtype=float) ** 2
    return np.where(r2 <= 1.0, np.sqrt(np.maximum(1.0 - r2, 0.0)), -1.0)


def radial_exact(x, y):
    """The exact solution: psi(r) for r <= a*, -A ln r + B beyond."""
    r = np.hypot(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
    return np.where(r <= A_STAR, np.sqrt(np.maximum(1.0 - r**2, 0.0)),
                    -A_COEF * np.log(np.maximum(r, 1e-300)) + B_COEF)


def radial_exact_cf():
    """The exact solution and its gradient as NGSolve coefficient functions."""
    import ngsolve as ng
    r2 = ng.x**2 + ng.y**2
    r = ng.sqrt(r2)
    inside = ng.sqrt(ng.IfPos(1 - r2, 1 - r2, 1e-300))
    outside = -A_COEF * ng.log(ng.IfPos(r - 1e-300, r, 1e-300)) + B_COEF
    u = ng.IfPos(A_STAR - r, inside, outside)
    grad = ng.IfPos(A_STAR - r, ng.CF((-ng.x / inside, -ng.y / inside)),
                    ng.CF((-A_COEF * ng.x / (r2 + 1e-300), -A_COEF * ng.y / (r2 + 1e-300))))
    return u, grad


def pyramid_psi(x, y):
    """A pyramid of height 0.3 over (1/2, 1/2), slope 1.2, -0.3 on the boundary."""
    return 0.3 - 1.2 * np.maximum(np.abs(np.asarray(x, dtype=float) - 0.5), np.abs(np.asarray(y, dtype=float) - 0.5))


# ---------------------------------------------------------------- the scene
@dataclass(frozen=True)
class Scene:
    """An obstacle problem on the rectangle ``box`` = (x0, x1, y0, y1).

    ``h`` is the cell size of the structured mesh (round((x1-x0)/h) x
    round((y1-y0)/h) squares, each cut into two triangles); ``f``, ``psi``,
    ``u_D`` are numbers or vectorised callables g(x, y); ``side`` is
    ``"lower"`` (u >= psi) or ``"upper"`` (u <= psi); ``exact`` is the exact
    solution (a callable like u_D) or None.
    """

    box: tuple[float, float, float, float] = (0.0, 1.0, 0.0, 1.0)
    h: float = 1 / 32
    f: Any = 0.0
    psi: Any = 0.0
    u_D: Any = 0.0
    side: str = "lower"
    exact: Callable | None = None
    name: str = ""

    def __post_init__(self):
        object.__setattr__(self, "box", tuple(self.box))
        self.validate()

    # -- derived quantities
    @property
    def counts(self) -> tuple[int, int]:
        """Numbers of squares (nx, ny) of the structured mesh."""
        x0, x1, y0, y1 = self.box
        return max(1, round((x1 - x0) / self.h)), max(1, round((y1 - y0) / self.h))

    def with_h(self, h: float) -> "Scene":
        """The same scene with cell size h."""
        return dataclasses.replace(self, h=h)

    def evaluate(self, name: str, x, y) -> np.ndarray:
        """Values of the field ``name`` (f, psi, u_D) at the points (x, y), checked finite."""
        g = getattr(self, name)
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        try:
            v = np.broadcast_to(np.asarray(g(x, y) if callable(g) else g, dtype=float), x.shape).copy()
        except Exception as err:
            raise ValueError(f"{name}: evaluating it failed: {err}") from None
        bad = ~np.isfinite(v)
        if bad.any():
            i = np.flatnonzero(bad.ravel())[0]
            raise ValueError(f"{name} is not finite at ({x.ravel()[i]:g}, {y.ravel()[i]:g}) "
                             f"({bad.sum()} such points); accepted: finite values")
        return v

    # -- validation
    def validate(self) -> None:
        """Raise ValueError naming the offending parameter and its accepted range."""
        if len(self.box) != 4 or not all(_is_real(v) and math.isfinite(v) for v in self.box):
            raise ValueError(f"box = {self.box!r}; accepted: four finite numbers (x0, x1, y0, y1)")
        x0, x1, y0, y1 = self.box
        if not (x0 < x1 and y0 < y1):
            raise ValueError(f"box = {self.box!r}; accepted: x0 < x1 and y0 < y1")
        if not (_is_real(self.h) and math.isfinite(self.h) and self.h > 0):
            raise ValueError(f"h = {self.h!r} is outside the accepted range 0 < h (finite)")
        if self.h > min(x1 - x0, y1 - y0) / 1.5:     # two squares across (round(side / h) >= 2): an interior node
            raise ValueError(f"h = {self.h} is larger than the domain allows; accepted 0 < h <= "
                             f"{min(x1 - x0, y1 - y0) / 1.5:.6g} (two squares across its shorter side, so that "
                             f"the mesh has an interior node)")
        nx, ny = self.counts
        if (nx + 1) * (ny + 1) > 4_000_000:
            raise ValueError(f"h = {self.h} is too small: {(nx + 1) * (ny + 1)} nodes (at most 4e6 accepted)")
        if self.side not in SIDES:
            raise ValueError(f"side = {self.side!r}; accepted: {', '.join(SIDES)}")
        for name in ("f", "psi", "u_D"):
            g = getattr(self, name)
            if not (callable(g) or _is_real(g)):
                raise ValueError(f"{name} must be a number or a callable g(x, y), got {g!r}")
        if self.exact is not None and not callable(self.exact):
            raise ValueError(f"exact must be a callable u(x, y) or None, got {self.exact!r}")
        # sample the fields on a grid (the mesh nodes are checked again in make_problem)
        X, Y = np.meshgrid(np.linspace(x0, x1, 41), np.linspace(y0, y1, 41))
        for name in ("f", "psi", "u_D"):
            self.evaluate(name, X, Y)
        t = np.linspace(0.0, 1.0, 81)
        bx = np.concatenate([x0 + (x1 - x0) * t, np.full_like(t, x1), x0 + (x1 - x0) * t, np.full_like(t, x0)])
        by = np.concatenate([np.full_like(t, y0), y0 + (y1 - y0) * t, np.full_like(t, y1), y0 + (y1 - y0) * t])
        check_boundary(self, bx, by)


def check_boundary(scene: Scene, x, y, tol: float = 1e-12) -> None:
    """Raise ValueError if the obstacle violates the boundary data at a point (x, y).

    For u >= psi the problem is infeasible when psi > u_D somewhere on the
    boundary (and for u <= psi when psi < u_D).
    """
    psi, uD = scene.evaluate("psi", x, y), scene.evaluate("u_D", x, y)
    gap = (psi - uD) if scene.side == "lower" else (uD - psi)
    bad = gap > tol * (1.0 + np.abs(uD))
    if bad.any():
        i = int(np.argmax(gap))
        where = "above" if scene.side == "lower" else "below"
        raise ValueError(f"psi: the obstacle lies {where} the boundary data u_D at ({x[i]:g}, {y[i]:g}) "
                         f"(psi = {psi[i]:g}, u_D = {uD[i]:g}); the problem is infeasible")


def _is_real(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)


# ---------------------------------------------------------------- named scenes
def radial(h: float = 1 / 16, **changes) -> Scene:
    """Bueler's radial obstacle on (-2, 2)^2 with its exact solution."""
    fields = dict(box=(-2.0, 2.0, -2.0, 2.0), h=h, f=0.0, psi=radial_psi, u_D=radial_exact,
                  exact=radial_exact, side="lower", name="radial")
    return Scene(**(fields | changes))


def pyramid(h: float = 1 / 32, **changes) -> Scene:
    """A pyramid obstacle on the unit square under the load f = -10, u_D = 0."""
    fields = dict(box=(0.0, 1.0, 0.0, 1.0), h=h, f=-10.0, psi=pyramid_psi, u_D=0.0, side="lower", name="pyramid")
    return Scene(**(fields | changes))


SCENES = {"radial": radial, "pyramid": pyramid}


def scene(name: str, h: float | None = None, **changes) -> Scene:
    """The named scene (``"radial"`` or ``"pyramid"``), optionally with cell size h."""
    if name not in SCENES:
        raise ValueError(f"scene = {name!r} is unknown; known scenes: {', '.join(SCENES)}")
    return SCENES[name](**({} if h is None else {"h": h}), **changes)
