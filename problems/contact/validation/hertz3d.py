"""Hertz in 3D: a body with a spherical cap pressed on a rigid plane (frictionless), the scene ``hertz3d``.

The body is the block (-0.5, 0.5)^2 x (0, 0.5) whose bottom face z = 0
carries the profile of a sphere of radius R = 1 centred over c = (0, 0): its
height above the rigid plane is R - sqrt(R^2 - r^2), r = |(x, y) - c|.  The
scene (problems/contact/scenes/hertz3d.toml) is its quarter x, y >= 0, with
the planes x = 0 and y = 0 as symmetry planes (``Scene3D.symmetry``: u.n = 0
there).  The top is clamped and the plane raised by delta = 0.0024 (as the
2D Hertz scene does, :mod:`admmkit.problems.contact.validation.hertz`), so
the gap is

    g(x, y) = R - sqrt(R^2 - r^2) - delta,

and the load F is the reaction, :func:`copies` (4) x sum_i mc_i lam_i.
E = 1, nu = 0.3.  This is Hertz's own model: a body whose surface is flat to
first order, with the initial separation of a sphere, and u.n measured along
the plane's normal.  Hertz (K. L. Johnson, *Contact Mechanics*, 1985,
section 4.2) for a sphere on a rigid plane, E* = E / (1 - nu^2):

    a  = (3 F R / (4 E*))^(1/3)          contact radius
    p0 = 3 F / (2 pi a^2)                peak pressure
    p(r) = p0 sqrt(1 - r^2 / a^2)         pressure profile, r <= a,

(and with a prescribed indentation d of a half-space, a = sqrt(R d)).  It
assumes a half-space and a << R.  Here a is about 0.05: a/R ~ 0.05, so the
sphere differs from Hertz's paraboloid r^2 / (2R) by at most (a/R)^2 / 4 ~
6e-4 relatively inside the contact; a / (the block's half-width and height)
~ 0.1, so the finite body changes the local field by about (a/H)^3 ~ 1e-3.
The comparison is at the measured F, since the approach delta of a clamped
finite block is not the half-space's d.

**What is measured** (:func:`measure`), from the nodal forces f_i = mc_i lam_i
(at an iterate of the condensed mode, exactly the forces of its displacement)
and the contact set (the nodes whose z-iterate p sits on the obstacle, p >= g):

- F = copies x sum_i f_i;
- ``a_fit`` and ``p0_fit``: Hertz's profile p0 s_a, s_a = sqrt(1 - r^2/a^2)+,
  closest in L2 of the contact face to the pressure p_h = M^{-1} f whose
  consistent loads are the nodal forces, M the Gram matrix of the nodal
  (Lagrange) basis on the face (:func:`face_mass`, :func:`profile_fit`).
  Only the forces and M enter: this is what P2 needs, whose vertices carry
  almost no force in 3D (the consistent P2 load of a triangle vanishes at its
  vertices), so the nodal pressures lam_i alternate between about 0
  (vertices) and 1.15-1.2 p0 (midpoints);
- ``a_moment``: the radius of the forces' second moment (:func:`moment_radius`),
  a second reading of a through the forces, without a fit;
- beside them, readings of the nodal pressures lam_i: ``a_h`` (the line of
  lam_i^2 against r_i^2 over the contact set's outer ring, r_i >= ``band`` x
  the outermost active radius, at zero: Hertz's p^2 is linear in r^2),
  ``p0_h`` (that line through all active nodes, at r = 0), ``a_area`` (the
  disc of the contact set's area) and ``p_max`` (the largest nodal pressure);
- the outermost active radius and the innermost inactive one (on P2 levels
  possibly a vertex inside the contact, whose force is near 0).

The nodal pressures of a lumped contact condition also oscillate about the
profile where a P1 mesh is not uniform (a node's weight mc_i and its
pressure go opposite ways, the force mc_i lam_i stays smooth): on an
adapted P1 level of 10,248 unknowns neighbours at r = 0.22 a and 0.31 a
read 1.04 p0 and 0.86 p0.  The readings through the forces are not affected.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

#: the scene's sphere radius, its centre over the plane, and the plane's rise (hertz3d.toml)
R_SPHERE = 1.0
CENTRE = (0.0, 0.0)
DELTA = 0.0024
#: the outer ring of the contact set whose pressures fix a_h: radii from this share of the outermost active one
BAND = 0.5


def e_star(E: float, nu: float) -> float:
    """The contact modulus against a rigid plane, E* = E / (1 - nu^2)."""
    return E / (1.0 - nu * nu)


def hertz_radius(F: float, R: float, E: float, nu: float) -> float:
    """Hertz's contact radius a = (3 F R / (4 E*))^(1/3) of a sphere of radius R under the load F."""
    if not (F > 0 and R > 0):
        raise ValueError(f"F = {F!r} and R = {R!r} must be > 0")
    return (3.0 * F * R / (4.0 * e_star(E, nu))) ** (1.0 / 3.0)


def hertz_peak_pressure(F: float, a: float) -> float:
    """p0 = 3 F / (2 pi a^2)."""
    return 3.0 * F / (2.0 * math.pi * a * a)


def hertz_load(a: float, R: float, E: float, nu: float) -> float:
    """The load that gives the contact radius a: F = 4 E* a^3 / (3 R)."""
    return 4.0 * e_star(E, nu) * a ** 3 / (3.0 * R)


def hertz_pressure(r: np.ndarray, F: float, R: float, E: float, nu: float) -> np.ndarray:
    """Hertz's p(r) = p0 sqrt(1 - r^2/a^2), 0 outside the contact radius."""
    a = hertz_radius(F, R, E, nu)
    return hertz_peak_pressure(F, a) * np.sqrt(np.maximum(1.0 - (np.asarray(r) / a) ** 2, 0.0))


def copies(scene) -> int:
    """How many copies of the model make the whole body: 2 per symmetry plane (they pass through the centre)."""
    return 2 ** len(getattr(scene, "symmetry", ()))


def radii(ops, centre=CENTRE) -> np.ndarray:
    """r = |(x, y) - centre| of every contact node."""
    return np.hypot(ops.xc[:, 0] - centre[0], ops.xc[:, 1] - centre[1])


def face_mass(ops) -> sp.csr_matrix:
    """The consistent mass matrix of the contact face's trace space (P1 or P2 Lagrange on its triangles) on the
    contact nodes, M_ij = int_Gamma phi_i phi_j; rows of nodes left out of the contact set (on a clamped face) are
    dropped.  For a nodal force vector f, M^{-1} f is the pressure p_h of the trace space whose consistent loads
    int p_h phi_i are f."""
    mesh, order = ops.mesh, ops.scene.order
    points = np.array(mesh.ngmesh.Coordinates())
    surface = mesh.ngmesh.Elements2D().NumPy()
    labels = np.array(mesh.GetBoundaries())[surface["index"] - 1]
    P = points[surface["nodes"][:, :3].astype(np.int64)[labels == ops.scene.contact] - 1]
    area = 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)
    if order == 2:
        P = np.concatenate([P, (P + np.roll(P, -1, axis=1)) / 2], axis=1)    # the midpoints of edges 01, 12, 20
    local = _triangle_mass(order)
    dist, idx = cKDTree(ops.xc[:, :2]).query(P[:, :, :2].reshape(-1, 2))
    idx = np.where(dist <= 1e-9 * max(1.0, float(np.abs(ops.xc).max())), idx, -1).reshape(len(P), -1)
    k = local.shape[0]
    rows, cols = np.repeat(idx, k, axis=1).ravel(), np.tile(idx, (1, k)).ravel()
    vals = (area[:, None, None] * local[None]).ravel()
    keep = (rows >= 0) & (cols >= 0)
    return sp.csr_matrix((vals[keep], (rows[keep], cols[keep])), shape=(ops.n_c, ops.n_c))


def _triangle_mass(order: int) -> np.ndarray:
    """The Lagrange P1 or P2 mass matrix of a triangle of unit area (P2: vertices 0-2, then the midpoints of edges
    01, 12, 20), A_ij / A = int phi_i phi_j / A."""
    if order == 1:
        return (np.ones((3, 3)) + np.eye(3)) / 12.0
    vertex = 6 * np.eye(3) - (np.ones((3, 3)) - np.eye(3))                       # 6 on the diagonal, -1 off it
    mid = 16 * (np.ones((3, 3)) + np.eye(3))                                      # 32 on the diagonal, 16 off it
    coupling = np.zeros((3, 3))
    coupling[0, 1], coupling[1, 2], coupling[2, 0] = -4, -4, -4                   # vertex i and the opposite edge
    return np.block([[vertex, coupling], [coupling.T, mid]]) / 180.0


def measure(ops, lam: np.ndarray, p: np.ndarray, *, R: float = R_SPHERE, centre=CENTRE, band: float = BAND,
            mass=None) -> dict:
    """F, a_fit and p0_fit (and the other readings of the module docstring) against Hertz's a and p0 at the
    measured F; ValueError when the contact set is too small to measure (fewer than 3 nodes in its outer ring).

    ``mass``: the Gram matrix of the nodal basis on the contact face that the fit uses, default
    :func:`face_mass` where ``ops`` has a mesh, else the lumped weights ``ops.mc`` (a diagonal).
    """
    scene = ops.scene
    lam = np.asarray(lam)[:ops.n_c]
    r = radii(ops, centre)
    forces = ops.mc * lam
    F = copies(scene) * float(forces.sum())
    active = np.asarray(p)[:ops.n_c] >= ops.g
    if F <= 0 or not active.any():
        raise ValueError("no contact: raise the plane (a larger delta)")
    r_in = float(r[active].max())
    r_out = float(r[~active].min()) if (~active).any() else math.inf
    ring = active & (r >= band * r_in)
    if ring.sum() < 3:
        raise ValueError(f"the contact set has {int(active.sum())} nodes, {int(ring.sum())} in its outer ring: too "
                         f"few to measure a (refine further)")
    slope, _ = np.polyfit(r[ring] ** 2, lam[ring] ** 2, 1)
    _, p0_squared = np.polyfit(r[active] ** 2, lam[active] ** 2, 1) if active.sum() >= 3 else (0.0, lam.max() ** 2)
    # the edge: the ring's line through the ring's mean, where it reaches zero
    mean_r2, mean_p2 = float(np.mean(r[ring] ** 2)), float(np.mean(lam[ring] ** 2))
    a_h = math.sqrt(mean_r2 - mean_p2 / slope) if slope < 0 else math.nan
    p0_h = math.sqrt(max(p0_squared, 0.0))
    a = hertz_radius(F, R, scene.E, scene.nu)
    p0 = hertz_peak_pressure(F, a)
    a_area = math.sqrt(copies(scene) * float(ops.mc[active].sum()) / math.pi)
    if mass is None:
        mass = face_mass(ops) if getattr(ops, "mesh", None) is not None else ops.mc
    a_fit, p0_fit = profile_fit(r, forces, mass, r_in)
    near = r < 1.5 * r_in
    a_moment = moment_radius(r[near], forces[near])
    return {"F": F, "a_h": a_h, "a_area": a_area, "a_area_err": a_area / a - 1.0, "a_hertz": a,
            "a_err": a_h / a - 1.0, "p0_h": p0_h, "p0_hertz": p0,
            "p0_err": p0_h / p0 - 1.0, "a_fit": a_fit, "a_fit_err": a_fit / a - 1.0, "p0_fit": p0_fit,
            "p0_fit_err": p0_fit / p0 - 1.0, "a_moment": a_moment, "a_moment_err": a_moment / a - 1.0,
            "p_max": float(lam.max()), "p_max_err": float(lam.max()) / p0 - 1.0,
            "edge_in": r_in / a, "edge_out": r_out / a, "active_nodes": int(active.sum())}


def moment_radius(r: np.ndarray, forces: np.ndarray) -> float:
    """The radius of the Hertz profile with the nodal forces' load and second moment: Hertz's pressure has
    int p r^2 = (2/5) a^2 F, so a = sqrt(5 sum f_i r_i^2 / (2 sum f_i)) (sum f_i r_i^2 is the forces' work on the
    displacement r^2, a P2 function: exactly int p_h r^2 for the pressure p_h of :func:`face_mass`)."""
    return math.sqrt(2.5 * float(forces @ (r * r)) / float(forces.sum()))


def profile_fit(r: np.ndarray, forces: np.ndarray, mass, r_in: float, steps: int = 4001) -> tuple[float, float]:
    """(a, p0) of Hertz's profile p0 s_a, s_a = sqrt(1 - r^2/a^2)+, closest to the pressure p_h = M^{-1} f of the
    nodal forces f in the L2 norm of the contact face, ||p_h - p0 s_a||_M^2 with M = ``mass`` (the Gram matrix of
    the nodal basis, :func:`face_mass`; a vector: a diagonal, the lumped weights) and s_a at the nodes: for a given
    a, p0 = f.s / s'Ms (the forces' work on s over its consistent load), and a is the best of ``steps`` values in
    [r_in / 2, 1.5 r_in] (r_in: the outermost active radius), the one that maximises (f.s)^2 / s'Ms."""
    r, f = np.asarray(r, dtype=float), np.asarray(forces, dtype=float)
    Ms = (lambda s: mass * s) if np.ndim(mass) == 1 else (lambda s: mass @ s)
    best = (-math.inf, math.nan, math.nan)
    for a in np.linspace(0.5 * r_in, 1.5 * r_in, steps):
        s = np.sqrt(np.maximum(1.0 - (r / a) ** 2, 0.0))
        weight = float(s @ Ms(s))
        if weight <= 0:
            continue
        work = float(f @ s)
        if work * work / weight > best[0]:
            best = (work * work / weight, float(a), work / weight)
    return best[1], best[2]


__all__ = ["profile_fit", "face_mass", "moment_radius", "copies", "R_SPHERE", "CENTRE", "DELTA", "BAND", "e_star", "hertz_radius", "hertz_peak_pressure",
           "hertz_load",
           "hertz_pressure", "radii", "measure"]
