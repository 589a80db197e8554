"""Hertz in ``admmkit bench adaptive``: the half-cylinder on a rigid plane, three ways of meshing it.

The scene is :class:`admmkit.problems.contact.validation.hertz.HertzCase`'s
(R = 1, E = 1, nu = 0.3, a ~ 0.02 R, the top clamped and the plane raised by
delta; docs/scale.md), meshed

- **adaptive**: ``solve_adaptive`` from netgen's coarse mesh (maxh R/4, the
  contact arc |x| <= 2.5 a_target in elements of its own length x_c / 1);
- **uniform**: netgen's quasi-uniform mesh of maxh 1/16 (the contact arc
  1/20) refined uniformly ``k`` times by NGSolve (every triangle marked;
  boundary vertices land on the circle), h = 2^-k / 16; a netgen mesh of
  maxh 1/256 alone took 16 s to make where the refinement takes 1 s;
- **a priori**: the Hertz validation's mesh (``HertzCase.scene``), size
  h_c = a_target / k on the contact arc and in the half-disk r <= 2 a_target.

The true energy error needs a reference (``contact.reference``,
started from the adaptive start in P2) and one correction,
:func:`penetration_term`: the obstacle is curved and the constraint holds at
the contact nodes only, so between two active nodes a P1 boundary cuts into
the plane's image by up to s^2 / (8 R) (s the node spacing), which lowers
J(u_h) below J(u). With e = u_h - u and p the contact pressure,
J(u_h) - J(u) = ||e||_a^2 / 2 - int p (u_h.n - g), so the study's true
error adds c_h = int p_h (u_h.n - g) back, with the discrete pressure p_h,
over the elements in contact (the edge's elements left out).
Every level also reports the errors of the contact half-width a and of the
peak pressure p0 against Hertz's formulas at the measured load
(:func:`hertz_errors`).
"""
from __future__ import annotations

import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np

#: uniform refinements of the base mesh (maxh 1/16) and a priori a_target / h_c, by order.  P2 stops at
#: 59,280 unknowns (two refinements): before P2 dofs had coordinates for the nested dissection, the next
#: uniform P2 mesh (about 237,000) sat in SuperLU's factorisation of the condensed set-up for over 5 minutes
#: (not tried since; the 59,280 one went from 10.7 s to 1.8 s)
UNIFORM_BASE_H = 1 / 16
UNIFORM_TIMES = {1: (0, 1, 2, 3, 4, 5), 2: (0, 1, 2)}
A_PRIORI_K = {1: (5, 10, 20, 40, 80, 160), 2: (5, 10, 20, 40)}
GAUSS = np.polynomial.legendre.leggauss(6)


class UniformlyRefined:
    """A netgen geometry meshed with maxh, then every triangle bisected ``times`` times by NGSolve.

    Quacks like the geometry for :class:`Scene` (``shape``, ``GenerateMesh``), as ``LocallyRefined`` does.
    (NGSolve's refinement, not netgen's: an NGSolve mesh made from a netgen-refined one crashed when the
    adaptive loop refined it again.)
    """

    def __init__(self, geometry, times: int):
        self.geometry, self.times, self.shape = geometry, times, geometry.shape

    def GenerateMesh(self, maxh: float, **_):  # noqa: N802 (netgen's name)
        """netgen's mesh of size maxh, refined uniformly ``times`` times."""
        import ngsolve as ng
        mesh = ng.Mesh(self.geometry.GenerateMesh(maxh=maxh))
        for _ in range(self.times):
            for el in mesh.Elements(ng.VOL):
                mesh.SetRefinementFlag(el, True)
            mesh.Refine()
        return mesh.ngmesh


def hertz_scene(case, order: int, h: float, geometry):
    """The Hertz Scene (top clamped, the plane raised by delta, u.n along (0, -1)) on ``geometry``."""
    from admmkit.problems.contact.model.scene import Scene
    return Scene(h=h, mesh_kind="unstructured", order=order, E=case.E, nu=case.nu, dirichlet=("top",),
                 contact="contact", gap=case.gap(case.delta_guess()), geometry=geometry,
                 contact_normal=(0.0, -1.0), name=f"hertz(h={h:.3g})")


def start_scene(case, order: int):
    """The adaptive start: netgen's coarse mesh, maxh R/4, the contact arc in elements of size x_c."""
    from admmkit.problems.contact.validation.hertz import half_cylinder_geometry
    return hertz_scene(case, order, case.R / 4, half_cylinder_geometry(case.R, case.x_c, case.x_c))


def uniform_scenes(case, order: int, times) -> list[tuple]:
    """(h, scene) of the uniform meshes: the base mesh of maxh 1/16 refined k times, h = 2^-k / 16."""
    from admmkit.problems.contact.validation.hertz import half_cylinder_geometry
    out = []
    for k in times:
        base = half_cylinder_geometry(case.R, case.x_c, min(UNIFORM_BASE_H, case.x_c))
        out.append((UNIFORM_BASE_H / 2 ** k, hertz_scene(case, order, UNIFORM_BASE_H, UniformlyRefined(base, k))))
    return out


def a_priori_scenes(case, order: int, ks) -> list[tuple]:
    """(h_c, scene) of the Hertz validation's meshes, h_c = a_target / k near the contact."""
    return [(case.a_target / k, replace(case.scene(case.a_target / k), order=order)) for k in ks]


def _by_x(ops, *vectors):
    o = np.argsort(ops.xc[:, 0])
    view = SimpleNamespace(xc=ops.xc[o], mc=ops.mc[o], g=ops.g[o])
    return (view, *(v[o] for v in vectors))


def hertz_errors(case, ops, res) -> dict:
    """a_error and p0_error: a_h / a_Hertz - 1, p0_h / p0_Hertz - 1 at the measured load (NaN if unmeasurable).

    ``measure`` of the Hertz validation on the contact nodes in the order of x (a refined mesh appends its
    new nodes); NaN where the contact zone has fewer than two active nodes a side (the coarse levels).
    """
    from admmkit.problems.contact.validation.hertz import measure
    view, lam, z = _by_x(ops, res.lam, res.z)
    try:
        m = measure(view, lam, z, case)
    except (ValueError, IndexError):
        return {"a_error": math.nan, "p0_error": math.nan}
    return {"a_error": m["a_err"], "p0_error": m["p0_err"]}


def penetration_term(case, ops, res) -> float:
    """c_h = int p_h (u_h.n - g) ds over the contact elements whose nodes are all active: the overlap.

    Along the contact arc in the order of x, element by element (P1: two nodes, P2: vertex, midpoint,
    vertex), u_h.n and p_h interpolated from the nodal values in the element's degree, g the exact gap,
    six Gauss points, ds the chord's length. Only where every node of the element is on the obstacle
    (z = g), where u_h.n interpolates g and the overlap is the interpolation's, s^2 / (8 R) at most in P1
    (in P2 the quadratic interpolates the circle's quadratic part exactly); the elements at the contact's
    edge, half active, are left out (p_h there is the discrete edge's, not the pressure's).
    """
    order = ops.scene.order
    view, un, lam, z = _by_x(ops, ops.B @ res.x, res.lam, res.z)
    active = z >= view.g
    x, gap = view.xc[:, 0], case.gap(case.delta_guess())
    t, w = GAUSS
    total = 0.0
    for start in range(0, len(x) - order, order):
        nodes = slice(start, start + order + 1)
        if not active[nodes].all():
            continue
        xe, ue, pe = x[nodes], un[nodes], lam[nodes]
        xq = xe[0] + (t + 1) / 2 * (xe[-1] - xe[0])
        basis = [np.prod([(xq - xe[j]) / (xe[i] - xe[j]) for j in range(order + 1) if j != i], axis=0)
                 for i in range(order + 1)]
        u_q, p_q = sum(b * v for b, v in zip(basis, ue)), sum(b * v for b, v in zip(basis, pe))
        chord = float(np.hypot(*(view.xc[start + order] - view.xc[start])))
        total += chord / 2 * float(np.sum(w * p_q * (u_q - gap(xq, 0.0))))
    return total


def hertz_rows(order: int, target: float, ref: dict, cut: int | None = None) -> list[dict]:
    """Adaptive, uniform and a priori rows of Hertz in P``order`` (``cut``: only the coarsest meshes)."""
    from admmkit.benchmarks.adaptive.contact import contact_rows
    from admmkit.problems.contact.validation.hertz import HertzCase
    case = HertzCase()
    return contact_rows("hertz", order, target, ref, start_scene(case, order),
                        uniform_scenes(case, order, UNIFORM_TIMES[order][:cut]),
                        a_priori_scenes(case, order, A_PRIORI_K[order][:cut]),
                        correction=lambda ops, res: penetration_term(case, ops, res),
                        extra=lambda ops, res: hertz_errors(case, ops, res))


def hertz_reference(target: float) -> dict:
    """J_ref of Hertz: P2 adaptive from the adaptive start to ``target`` (gamma 0.01), c_h included."""
    from admmkit.benchmarks.adaptive.contact import reference
    from admmkit.problems.contact.validation.hertz import HertzCase
    case = HertzCase()
    return reference(target, "hertz", start_scene(case, 2), lambda ops, res: penetration_term(case, ops, res),
                     start="its coarse mesh (maxh R/4)")
