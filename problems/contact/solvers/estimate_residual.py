"""A residual-type a posteriori error estimator for frictionless contact (Hild & Nicaise), beside the ZZ estimate.

Hild & Nicaise (2007, "Residual a posteriori error estimators for contact
problems in elasticity", ESAIM: M2AN 41) estimate the error of a Signorini
problem's finite element solution u_h with its discrete contact pressure
lambda_h by the residuals of the equilibrium equations and the contact
conditions.  With k = 2 mu (so that every term is in the units of the energy
norm ``||v||_a^2 = int sigma(v):eps(v)``), for every element T::

    eta_T^2 =  h_T^2 / k ||div sigma(u_h) + f||_T^2                         (element residual; 0 for P1)
             + 1/2 sum_{E in T, E interior} h_E / k ||[sigma(u_h) n]||_E^2     (normal-stress jumps)
             + sum_{E in T, E on Gamma_N} h_E / k ||sigma(u_h) n - t||_E^2    (Neumann residual; t = 0 where no
                                                                              traction is given; on a 3D
                                                                              symmetry face its tangential part)
             + sum_{E in T, E on Gamma_C} [ h_E / k ||sigma_n(u_h) + lambda_h||_E^2       (normal stress against
                                                                                           the discrete pressure)
                                            + h_E / k ||sigma_t(u_h)||_E^2               (tangential stress: 0
                                                                                          without friction)
                                            + int_E lambda_h^+ (g - u_hn)^+              (complementarity)
                                            + h_E / k ||lambda_h^-||_E^2                 (negative pressure)
                                            + k / h_E ||(u_hn - g)^+||_E^2 ]             (penetration)

and eta = (sum_T eta_T^2)^{1/2} estimates ``||u - u_h||_a``.  lambda_h is the
pressure at the contact nodes (lam = -sigma_n >= 0, the plug-in's
multiplier) interpolated on Gamma_C in the scene's order; g is the scene's
gap (an expression or a number, evaluated between the nodes where the
scene gives it as an NGSolve-readable function), u_hn = u_h . n.

Which terms, and why.  The first three are the residual estimator of
linear elasticity (Verfuerth); the contact terms are those of Hild &
Nicaise's Theorem 3.1 for a frictionless contact: the mismatch between the
normal stress and the pressure (which the nodal, lumped contact condition
leaves on every contact edge), the tangential stress, and the
complementarity and sign defects of lambda_h and of the gap between the
nodes.  The nodal contact condition makes u_hn <= g and lambda_h >= 0 hold at
the nodes, so the last three vanish for P1 with a constant gap, and measure
the interpolation of a curved gap (Example 2) and of P2 between nodes.
Not included: the oscillation of the data (f, t, g) (higher order for smooth
data).  The constants are not computed: eta is an estimate whose effectivity
is measured by ``tests/problems/test_contact_estimate_residual.py`` and
``admmkit bench estimators``.

All integrals are NGSolve's: one linear form on the element-wise constants
(``L2(order=0)``), ``dx(skeleton=True)`` with ``Other()`` for the jumps and
``ds(skeleton=True)`` for the boundary terms, in 2D and 3D, P1 and P2.
"""
from __future__ import annotations

import ngsolve as ng
import numpy as np
import scipy.sparse.linalg as spla

from admmkit.problems.contact.model.assembly import _point_evaluation, _vector_cf, lame
from admmkit.problems.contact.model.assembly3d import point_evaluation
from admmkit.problems.fe import facet_sizes


class ResidualEstimator:
    """The residual estimator of one assembled contact scene (module docstring); the mesh data built once."""

    def __init__(self, ops):
        if ops.friction is not None:
            raise ValueError("the residual estimator is for frictionless contact (a friction law was given)")
        self.ops = ops
        mesh, scene = ops.mesh, ops.scene
        self.dim, self.order = mesh.dim, scene.order
        self.mu, self.lam = lame(scene.E, scene.nu)
        self.cells = ng.L2(mesh, order=0)
        pts = np.array(mesh.ngmesh.Coordinates())
        vol = np.array([[v.nr for v in el.vertices] for el in mesh.Elements(ng.VOL)], dtype=np.int64)
        corners = pts[vol]
        k = vol.shape[1]
        diam = np.max([np.linalg.norm(corners[:, i] - corners[:, j], axis=1)
                       for i in range(k) for j in range(i + 1, k)], axis=0)
        self.h_T = ng.GridFunction(self.cells)
        self.h_T.vec.FV().NumPy()[:] = diam
        self.h_E = facet_sizes(mesh)
        self.scalar = ng.H1(mesh, order=self.order)
        self._nodes = _boundary_interpolation(mesh, self.scalar, ops.xc, pts, self.order)
        self.pressure = ng.GridFunction(self.scalar)
        self.gap = _gap_cf(scene, self.scalar, self._nodes, ops.g)
        self.symmetry = tuple(getattr(scene, "symmetry", ()))
        labels = set(mesh.GetBoundaries()) - set(scene.dirichlet) - set(self.symmetry) - {scene.contact}
        self.neumann = {label: _traction_cf(scene.tractions.get(label), self.dim) for label in sorted(labels)}
        force = getattr(scene, "body_force", None)
        self.f = ng.CF((0.0,) * self.dim) if force is None else _vector_cf(force)

    def stress(self, u: ng.GridFunction):
        """sigma(u) = 2 mu eps(u) + lambda div(u) I as an NGSolve coefficient function."""
        eps = ng.Sym(ng.Grad(u))
        return 2 * self.mu * eps + self.lam * ng.Trace(eps) * ng.Id(self.dim)

    def divergence(self, u: ng.GridFunction):
        """div sigma(u) = mu Laplace u + (mu + lambda) grad div u, from the Hessians (0 for P1)."""
        d = self.dim
        if self.order == 1:
            return ng.CF((0.0,) * d)
        H = u.Operator("hesse")                                     # H[i, j d + l] = d_j d_l u_i
        return ng.CF(tuple(self.mu * sum(H[i, j * d + j] for j in range(d))
                           + (self.mu + self.lam) * sum(H[j, i * d + j] for j in range(d)) for i in range(d)))

    def terms(self, u: np.ndarray, lam: np.ndarray) -> dict[str, np.ndarray]:
        """The squared contributions per element (u: the displacement on the free dofs, lam: the pressure at the
        contact nodes): ``residual``, ``jump``, ``neumann``, ``normal_stress``, ``tangential``,
        ``complementarity``, ``sign``, ``penetration`` (module docstring)."""
        ops, k = self.ops, 2 * self.mu
        mesh = ops.mesh
        uh = ops.to_gridfunction(u)
        self.pressure.vec.FV().NumPy()[:] = self._nodes(lam)
        q = self.cells.TestFunction()
        n = ng.specialcf.normal(self.dim)
        sigma = self.stress(uh)
        sn = sigma * n
        hE = self.h_E
        contact = dict(skeleton=True, definedon=mesh.Boundaries(ops.scene.contact), bonus_intorder=2)
        normal_stress, un = ng.InnerProduct(sn, n), ng.InnerProduct(uh, n)
        p, slack = self.pressure, self.gap - un
        forms = {
            "residual": self.h_T ** 2 / k * ng.InnerProduct(self.divergence(uh) + self.f, self.divergence(uh) + self.f)
            * q * ng.dx(bonus_intorder=2),
            "jump": 0.5 * hE / k * ng.InnerProduct((sigma - sigma.Other()) * n, (sigma - sigma.Other()) * n)
            * (q + q.Other()) * ng.dx(skeleton=True),
            "normal_stress": hE / k * (normal_stress + p) ** 2 * q * ng.ds(**contact),
            "tangential": hE / k * ng.InnerProduct(sn - normal_stress * n, sn - normal_stress * n) * q * ng.ds(**contact),
            "complementarity": ng.IfPos(p, p, 0) * ng.IfPos(slack, slack, 0) * q * ng.ds(**contact),
            "sign": hE / k * ng.IfPos(p, 0, p) ** 2 * q * ng.ds(**contact),
            "penetration": k / hE * ng.IfPos(slack, 0, slack) ** 2 * q * ng.ds(**contact),
        }
        neumann = [hE / k * ng.InnerProduct(sn - t, sn - t) * q
                   * ng.ds(skeleton=True, definedon=mesh.Boundaries(label), bonus_intorder=2)
                   for label, t in self.neumann.items()]
        neumann += [hE / k * ng.InnerProduct(sn - normal_stress * n, sn - normal_stress * n) * q   # symmetry: s.t = 0
                    * ng.ds(skeleton=True, definedon=mesh.Boundaries(label), bonus_intorder=2)
                    for label in self.symmetry]
        out = {name: _assemble(self.cells, [form]) for name, form in forms.items()}
        out["neumann"] = _assemble(self.cells, neumann)
        return out

    def indicators(self, u: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """eta_T for every element."""
        return np.sqrt(sum(self.terms(u, lam).values()))


def _assemble(space, forms) -> np.ndarray:
    """sum of the forms tested with the element indicators: one value per element, clipped at 0 (round-off)."""
    if not forms:
        return np.zeros(space.ndof)
    lf = ng.LinearForm(space)
    for form in forms:
        lf += form
    lf.Assemble()
    return np.maximum(lf.vec.FV().NumPy().copy(), 0.0)


def _boundary_interpolation(mesh, scalar, xc: np.ndarray, points: np.ndarray, order: int):
    """values at the contact nodes -> the coefficients of the function of ``scalar`` with these values on Gamma_C
    (0 at the clamped ends and off Gamma_C).  P1: the contact nodes are vertices; P2 (2D and 3D): the vertex and
    edge coefficients of the hierarchical basis from the values at the vertices and midpoints."""
    if order == 1:
        from scipy.spatial import cKDTree
        _, vertex = cKDTree(points[:, :xc.shape[1]]).query(xc)

        def nodal(values):
            out = np.zeros(scalar.ndof)
            out[vertex] = values
            return out
        return nodal
    E = (_point_evaluation if xc.shape[1] == 2 else point_evaluation)(mesh, scalar, xc).tocsr()
    single = np.diff(E.indptr) == 1                          # a vertex's row: its own hat function, value 1
    vertices = E.indices[E.indptr[:-1][single]]
    edges = np.unique(E.indices[E.indices >= mesh.nv])       # the bubbles of the contact edges
    keep = np.concatenate([vertices, edges])                 # not the clamped ends, which midpoints also see
    solve = spla.splu(E[:, keep].tocsc())

    def hierarchical(values):
        out = np.zeros(scalar.ndof)
        out[keep] = solve.solve(np.asarray(values, dtype=float))
        return out
    return hierarchical


def _gap_cf(scene, scalar, nodes, g_nodes):
    """The gap g as a coefficient function: the scene's function of (x, y) where NGSolve can evaluate it, a
    constant for a number, else interpolated from the contact nodes."""
    gap = scene.gap
    if not callable(gap):
        return ng.CF(float(gap))
    try:
        cf = gap(ng.x, ng.y)
        if isinstance(cf, ng.CoefficientFunction):
            return cf
    except Exception:   # a callable for numbers only: the nodal values below
        pass
    gf = ng.GridFunction(scalar)
    gf.vec.FV().NumPy()[:] = nodes(g_nodes)
    return gf


def _traction_cf(t, dim: int):
    """The traction of a Neumann boundary as a coefficient function (0 where none is given)."""
    if t is None:
        return ng.CF((0.0,) * dim)
    return _vector_cf(t) if dim == 2 else ng.CF(tuple(float(v) for v in t))


#: the estimators by name (``--estimator``, ``estimator=``)
ESTIMATORS = ("zz", "residual")


def check_estimator(name) -> str:
    """The estimator's name, or ValueError naming the accepted ones."""
    if name not in ESTIMATORS:
        raise ValueError(f"estimator = {name!r} is unknown; accepted: {', '.join(ESTIMATORS)}")
    return name


def residual_estimator(ops) -> ResidualEstimator:
    """The operators' residual estimator (built on first use, then kept on them)."""
    if getattr(ops, "_residual", None) is None:
        ops._residual = ResidualEstimator(ops)
    return ops._residual


def residual_indicators(ops, u: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """eta_T of the residual estimator for every element (u on the free dofs, lam the pressure at the contact nodes)."""
    return residual_estimator(ops).indicators(u, lam)


def residual_estimate(ops, u: np.ndarray, lam: np.ndarray) -> float:
    """eta = (sum_T eta_T^2)^{1/2}: the residual estimate of the discretisation error ``||u_h - u||_a``."""
    return float(np.sqrt(np.sum(residual_indicators(ops, u, lam) ** 2)))


def condensed_pressure(problem, x: np.ndarray) -> np.ndarray:
    """The pressure of a condensed iterate x = (s, w): lam = -w / m_c, the one that balances u = s u0 + K^{-1} B'w
    exactly (K u - f + B'M_c lam = 0), whatever the ADMM multiplier."""
    return -np.asarray(x[1:]) / problem.w


__all__ = ["ESTIMATORS", "check_estimator", "ResidualEstimator", "residual_estimator", "residual_indicators", "residual_estimate",
           "condensed_pressure"]
