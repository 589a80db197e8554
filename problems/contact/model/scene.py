"""Declarative description of a 2D plane-strain contact problem (frictionless, stick, Tresca or Coulomb).

A :class:`Scene` says *what* is solved (geometry, mesh, material, boundary
conditions, gap); :func:`admmkit.problems.contact.model.assembly.assemble` turns it into matrices.
Every scene is validated when it is built, so bad input fails early with a
``ValueError`` that names the parameter and the accepted range.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from admmkit.problems.expressions import as_function as _as_func, expression, finite_positive as _finite_positive
from admmkit.problems.contact.solvers.friction import TANGENTIAL, check_friction_fields
from admmkit.problems.contact.model.memory import InsufficientMemory, available_memory, estimate_memory, rectangle_measure
from admmkit.problems.contact.model.mesh import BOUNDARY_NAMES

MESH_KINDS = ("structured", "unstructured")
SCENES_DIR = Path(__file__).parents[1] / "scenes"   # problems/contact/scenes: the package data
#: more cells than this is refused outright (the memory check refuses far fewer; this keeps its arithmetic finite)
MAX_CELLS = 1e12

# ---------------------------------------------------------------- scene
class FrozenDict(dict):
    """A hashable dict (keeps Scene hashable); do not mutate it."""

    def __hash__(self):
        return hash(tuple(sorted(self.items(), key=lambda kv: kv[0])))


@dataclass(frozen=True)
class Scene:
    """Linear elastic body on a rigid foundation, plane strain, small deformations.

    Geometry: the rectangle (0, L) x (0, H) with boundary labels bottom/right/top/left,
    meshed ``"structured"`` (FreeFEM ``square``: round(L/h) x round(H/h) squares cut in two) or
    ``"unstructured"`` (netgen, maxh = h); or, if ``geometry`` is a netgen geometry
    object, that geometry meshed by netgen (labels are then its boundary names).

    Boundary conditions: u = 0 on the ``dirichlet`` labels, sigma n = t on the labels
    of ``tractions`` (a constant 2-vector or a pair/callable of (x, y)), unmentioned
    labels are traction free; contact u.n <= g on ``contact``; tangentially
    sigma_t = 0 (``"frictionless"``, the default), u_t = 0 (``"stick"``, the paper's eq. (1)),
    Tresca friction (tangential traction at most s) with the slip bound ``slip_bound`` = s(x, y) >= 0
    (``"tresca"``) or Coulomb friction (at most mu times the pressure) with the coefficient ``mu`` >= 0
    (``"coulomb"``); ``obstacle_slide`` moves the foundation by that tangential displacement
    (along t = (-n_y, n_x); friction only), see ``problems/contact/solvers/friction.py`` and docs/friction.md.
    ``gap`` and ``body_force`` likewise accept numbers, callables or expressions in x, y.
    ``contact_normal``: None measures u.n along the body's outward normal at each contact
    node; a pair (nx, ny) measures it along that fixed direction instead, the outward
    normal of a flat obstacle (e.g. (0, -1) for the plane below a curved body, as in Hertz
    contact; g is then the distance to the obstacle along it).
    """

    L: float = 1.0
    H: float = 1.0
    h: float = 1 / 40
    mesh_kind: str = "structured"
    order: int = 1
    E: float = 1.0
    nu: float = 0.3
    dirichlet: tuple[str, ...] = ("left",)
    tractions: Mapping[str, Any] = field(default_factory=dict)
    body_force: Any = None
    contact: str = "bottom"
    gap: Any = 0.0
    tangential: str = "frictionless"
    geometry: Any = None
    name: str = ""
    contact_normal: Any = None
    slip_bound: Any = None
    mu: Any = None
    obstacle_slide: float = 0.0

    def __post_init__(self):
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731 (frozen)
        if isinstance(self.dirichlet, str):
            set_("dirichlet", (self.dirichlet,))
        set_("dirichlet", tuple(self.dirichlet))
        set_("tractions", FrozenDict({k: _traction(v, f"tractions[{k!r}]") for k, v in dict(self.tractions).items()}))
        if self.body_force is not None:
            set_("body_force", _traction(self.body_force, "body_force"))
        set_("gap", _as_func(self.gap, "gap"))
        if self.contact_normal is not None:
            set_("contact_normal", _unit_pair(self.contact_normal, "contact_normal"))
        if self.slip_bound is not None:
            set_("slip_bound", _as_func(self.slip_bound, "slip_bound"))
        self.validate()

    # -- derived quantities
    @property
    def labels(self) -> tuple[str, ...]:
        """Boundary labels: bottom/right/top/left, or the names in the netgen geometry."""
        return BOUNDARY_NAMES if self.geometry is None else tuple(_geometry_labels(self.geometry))

    def with_h(self, h: float) -> "Scene":
        """The same scene with mesh size h."""
        return dataclasses.replace(self, h=h)

    def gap_at(self, x: float, y: float) -> float:
        """The gap g(x, y)."""
        return float(self.gap(x, y)) if callable(self.gap) else float(self.gap)

    # -- validation
    def validate(self) -> None:
        """Raise ValueError naming the offending parameter and its accepted range."""
        _finite_positive(self.E, "E", "E > 0")
        if not (isinstance(self.nu, (int, float)) and -1.0 < self.nu < 0.5):
            raise ValueError(f"nu = {self.nu!r} is outside the accepted range -1 < nu < 0.5")
        if self.order not in (1, 2):
            raise ValueError(f"order = {self.order!r}; accepted: 1 or 2")
        if self.mesh_kind not in MESH_KINDS:
            raise ValueError(f"mesh_kind = {self.mesh_kind!r}; accepted: {', '.join(MESH_KINDS)}")
        if self.tangential not in TANGENTIAL:
            raise ValueError(f"tangential = {self.tangential!r}; accepted: {', '.join(TANGENTIAL)}")
        _finite_positive(self.h, "h", "0 < h (finite)")
        if self.geometry is None:
            _finite_positive(self.L, "L", "L > 0")
            _finite_positive(self.H, "H", "H > 0")
            if self.h > min(self.L, self.H):
                raise ValueError(f"h = {self.h} is larger than the rectangle; accepted 0 < h <= "
                                 f"min(L, H) = {min(self.L, self.H)}")
            if (self.L / self.h) * (self.H / self.h) > MAX_CELLS:   # before any count overflows a float
                raise ValueError(f"h = {self.h!r} is too small: (L/h)(H/h) = {(self.L / self.h) * (self.H / self.h):.3g} "
                                 f"cells; accepted: h with at most {MAX_CELLS:.0e} cells")
            area, perim = rectangle_measure(self)
            need = estimate_memory(area, perim, self.h, self.order, self.mesh_kind, solver="iterative")
            have = available_memory()
            if need > have:   # refused before anything is assembled; the direct modes check again (memory_need)
                direct = estimate_memory(area, perim, self.h, self.order, self.mesh_kind)
                raise InsufficientMemory(f"h = {self.h} is too small: the system needs about {need / 2**30:.3g} GiB "
                                 f"with the iterative x-step ({direct / 2**30:.3g} GiB with a sparse "
                                 f"factorisation), only {have / 2**30:.3g} GiB available; choose a larger h")
        elif self.mesh_kind != "unstructured":
            raise ValueError("mesh_kind = 'structured' needs the built-in rectangle; "
                             "with a netgen geometry use mesh_kind = 'unstructured'")
        labels = self.labels
        for name, used in [("dirichlet", self.dirichlet), ("tractions", tuple(self.tractions)),
                           ("contact", (self.contact,))]:
            for label in used:
                if label not in labels:
                    raise ValueError(f"{name}: unknown boundary label {label!r}; known labels: {', '.join(labels)}")
        if not self.dirichlet:
            raise ValueError("dirichlet: no clamped boundary; at least one label is needed "
                             "(otherwise the stiffness matrix K is singular)")
        if not self.contact:
            raise ValueError(f"contact: empty contact boundary; give one of {', '.join(labels)}")
        if self.contact in self.dirichlet:
            raise ValueError(f"contact: label {self.contact!r} is also clamped (dirichlet); "
                             f"the contact boundary would have no free node")
        if self.contact in self.tractions:
            raise ValueError(f"tractions: label {self.contact!r} is the contact boundary")
        if not callable(self.gap) and not math.isfinite(self.gap):
            raise ValueError(f"gap = {self.gap!r} is not finite; accepted: a finite number or function")
        if callable(self.gap) and self.geometry is None:  # sample g along the contact edge
            for x, y in _edge_points(self.contact, self.L, self.H):
                try:
                    value = float(self.gap(x, y))
                except Exception as err:
                    raise ValueError(f"gap: g({x:g}, {y:g}) failed: {err}") from None
                if not math.isfinite(value):
                    raise ValueError(f"gap: g({x:g}, {y:g}) = {value} is not finite; accepted: finite values")
        points = _edge_points(self.contact, self.L, self.H) if self.geometry is None else []
        check_friction_fields(self.tangential, self.slip_bound, self.mu, points)
        check_slide(self.obstacle_slide, self.tangential, 1)


def check_slide(value, tangential: str, components: int) -> None:
    """Check obstacle_slide: finite (a number in 2D, a pair in 3D), nonzero only with friction."""
    parts = (value,) if components == 1 else value
    ok = isinstance(parts, (list, tuple)) and len(parts) == components and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in parts)
    if not ok:
        what = "a finite number" if components == 1 else f"{components} finite numbers"
        raise ValueError(f"obstacle_slide = {value!r}; accepted: {what}")
    if any(parts) and tangential not in ("tresca", "coulomb"):
        raise ValueError(f"obstacle_slide = {value!r} moves the foundation tangentially, which acts only "
                         f"with friction (tangential = 'tresca' or 'coulomb'), got tangential = {tangential!r}")


def _unit_pair(value, name: str) -> tuple[float, float]:
    """A pair of finite numbers, not both zero, scaled to unit length."""
    ok = isinstance(value, (list, tuple)) and len(value) == 2 and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
    norm = math.hypot(*value) if ok else 0.0
    if not ok or norm == 0.0:
        raise ValueError(f"{name} = {value!r}; accepted: None or a pair (nx, ny) of finite numbers, not both 0")
    return (value[0] / norm, value[1] / norm)


def _edge_points(label: str, L: float, H: float, n: int = 21):
    """n points along one side of the rectangle."""
    t = [i / (n - 1) for i in range(n)]
    side = {"bottom": lambda s: (L * s, 0.0), "top": lambda s: (L * s, H),
            "left": lambda s: (0.0, H * s), "right": lambda s: (L, H * s)}[label]
    return [side(s) for s in t]


def _traction(value, name: str):
    """A constant 2-vector (tuple of floats) or a callable (x, y) -> 2-vector."""
    if callable(value):
        return value
    if isinstance(value, (list, tuple)) and len(value) == 2:
        parts = tuple(_as_func(v, name) for v in value)
        if all(isinstance(p, float) for p in parts):
            if not all(math.isfinite(p) for p in parts):
                raise ValueError(f"{name} = {value!r} is not finite")
            return parts
        return lambda x, y: tuple(p(x, y) if callable(p) else p for p in parts)
    raise ValueError(f"{name} must be a pair (tx, ty) of numbers/expressions or a callable, got {value!r}")


def _geometry_labels(geometry) -> list[str]:
    """Boundary names of a netgen geometry (OCCGeometry in 2D or SplineGeometry)."""
    if hasattr(geometry, "shape"):  # netgen.occ.OCCGeometry
        return sorted({e.name for e in geometry.shape.edges if e.name})
    if hasattr(geometry, "GetBCName"):  # netgen.geom2d.SplineGeometry
        names = {geometry.GetBCName(i) for i in range(1, geometry.GetNSplines() + 1)}
        return sorted(names - {"default"})
    raise ValueError(f"geometry: unsupported object {type(geometry).__name__}; "
                     "accepted: None (rectangle), netgen.occ.OCCGeometry, netgen.geom2d.SplineGeometry")


def is_scene3d(scene) -> bool:
    """Whether ``scene`` is a 3D ``Scene3D`` (problems/contact/model/scene3d.py), asked without importing its
    module: a Scene3D exists only once that module is imported, which a 2D run does not do (issue #49)."""
    import sys
    scene3d = sys.modules.get("admmkit.problems.contact.model.scene3d")
    return scene3d is not None and isinstance(scene, scene3d.Scene3D)


# ---------------------------------------------------------------- the paper's examples
def example1(h: float = 1 / 40, **changes) -> Scene:
    """Paper's Example 1: (0,2)x(0,1), clamped at x=0, top traction (0,-10), g = 0.01,
    E = 2000, nu = 0.3; ``changes`` override any Scene field (e.g. order=2)."""
    fields = dict(L=2.0, H=1.0, h=h, E=2000.0, nu=0.3, dirichlet=("left",),
                  tractions={"top": (0.0, -10.0), "right": (0.0, 0.0)}, contact="bottom",
                  gap=0.01, name="example1")
    return Scene(**(fields | changes))


def example2(h: float = 1 / 40, **changes) -> Scene:
    """Paper's Example 2: (0,3)x(0,1), clamped at x=0, right traction (0,-2),
    g(x) = 0.003 (x - 1.5)^2 + 0.001, E = 5000, nu = 0.49."""
    fields = dict(L=3.0, H=1.0, h=h, E=5000.0, nu=0.49, dirichlet=("left",),
                  tractions={"right": (0.0, -2.0), "top": (0.0, 0.0)}, contact="bottom",
                  gap=expression("0.003*(x - 1.5)**2 + 0.001"), name="example2")
    return Scene(**(fields | changes))
