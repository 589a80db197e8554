"""3D contact: an elastic block on a rigid foundation with a curved gap (P1 or P2 tetrahedra, NGSolve).

The 3D analogue of the paper's Example 2 (:func:`example2_3d`): the block
(0, 3) x (0, 1) x (0, 1), clamped on the face x = 0 ("back"), loaded by the
traction (0, 0, -2) on the face x = 3 ("front"), resting without friction on
a rigid foundation under its bottom face z = 0 with the curved gap

    g(x, y) = 0.003 (x - 1.5)^2 + 0.003 (y - 0.5)^2 + 0.001,

E = 5000, nu = 0.49.  The contact model is the 2D one (docs/contact.md) one
dimension up: u.n <= g at the nodes of the contact face with n = (0, 0, -1),
lumped boundary mass (a third of the area of every adjacent triangle),
multiplier lam = pressure; P2 adds the edge midpoints of the face as contact
nodes, with HRZ-lumped weights.  The assembly is
:func:`admmkit.problems.contact.model.assembly3d.assemble3d`: it returns the same
``ContactOperators`` as the 2D assembly, so every contact mode and method
works unchanged; at useful sizes only the iterative mode is practical.

Symmetry planes (``symmetry``): faces on which only the normal displacement is 0 (u_x = 0 on back / front,
u_y = 0 on left / right, u_z = 0 on top), the mirror condition of a body symmetric about that face's plane
and loaded symmetrically; e.g. a quarter of a block symmetric about x = 0 and y = 0 (the scene hertz3d).

Mesh: ``block_mesh`` cuts nx x ny x nz cubes into 6 tetrahedra each, the
Kuhn triangulation of ``ngsolve.meshes.MakeStructured3DMesh(hexes=False)``
with the same vertex numbering and tetrahedra, built from arrays.  Boundary
names as there: back (x = 0), front (x = Lx), left (y = 0), right (y = Ly),
bottom (z = 0), top (z = Lz).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Mapping

import numpy as np

if TYPE_CHECKING:      # block_mesh imports NGSolve when it meshes: reading a scene file needs none
    import ngsolve as ng

from admmkit.problems.expressions import as_function, expression, finite_positive
from admmkit.problems.contact.model.memory import InsufficientMemory, available_memory, dofs3d, estimate_memory3d, memory_need3d  # noqa: F401  (memory_need3d: this scene's)
from admmkit.problems.contact.solvers.friction import check_friction_fields
from admmkit.problems.contact.model.scene import MAX_CELLS, FrozenDict, check_slide

FACES_3D = ("back", "front", "left", "right", "bottom", "top")
#: the displacement component normal to each face (the one a symmetry plane there fixes)
FACE_AXIS = {"back": "x", "front": "x", "left": "y", "right": "y", "bottom": "z", "top": "z"}
#: the 6 tetrahedra of a cube (local corners as in MakeStructured3DMesh: 0 = (i,j,k), 1 = k+1,
#: 2 = j+1,k+1, 3 = j+1, 4 = i+1, 5 = i+1,k+1, 6 = i+1,j+1,k+1, 7 = i+1,j+1); all share the diagonal 0-6
KUHN = ((0, 4, 5, 6), (0, 6, 7, 4), (0, 3, 7, 6), (0, 1, 6, 5), (0, 1, 2, 6), (0, 3, 6, 2))


def block_counts(Lx: float, Ly: float, Lz: float, h: float) -> tuple[int, int, int]:
    """Cubes per direction: round(L/h), at least 1."""
    return max(1, round(Lx / h)), max(1, round(Ly / h)), max(1, round(Lz / h))


def block_arrays(Lx: float, Ly: float, Lz: float, h: float) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """(points, tets, faces) of the structured tetrahedral mesh of the block (0, Lx) x (0, Ly) x (0, Lz) as arrays
    (module docstring): points (nv, 3), tets (6 nx ny nz, 4) as 0-based int32 vertex numbers, and for each name of
    FACES_3D its boundary triangles (int32, right-hand normal pointing out of the block), in the order
    :func:`block_mesh` gives them to netgen.  No netgen, no NGSolve."""
    nx, ny, nz = block_counts(Lx, Ly, Lz, h)
    I, J, Kk = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), np.arange(nz + 1), indexing="ij")
    points = np.column_stack([(I / nx).ravel() * Lx, (J / ny).ravel() * Ly, (Kk / nz).ravel() * Lz])
    vid = lambda i, j, k: (i * (ny + 1) + j) * (nz + 1) + k  # noqa: E731
    i, j, k = (a.ravel() for a in np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"))
    corners = np.column_stack([vid(i, j, k), vid(i, j, k + 1), vid(i, j + 1, k + 1), vid(i, j + 1, k),
                               vid(i + 1, j, k), vid(i + 1, j, k + 1), vid(i + 1, j + 1, k + 1), vid(i + 1, j + 1, k)])
    tets = np.empty((corners.shape[0] * 6, 4), dtype=np.int32)
    for t, local in enumerate(KUHN):
        tets[t::6] = corners[:, local]
    # boundary squares (lowest corner a, corners a, b, c = opposite, d; u, v the face's two
    # increasing coordinates): triangles (a, b, c), (a, c, d) follow the cube diagonals through
    # corner 0 / 6, so they are faces of the tetrahedra
    squares = {
        "back": (lambda u, v: vid(0, u, v), ny, nz),
        "front": (lambda u, v: vid(nx, u, v), ny, nz),
        "left": (lambda u, v: vid(u, 0, v), nx, nz),
        "right": (lambda u, v: vid(u, ny, v), nx, nz),
        "bottom": (lambda u, v: vid(u, v, 0), nx, ny),
        "top": (lambda u, v: vid(u, v, nz), nx, ny),
    }
    faces = {}
    for name in FACES_3D:
        fn, nu_, nv_ = squares[name]
        u, v = (a.ravel() for a in np.meshgrid(np.arange(nu_), np.arange(nv_), indexing="ij"))
        a, b, c, d = fn(u, v), fn(u + 1, v), fn(u + 1, v + 1), fn(u, v + 1)
        # du x dv is +x (back/front), -y (left/right), +z (bottom/top): flip where that points
        # into the block, so that every triangle's right-hand normal points out
        tri = [np.column_stack([a, b, c]), np.column_stack([a, c, d])]
        if name in ("back", "right", "bottom"):
            tri = [t[:, ::-1] for t in tri]
        faces[name] = np.vstack(tri).astype(np.int32)
    return points, tets, faces


def block_mesh(Lx: float, Ly: float, Lz: float, h: float) -> ng.Mesh:
    """Structured tetrahedral mesh of the block (0, Lx) x (0, Ly) x (0, Lz) (module docstring): the arrays of
    :func:`block_arrays` given to netgen."""
    import ngsolve as ng
    from netgen.meshing import FaceDescriptor, Mesh
    points, tets, faces = block_arrays(Lx, Ly, Lz, h)
    mesh = Mesh(dim=3)
    mesh.AddPoints(points)
    for bc, name in enumerate(FACES_3D, 1):
        mesh.Add(FaceDescriptor(surfnr=bc, domin=1, domout=0, bc=bc))
        mesh.SetBCName(bc - 1, name)
    mesh.AddElements(dim=3, index=1, data=tets, base=0)
    for bc, name in enumerate(FACES_3D, 1):
        mesh.AddElements(dim=2, index=bc, data=faces[name], base=0)
    return ng.Mesh(mesh)


# ---------------------------------------------------------------- the scene
@dataclass(frozen=True)
class Scene3D:
    """Linear elastic block on a rigid foundation, small deformations (3D).

    Tangentially on the contact face: ``"frictionless"`` (default), ``"stick"``
    (u_x = u_y = 0 there), ``"tresca"`` with ``slip_bound`` s(x, y) >= 0 or
    ``"coulomb"`` with ``mu`` >= 0, as in the 2D :class:`~admmkit.problems.contact.model.scene.Scene`;
    ``obstacle_slide`` = (w_x, w_y) moves the foundation tangentially (friction only).
    ``symmetry``: faces that are symmetry planes, u.n = 0 there and the tangential traction 0 (module docstring).
    """

    Lx: float = 3.0
    Ly: float = 1.0
    Lz: float = 1.0
    h: float = 1 / 8
    E: float = 5000.0
    nu: float = 0.49
    dirichlet: tuple[str, ...] = ("back",)
    tractions: Mapping[str, Any] = field(default_factory=lambda: {"front": (0.0, 0.0, -2.0)})
    contact: str = "bottom"
    gap: Any = 0.0
    name: str = ""
    order: int = 1
    tangential: str = "frictionless"
    slip_bound: Any = None
    mu: Any = None
    obstacle_slide: tuple[float, float] = (0.0, 0.0)
    symmetry: tuple[str, ...] = ()

    def __post_init__(self):
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731 (frozen)
        if isinstance(self.dirichlet, str):
            set_("dirichlet", (self.dirichlet,))
        set_("dirichlet", tuple(self.dirichlet))
        set_("symmetry", (self.symmetry,) if isinstance(self.symmetry, str) else tuple(self.symmetry))
        set_("tractions", FrozenDict({k: _traction3(v, f"tractions[{k!r}]") for k, v in dict(self.tractions).items()}))
        set_("gap", as_function(self.gap, "gap"))
        if self.slip_bound is not None:
            set_("slip_bound", as_function(self.slip_bound, "slip_bound"))
        if isinstance(self.obstacle_slide, list):
            set_("obstacle_slide", tuple(self.obstacle_slide))
        self.validate()

    @property
    def counts(self) -> tuple[int, int, int]:
        """Cubes per direction."""
        return block_counts(self.Lx, self.Ly, self.Lz, self.h)

    @property
    def mesh_kind(self) -> str:
        """Always the structured tetrahedral mesh."""
        return "structured"

    def gap_at(self, x: float, y: float) -> float:
        """g(x, y) on the contact face."""
        return float(self.gap(x, y)) if callable(self.gap) else float(self.gap)

    def validate(self) -> None:
        """Raise ValueError naming the offending parameter and its accepted range."""
        for name in ("Lx", "Ly", "Lz", "E"):
            finite_positive(getattr(self, name), name, f"{name} > 0")
        if not (isinstance(self.nu, (int, float)) and -1.0 < self.nu < 0.5):
            raise ValueError(f"nu = {self.nu!r} is outside the accepted range -1 < nu < 0.5")
        if self.order not in (1, 2) or isinstance(self.order, bool):
            raise ValueError(f"order = {self.order!r}; accepted: 1 (P1 tetrahedra) or 2 (P2)")
        finite_positive(self.h, "h", "0 < h (finite)")
        if self.h > min(self.Lx, self.Ly, self.Lz):
            raise ValueError(f"h = {self.h} is larger than the block; accepted 0 < h <= {min(self.Lx, self.Ly, self.Lz)}")
        cells = (self.Lx / self.h) * (self.Ly / self.h) * (self.Lz / self.h)
        if cells > MAX_CELLS:   # before any count overflows a float
            raise ValueError(f"h = {self.h!r} is too small: {cells:.3g} cubes; accepted: h with at most {MAX_CELLS:.0e} cubes")
        for what, labels in (("dirichlet", self.dirichlet), ("tractions", tuple(self.tractions)), ("contact", (self.contact,))):
            for label in labels:
                if label not in FACES_3D:
                    raise ValueError(f"{what}: unknown face {label!r}; known faces: {', '.join(FACES_3D)}")
        if not self.dirichlet:
            raise ValueError("dirichlet: no clamped face; at least one is needed (otherwise K is singular)")
        for label in self.symmetry:
            if label not in FACES_3D:
                raise ValueError(f"symmetry: unknown face {label!r}; known faces: {', '.join(FACES_3D)}")
            if label == self.contact or label in self.dirichlet or label in self.tractions:
                raise ValueError(f"symmetry: face {label!r} is also the contact face, clamped or loaded; accepted: "
                                 f"faces that are none of these")
        if self.contact != "bottom":
            raise ValueError(f"contact: {self.contact!r}; accepted: 'bottom' (the face z = 0 on the foundation)")
        if self.contact in self.dirichlet or self.contact in self.tractions:
            raise ValueError(f"contact: face {self.contact!r} is also clamped or loaded")
        need, have = estimate_memory3d(*self.counts, solver="iterative", order=self.order), available_memory()
        if need > have:
            raise InsufficientMemory(f"h = {self.h} is too small: {dofs3d(*self.counts, self.order):.3g} unknowns need "
                             f"about {need / 2**30:.3g} GiB with the iterative x-step "
                             f"({estimate_memory3d(*self.counts, order=self.order) / 2**30:.3g} GiB with a sparse "
                             f"factorisation), only {have / 2**30:.3g} GiB available; choose a larger h")
        for x in np.linspace(0, self.Lx, 7):
            for y in np.linspace(0, self.Ly, 7):
                value = self.gap_at(float(x), float(y))
                if not math.isfinite(value):
                    raise ValueError(f"gap: g({x:g}, {y:g}) = {value} is not finite; accepted: finite values")
        face = [(float(x), float(y)) for x in np.linspace(0, self.Lx, 7) for y in np.linspace(0, self.Ly, 7)]
        check_friction_fields(self.tangential, self.slip_bound, self.mu, face)
        check_slide(self.obstacle_slide, self.tangential, 2)

    def with_h(self, h: float) -> "Scene3D":
        """The same scene with mesh size h."""
        import dataclasses
        return dataclasses.replace(self, h=h)


def _traction3(value, name: str):
    """A constant 3-vector of finite numbers."""
    ok = isinstance(value, (list, tuple)) and len(value) == 3 and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
    if not ok:
        raise ValueError(f"{name} must be a triple (tx, ty, tz) of finite numbers, got {value!r}")
    return tuple(float(v) for v in value)


def example2_3d(h: float = 1 / 8, **changes) -> Scene3D:
    """The 3D analogue of the paper's Example 2 (module docstring)."""
    fields = dict(Lx=3.0, Ly=1.0, Lz=1.0, h=h, E=5000.0, nu=0.49, dirichlet=("back",),
                  tractions={"front": (0.0, 0.0, -2.0)}, contact="bottom",
                  gap=expression("0.003*(x - 1.5)**2 + 0.003*(y - 0.5)**2 + 0.001"), name="example2_3d")
    return Scene3D(**(fields | changes))
