"""Declarative description of an obstacle problem, and the named scenes.

    -Delta u = f in Omega,   u >= psi (side "lower") or u <= psi (side "upper"),
    u = u_D on the boundary,

on a rectangle Omega = (x0, x1) x (y0, y1), meshed with a structured P1 mesh of
cell size h.  ``f``, ``psi`` and ``u_D`` are numbers, callables ``g(x, y)``
that accept numpy arrays, or expression strings in x and y (:mod:`.fields`);
``exact``, the exact solution where one is known, an expression string or a
callable that also works on NGSolve coefficient functions (for the errors).
A :class:`Scene` is validated when it is built, so bad input fails early with
a ``ValueError`` naming the parameter.  Scene files (TOML): :mod:`.scene_file`.

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
from typing import Any

import ngsolve as ng
import numpy as np

from .fields import field

SIDES = ("lower", "upper")
#: the fields of a scene that may be given as expression strings in x and y
FIELDS = ("f", "psi", "u_D", "exact")

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
    ``u_D`` are numbers, vectorised callables g(x, y) or expression strings in
    x and y (``"sin(pi*x)"``; read into callables); ``side`` is ``"lower"``
    (u >= psi) or ``"upper"`` (u <= psi); ``exact`` is the exact solution or
    None: an expression string, a number, or a callable that works on numpy
    arrays and on ``ngsolve.x``, ``ngsolve.y`` (:meth:`exact_coefficients`:
    the errors are integrated against it).
    """

    box: tuple[float, float, float, float] = (0.0, 1.0, 0.0, 1.0)
    h: float = 1 / 32
    f: Any = 0.0
    psi: Any = 0.0
    u_D: Any = 0.0
    side: str = "lower"
    exact: Any = None
    name: str = ""

    def __post_init__(self):
        object.__setattr__(self, "box", tuple(self.box))
        for name in FIELDS:                                   # expression strings -> callables g(x, y)
            text = getattr(self, name)
            if isinstance(text, str):
                try:
                    object.__setattr__(self, name, field(text))
                except ValueError as err:
                    raise ValueError(f"{name}: {err}") from None
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

    def exact_coefficients(self) -> tuple[ng.CoefficientFunction, ng.CoefficientFunction]:
        """The exact solution u and its gradient as NGSolve coefficient functions (for the errors).

        The radial scene's :func:`radial_exact` has its written-out pair (``radial_exact_cf``); any other
        exact solution is evaluated on ``ngsolve.x``, ``ngsolve.y`` and differentiated by NGSolve (``Diff``).
        ValueError if the scene has none, or if it cannot be evaluated so (a callable using ``np.where``, say).
        """
        exact = self.exact
        if exact is None:
            raise ValueError(f"scene {self.name!r} has no exact solution")
        if exact is radial_exact:
            return radial_exact_cf()
        try:
            u = exact(ng.x, ng.y) if callable(exact) else exact
            u = ng.CoefficientFunction(float(u)) if _is_real(u) else u
            if not isinstance(u, ng.CoefficientFunction) or u.dim != 1:
                raise TypeError(f"it gave {type(u).__name__}")
            return u, ng.CoefficientFunction((u.Diff(ng.x), u.Diff(ng.y)))
        except Exception as err:
            raise ValueError(f"exact = {exact!r} cannot be evaluated as an NGSolve coefficient function of x, y "
                             f"({err}); accepted: an expression string such as 'sin(pi*x)*sin(pi*y)', a number, "
                             f"or a callable that works on ngsolve.x, ngsolve.y") from None

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
        nx, ny = self.counts
        if min(nx, ny) < 2:
            raise ValueError(f"h = {self.h:g} leaves no interior node ({nx} x {ny} squares): it is larger than the "
                             f"domain allows; accepted 0 < h <= {max_h(self.box):g}, two squares across the box's "
                             f"shorter side")
        if (nx + 1) * (ny + 1) > 4_000_000:
            raise ValueError(f"h = {self.h} is too small: {(nx + 1) * (ny + 1)} nodes (at most 4e6 accepted)")
        if self.side not in SIDES:
            raise ValueError(f"side = {self.side!r}; accepted: {', '.join(SIDES)}")
        for name in ("f", "psi", "u_D"):
            g = getattr(self, name)
            if not (callable(g) or _is_real(g)):
                raise ValueError(f"{name} must be a number, a callable g(x, y) or an expression string, got {g!r}")
        if self.exact is not None and not (callable(self.exact) or _is_real(self.exact)):
            raise ValueError(f"exact must be a number, a callable u(x, y), an expression string or None, "
                             f"got {self.exact!r}")
        if self.exact is not None:
            self.exact_coefficients()
        # sample the fields on a grid (the mesh nodes are checked again in make_problem)
        X, Y = np.meshgrid(np.linspace(x0, x1, 41), np.linspace(y0, y1, 41))
        for name in ("f", "psi", "u_D") + (("exact",) if self.exact is not None else ()):
            self.evaluate(name, X, Y)
        t = np.linspace(0.0, 1.0, 81)
        bx = np.concatenate([x0 + (x1 - x0) * t, np.full_like(t, x1), x0 + (x1 - x0) * t, np.full_like(t, x0)])
        by = np.concatenate([np.full_like(t, y0), y0 + (y1 - y0) * t, np.full_like(t, y1), y0 + (y1 - y0) * t])
        check_boundary(self, bx, by)


def max_h(box) -> float:
    """The largest cell size that leaves an interior node on the box: two squares across its shorter side
    (round(side / h) >= 2, i.e. h <= side / 1.5)."""
    x0, x1, y0, y1 = box
    return min(x1 - x0, y1 - y0) / 1.5


def has_radial_exact(scene: Scene) -> bool:
    """Whether the scene's exact solution is the radial one, whose free boundary is the circle r = a*."""
    return scene.exact is radial_exact


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
