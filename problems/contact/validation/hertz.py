"""Hertz validation: an elastic half-cylinder pressed onto a rigid plane (plane strain, frictionless).

The body is the lower half of the disk of radius R centred at (0, R),

    x^2 + (y - R)^2 <= R^2,  y <= R,

which touches the rigid plane y = 0 at the origin.  Hertz's two-dimensional
solution (K. L. Johnson, *Contact Mechanics*, Cambridge University Press 1985,
section 4.2: contact of cylinders with parallel axes) for a load P per unit
length, with E* = E/(1 - nu^2) for a rigid plane, is

    a  = sqrt(4 P R / (pi E*))          contact half-width
    p0 = 2 P / (pi a)                   peak pressure
    p(x) = p0 sqrt(1 - x^2/a^2)         pressure profile, |x| <= a.

It assumes a parabolic profile x^2/(2R) and a << R (both bodies treated as
half-spaces).

**How the body is loaded: a prescribed displacement, and P is the measured
reaction.**  The flat top y = R is moved down by delta.  Moving the whole body
rigidly by (0, delta) changes no strain, so this is the same as clamping the
top (u = 0) and raising the plane by delta: the gap becomes
g(x) = R - sqrt(R^2 - x^2) - delta (an interference of delta at x = 0).  The
load P is the reaction, the total contact force sum_i mc_i lam_i.  A uniform
traction on the top instead would leave no boundary clamped: K would be
singular, and for frictionless contact the horizontal translation would be
restrained by nothing at all.  By Saint-Venant's principle the two loadings
differ only far from the contact when a << R, and a(P), p0(P) are local
quantities, so comparing with Hertz at the measured P is fair.

**The gap is the exact circle, measured along the plane's normal.**
g(x) = R - sqrt(R^2 - x^2) - delta is the body's height above the plane at
the contact nodes (netgen puts boundary vertices on the circle), and u.n is
measured along the plane's outward normal (0, -1) (``Scene.contact_normal``),
not along the body's normal, as for a rigid plane.  Hertz's parabola x^2/(2R)
differs from the circle by x^4/(8R^3), a relative x^2/(4R^2) <= (a/R)^2/4,
i.e. 1e-4 at the contact edge for the default a/R = 0.02 (``profile="parabola"``
uses the parabola).

**The mesh is refined only near the contact:** the contact nonlinearity lives
on Gamma_C.  Only the arc |x| <= x_c of the circle (x_c = 2.5 a_target by
default) is the contact boundary.  The mesh size is h_c on it and in the
half-disk r <= r_z = 2 a_target around the origin (netgen ``RestrictH``), where
Hertz's stress field varies on the scale a, and grows to maxh h (R/4)
elsewhere with netgen's grading 0.3.  Refining the contact edge alone is not
enough: with h_c only on the edge, the elements at depth ~a stay ~0.3 a
whatever h_c, and the computed a and p0 stalled 3 % off Hertz's values.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from admmkit.problems.contact.model.scene import Scene

PROFILES = ("circle", "parabola")


def e_star(E: float, nu: float) -> float:
    """Plane-strain modulus against a rigid plane: E* = E / (1 - nu^2)."""
    return E / (1.0 - nu * nu)


def hertz_half_width(P: float, R: float, E: float, nu: float) -> float:
    """a = sqrt(4 P R / (pi E*)) (Johnson 1985, section 4.2)."""
    return math.sqrt(4.0 * P * R / (math.pi * e_star(E, nu)))


def hertz_peak_pressure(P: float, a: float) -> float:
    """p0 = 2 P / (pi a)."""
    return 2.0 * P / (math.pi * a)


def hertz_load(a: float, R: float, E: float, nu: float) -> float:
    """The load per unit length that gives half-width a: P = pi E* a^2 / (4 R)."""
    return math.pi * e_star(E, nu) * a * a / (4.0 * R)


def hertz_pressure(x: np.ndarray, P: float, R: float, E: float, nu: float) -> np.ndarray:
    """Hertz's p(x) = p0 sqrt(1 - x^2/a^2) (0 outside |x| < a)."""
    a = hertz_half_width(P, R, E, nu)
    p0 = hertz_peak_pressure(P, a)
    return p0 * np.sqrt(np.maximum(1.0 - (np.asarray(x) / a) ** 2, 0.0))


def half_cylinder_geometry(R: float, x_c: float, h_c: float):
    """netgen OCC geometry of the half-disk; edges "contact" (|x| <= x_c, maxh h_c), "free", "top".

    The contact arc is two arcs meeting at the origin, so that a vertex sits
    at x = 0 where the peak pressure is; netgen grades the interior mesh from
    h_c on the contact arc to the global maxh.
    """
    from netgen.occ import OCCGeometry, WorkPlane
    if not (0 < x_c < R):
        raise ValueError(f"contact half-width x_c = {x_c!r} must lie in (0, R = {R})")
    phi = math.degrees(math.asin(x_c / R))
    wp = WorkPlane().MoveTo(-R, R).Direction(0, -1)       # top-left corner, heading down
    wp.Arc(R, 90 - phi, name="free")
    wp.Arc(R, phi, name="contact", maxh=h_c).Arc(R, phi, name="contact", maxh=h_c)
    wp.Arc(R, 90 - phi, name="free").LineTo(-R, R, name="top")
    return OCCGeometry(wp.Face(), dim=2)


class LocallyRefined:
    """A netgen OCC geometry meshed with size h_z in the half-disk r <= r_z around the origin.

    Quacks like the geometry itself for :class:`Scene` (``shape`` for the
    boundary names, ``GenerateMesh(maxh=...)``).
    """

    def __init__(self, geometry, h_z: float, r_z: float, grading: float = 0.3):
        self.geometry, self.h_z, self.r_z, self.grading = geometry, h_z, r_z, grading
        self.shape = geometry.shape

    def GenerateMesh(self, maxh: float, **_):  # noqa: N802 (netgen's name)
        """netgen mesh with local size h_z on a grid of points covering the zone."""
        from netgen.meshing import MeshingParameters
        mp = MeshingParameters(maxh=maxh, grading=self.grading)
        step = self.h_z
        xs = np.arange(-self.r_z, self.r_z + step / 2, step)
        ys = np.arange(0.0, self.r_z + step / 2, step)
        X, Y = np.meshgrid(xs, ys)
        inside = X**2 + Y**2 <= self.r_z**2
        for x, y in zip(X[inside], Y[inside]):
            mp.RestrictH(x=float(x), y=float(y), z=0.0, h=self.h_z)
        return self.geometry.GenerateMesh(mp=mp)


@dataclass(frozen=True)
class HertzCase:
    """Parameters of the Hertz scene (defaults: a/R = 0.02, E = 1, nu = 0.3)."""

    R: float = 1.0
    E: float = 1.0
    nu: float = 0.3
    a_target: float = 0.02
    delta: float | None = None    # prescribed approach; None: the estimate delta_guess()
    contact_factor: float = 2.5   # x_c = contact_factor * a_target
    zone_factor: float = 2.0      # r_z = zone_factor * a_target, refined to h_c
    h: float | None = None        # maxh away from the contact (default R/4)
    profile: str = "circle"

    def __post_init__(self):
        for name in ("R", "E", "a_target", "contact_factor", "zone_factor"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"{name} = {v!r}; accepted: a finite number > 0")
        if not (-1 < self.nu < 0.5):
            raise ValueError(f"nu = {self.nu!r}; accepted: -1 < nu < 0.5")
        if not self.a_target * self.contact_factor < self.R:
            raise ValueError(f"a_target * contact_factor = {self.a_target * self.contact_factor:g} must be < R = {self.R}")
        if self.contact_factor <= 1.2:
            raise ValueError(f"contact_factor = {self.contact_factor!r}; accepted: > 1.2 (the contact arc must "
                             f"extend past the contact zone)")
        if self.profile not in PROFILES:
            raise ValueError(f"profile = {self.profile!r}; accepted: {', '.join(PROFILES)}")

    @property
    def x_c(self) -> float:
        """Half-width of the contact boundary arc."""
        return self.contact_factor * self.a_target

    def gap(self, delta: float):
        """g(x) = R - sqrt(R^2 - x^2) - delta (or x^2/(2R) - delta)."""
        R = self.R
        if self.profile == "parabola":
            return lambda x, y: x * x / (2 * R) - delta
        return lambda x, y: R - (R * R - x * x) ** 0.5 - delta

    def scene(self, h_c: float, delta: float | None = None) -> Scene:
        """The contact Scene with contact mesh size h_c and approach delta."""
        if not (isinstance(h_c, (int, float)) and 0 < h_c <= self.x_c):
            raise ValueError(f"h_c = {h_c!r}; accepted: 0 < h_c <= x_c = {self.x_c:g}")
        delta = self.delta_guess() if delta is None else delta
        geometry = LocallyRefined(half_cylinder_geometry(self.R, self.x_c, h_c), h_c, self.zone_factor * self.a_target)
        return Scene(h=self.h or self.R / 4, mesh_kind="unstructured", order=1, E=self.E, nu=self.nu,
                     dirichlet=("top",), contact="contact", gap=self.gap(delta), geometry=geometry,
                     contact_normal=(0.0, -1.0), name=f"hertz(h_c={h_c:.3g})")

    def delta_guess(self) -> float:
        """The given delta, or a first guess from the 2D half-space estimate
        delta ~ P/(pi E*) (2 ln(2R/a) + 1) at P = hertz_load(a_target)."""
        if self.delta is not None:
            return self.delta
        P = hertz_load(self.a_target, self.R, self.E, self.nu)
        return P / (math.pi * e_star(self.E, self.nu)) * (2 * math.log(2 * self.R / self.a_target) + 1)


def measure(ops, lam: np.ndarray, p: np.ndarray, case: HertzCase) -> dict:
    """Contact half-width, peak pressure and load of a solution, and Hertz's values at that load.

    - P = sum_i mc_i lam_i, the vertical reaction per unit length;
    - p0_h = max_i lam_i (a node sits at x = 0, the geometry's point);
    - the active set is where the z-step put p on the obstacle (p = g); its
      outermost nodes x_in and the next ones x_out bracket the edge on each side;
    - a_h: on each side, p^2 (linear in x^2 for Hertz's profile) extrapolated to
      zero from the two outermost active nodes; the mean of both sides.
    """
    x = ops.xc[:, 0]
    P = float(ops.mc @ lam)
    active = p >= ops.g
    if not active.any():
        raise ValueError("no contact: increase delta")
    if active[0] or active[-1]:
        raise ValueError("the contact zone reaches the end of the contact arc: increase contact_factor")
    estimates, brackets = [], []
    for side in (+1, -1):
        idx = np.flatnonzero(active & (side * x >= 0))
        idx = idx[np.argsort(side * x[idx])]
        last, prev = idx[-1], idx[-2]
        nxt = last + side
        brackets.append((abs(x[last]), abs(x[nxt])))
        p_last, p_prev = lam[last] ** 2, lam[prev] ** 2
        if p_prev > p_last:
            x2 = x[last] ** 2 + p_last * (x[last] ** 2 - x[prev] ** 2) / (p_prev - p_last)
            estimates.append(math.sqrt(x2))
        else:
            estimates.append(abs(x[last]))
    a_hertz = hertz_half_width(P, case.R, case.E, case.nu)
    p0_hertz = hertz_peak_pressure(P, a_hertz)
    a_h = float(np.mean(estimates))
    p0_h = float(lam.max())
    return {"P": P, "a_h": a_h, "p0_h": p0_h, "a_hertz": a_hertz, "p0_hertz": p0_hertz,
            "a_err": a_h / a_hertz - 1.0, "p0_err": p0_h / p0_hertz - 1.0,
            "a_bracket": (float(np.mean([b[0] for b in brackets])), float(np.mean([b[1] for b in brackets]))),
            "active_nodes": int(active.sum()),
            "profile_err": float(np.max(np.abs(lam - hertz_pressure(x, P, case.R, case.E, case.nu))) / p0_hertz)}
