"""The obstacle plug-in: P1 finite elements, split with z = u on the free nodes.

Discrete problem on the free (interior) nodes, the Dirichlet values lifted:

    min 1/2 u'Ku - F'u   subject to   u >= psi   (side "lower"; u <= psi for "upper")

with K the P1 stiffness on the free nodes and F = M_c f - K_fD u_D (f
interpolated, M_c the consistent mass).  Splitting: f(u) = 1/2 u'Ku - F'u,
g(z) = indicator of {z >= psi}, constraint u - z = 0 in the lumped mass inner
product (a, b)_M = sum_i m_i a_i b_i.  The augmented Lagrangian's steps are

    x-step:  (K + rho M) u = F + M (rho z - lam)        (one factorisation per rho,
                                                         AMG-CG with backend="iterative", or
                                                         Jacobi-CG with backend="jacobi": xstep.py)
    z-step:  z = max(psi, u + lam/rho)                 (min for an upper obstacle)

Sign convention.  admmkit's Lagrangian is f(u) + g(z) + (lam, u - z)_M, so at
a solution K u - F + M lam = 0.  For u >= psi the lower-bound multiplier
mu >= 0 satisfies K u - F = M mu (the contact pressure density), hence
lam = -mu <= 0, supported on the contact set.  For u <= psi, lam >= 0.
"""
from __future__ import annotations

import math

import ngsolve as ng
import numpy as np
import scipy.sparse as sp
from ngsolve.meshes import MakeStructured2DMesh

from admmkit import Problem
from admmkit.blocks.prox import Box, UpperBound
from admmkit.problems.fe import ADAPTIVE_TASKS_MIN_ELEMENTS, areas, ngsolve_tasks, p1_mass, triangles
from admmkit.blocks.xstep import QuadraticXStep

from .xstep import JacobiCG
from .scene import A_STAR, Scene, check_boundary

BOUNDARY = "bottom|right|top|left"
#: sparse solver of K + rho M.  Not "auto": on this 2-D scalar Laplacian the auto
#: choice, CHOLMOD (supernodal, default ordering), took 2.5 s to factorise 65025
#: unknowns (h = 1/64 on the radial scene) against 0.2 s for SuperLU and 0.13 s for
#: qdldl, with similar solve times (measured on the project machine, 2 cores).
DEFAULT_BACKEND = "superlu"


def csr_of(mat) -> sp.csr_matrix:
    """An assembled NGSolve matrix as scipy CSR."""
    vals, cols, rows = mat.CSR()
    return sp.csr_matrix((np.array(vals), np.array(cols), np.array(rows)), shape=(mat.height, mat.width))


def x_step_of(backend: str, K, F: np.ndarray, m: np.ndarray):
    """The x-step of f(u) = 1/2 u'Ku - F'u with A = I in the lumped mass: (K + rho M) u = F + M (rho z - lam),
    by a factorisation per rho (a sparse ``backend``), AMG-preconditioned CG (``"iterative"``; near-null
    space: the constants) or Jacobi-CG (``"jacobi"``, xstep.py)."""
    if backend == "iterative":
        return QuadraticXStep(K, -F, M=m, solver="amg", near_null=np.ones((K.shape[0], 1)))
    if backend == "jacobi":
        return JacobiCG(K, F, m)
    return QuadraticXStep(K, -F, M=m, solver="direct", backend=backend)


def build_mesh(scene: Scene) -> ng.Mesh:
    """Structured triangular mesh of the scene's rectangle (nx x ny squares cut in two)."""
    x0, x1, y0, y1 = scene.box
    nx, ny = scene.counts
    return MakeStructured2DMesh(quads=False, nx=nx, ny=ny,
                                mapping=lambda s, t: (x0 + (x1 - x0) * s, y0 + (y1 - y0) * t))


class ObstacleProblem(Problem):
    """The discrete obstacle problem of a :class:`Scene` as an admmkit plug-in.

    Attributes: ``K`` (stiffness on free nodes), ``F`` (load with the lifted
    Dirichlet data), ``m`` (lumped mass on the free nodes), ``psi`` (obstacle
    at the free nodes), ``nodes`` (all node coordinates), ``tri`` and ``area``
    (the vertices and area of every triangle), ``free`` (indices of
    the free nodes), ``u_D`` (nodal values of all nodes, the boundary data on
    the boundary), ``mesh``, ``fes``, ``scene``, ``n`` and ``c = 0``.
    """

    #: polynomial order of the elements (P2: admmkit.problems.obstacle.p2)
    order = 1
    #: the consistent mass is at least this times the lumped one, element by element (the EnergyGap bound)
    mass_ratio = 0.25

    def __init__(self, scene: Scene, *, backend: str = DEFAULT_BACKEND, mesh: ng.Mesh | None = None):
        if not isinstance(scene, Scene):
            raise ValueError(f"scene must be a admmkit.problems.obstacle.Scene, got {type(scene).__name__}")
        self.scene = scene
        self.sign = 1.0 if scene.side == "lower" else -1.0   # u >= psi  <=>  sign*(u - psi) >= 0
        self.mesh = mesh = build_mesh(scene) if mesh is None else mesh     # given: an adapted mesh of the box
        self.fes = fes = ng.H1(mesh, order=self.order, dirichlet=BOUNDARY)
        self.nodes = self._node_points()
        x, y = self.nodes.T
        is_free = np.array(fes.FreeDofs(), dtype=bool)
        self.free, bnd = np.flatnonzero(is_free), np.flatnonzero(~is_free)     # not setdiff1d: a sort, 0.1 s at 2e5
        check_boundary(scene, x[bnd], y[bnd])

        self.tri = triangles(mesh)                                   # (cells, 3) vertex numbers
        self.area = areas(self.nodes[:mesh.nv], self.tri)
        Kfull, mass, lumped = self._forms()
        self.u_D = np.zeros(fes.ndof)
        self.u_D[bnd] = scene.evaluate("u_D", x[bnd], y[bnd])
        Ffull = mass(scene.evaluate("f", x, y))
        self.K = Kfull[self.free][:, self.free].tocsc()
        self.F = Ffull[self.free] - Kfull[self.free] @ self.u_D
        self.m = lumped[self.free]                                   # lumped mass, > 0
        self.psi = scene.evaluate("psi", x, y)[self.free]
        # energy of the full field = 1/2 u'Ku - F'u + this constant
        self._energy0 = float(0.5 * self.u_D @ (Kfull @ self.u_D) - Ffull @ self.u_D)
        self.n = self.free.size
        self.c = 0.0
        self._xstep = x_step_of(backend, self.K, self.F, self.m)
        self._g = Box(lower=self.psi) if self.sign > 0 else UpperBound(self.psi)   # g = indicator of the obstacle

    def _node_points(self) -> np.ndarray:
        """The point of every dof: P1's dof i is vertex i."""
        assert self.fes.ndof == self.mesh.nv
        return np.array(self.mesh.ngmesh.Coordinates())[:, :2]

    def _forms(self):
        """(K on all dofs, f -> M f, the lumped mass on all dofs).  The mass is only applied (to f) and lumped:
        element by element, not assembled (0.33 s at 4.7e5 cells)."""
        u, v = self.fes.TnT()
        with ngsolve_tasks(self.mesh.ne, ADAPTIVE_TASKS_MIN_ELEMENTS):
            K = csr_of(ng.BilinearForm(ng.grad(u) * ng.grad(v) * ng.dx).Assemble().mat)
        lumped, mass = p1_mass(self.nodes, self.tri, self.area)
        return K, mass, lumped

    # -- the splitting --------------------------------------------------------
    def x_step(self, z, lam, rho, x):
        """Solve (K + rho M) u = F + M (rho z - lam) (admmkit.blocks.xstep.QuadraticXStep)."""
        return self._xstep(z, lam, rho, x)

    def update_rho(self, rho):
        """A change of rho: the x-step's refresh (a factorisation or an AMG decision; Jacobi-CG decides at
        each solve, from the CG iterations spent at that rho)."""
        self._xstep.update_rho(rho)

    def z_step(self, Ax, lam, rho, z):
        """Project u + lam/rho pointwise onto {z >= psi} (or {z <= psi}): the prox of the obstacle's indicator."""
        return self._g.prox(Ax + lam / rho, 1.0 / rho, self.m)

    def apply_A(self, x):
        """A = I."""
        return np.array(x, dtype=float)

    def inner(self, a, b):
        """The lumped mass inner product sum_i m_i a_i b_i."""
        return float(np.sum(self.m * a * b))

    def x_norm(self, x):
        """The lumped L2 norm of u on the free nodes."""
        return self.norm(x)

    def adjoint_norm(self, y):
        """||A' M y||_2 = ||M y||_2."""
        return float(np.linalg.norm(self.m * y))

    # -- diagnostics ----------------------------------------------------------
    def objective(self, x, z):
        """Dirichlet energy 1/2 a(u, u) - (f, u) of the full field (boundary data included)."""
        return float(0.5 * x @ (self.K @ x) - self.F @ x + self._energy0)

    def kkt(self, x, z, lam):
        """KKT residuals (inf-norms) of the discrete problem at (u, lam).

        primal: ||u - z||; infeasibility: max (psi - u)^+ (lower obstacle);
        dual: ||K u - F + M lam|| (stationarity, a nodal force); dual_density:
        the same divided by m_i; sign: max (lam)^+ for u >= psi (lam <= 0 is
        the contact pressure), max (-lam)^+ for u <= psi; complementarity:
        max ``|lam_i| |u_i - psi_i|``.
        """
        slack = self.sign * (x - self.psi)
        residual = self.K @ x - self.F + self.m * lam
        return {
            "primal": _inf(x - z),
            "infeasibility": _inf(np.maximum(-slack, 0.0)),
            "dual": _inf(residual),
            "dual_density": _inf(residual / self.m),
            "sign": _inf(np.maximum(self.sign * lam, 0.0)),
            "complementarity": _inf(lam * slack),
        }

    def kkt_relative(self, x, z, lam):
        """The KKT residuals relative to the problem's scales, which the framework compares with the
        stopping rule's tolerance (a run whose worst measure is above 10x that says ``converged_inaccurate``).

        infeasibility / max(||psi||, ||u||), stationarity ||K u - F + M lam|| / max(||F||, ||K u||, ||M lam||),
        sign and complementarity / ||lam|| (complementarity also / max(||psi||, ||u||)); inf-norms.
        """
        slack = self.sign * (x - self.psi)
        Ku, Mlam = self.K @ x, self.m * lam
        u_scale = max(_inf(self.psi), _inf(x), 1e-300)
        lam_scale = max(_inf(lam), 1e-300)
        return {
            "infeasibility": _inf(np.maximum(-slack, 0.0)) / u_scale,
            "stationarity": _inf(Ku - self.F + Mlam) / max(_inf(self.F), _inf(Ku), _inf(Mlam), 1e-300),
            "sign": _inf(np.maximum(self.sign * lam, 0.0)) / lam_scale,
            "complementarity": _inf(lam * slack) / (lam_scale * u_scale),
        }

    def begin_run(self):
        """Count the x-step's work from the start of a run (called by admmkit.solve)."""
        self._xstep.begin_run()

    def counters(self):
        """Factorisations (or AMG setups and CG iterations) and solves of K + rho M in this run."""
        return self._xstep.counters()

    def rho_scale(self) -> float:
        """The mean over the free nodes of K_ii / m_i: the size of M^{-1}K at the mesh's own scale (about h^-2),
        the unit in which a warm level's rho is kept (``adaptive.WARM_RHO``)."""
        return float(np.mean(self.K.diagonal() / self.m))

    # -- finite element helpers -------------------------------------------------
    @property
    def h(self) -> float:
        """Cell size of the scene."""
        return self.scene.h

    def full_vector(self, u: np.ndarray) -> np.ndarray:
        """Nodal values on all nodes: u on the free nodes, u_D on the boundary."""
        full = self.u_D.copy()
        full[self.free] = u
        return full

    def full_multiplier(self, lam: np.ndarray) -> np.ndarray:
        """The multiplier on all nodes: lam on the free nodes, 0 on the boundary (where u = u_D is fixed)."""
        full = np.zeros(self.fes.ndof)
        full[self.free] = lam
        return full

    def gridfunction(self, u: np.ndarray) -> ng.GridFunction:
        """The P1 function with free nodal values u and boundary values u_D."""
        gf = ng.GridFunction(self.fes)
        gf.vec.FV().NumPy()[:] = self.full_vector(u)
        return gf

    def contact_set(self, u: np.ndarray, tol: float = 1e-7) -> np.ndarray:
        """Boolean mask of the free nodes with ``|u - psi| <= tol`` (the contact set)."""
        return self.sign * (u - self.psi) <= tol

    def contact_area(self, u: np.ndarray, tol: float = 1e-7) -> float:
        """Area of the contact set: the sum of the lumped masses of its nodes."""
        return float(self.m[self.contact_set(u, tol)].sum())

    def contact_radius(self, u: np.ndarray, tol: float = 1e-7, method: str = "area") -> float:
        """Radius of the contact set around the centre of the box (radial scene).

        ``method="area"``: sqrt(area / pi), the disk of the same (lumped) area;
        ``"max"``: the largest distance of a contact node from the centre.
        """
        if method == "area":
            return math.sqrt(self.contact_area(u, tol) / math.pi)
        if method != "max":
            raise ValueError(f"method = {method!r}; accepted: 'area', 'max'")
        x0, x1, y0, y1 = self.scene.box
        pts = self.nodes[self.free][self.contact_set(u, tol)]
        return float(np.max(np.hypot(pts[:, 0] - (x0 + x1) / 2, pts[:, 1] - (y0 + y1) / 2), initial=0.0))

    def errors(self, u: np.ndarray, intorder: int = 6) -> dict[str, float]:
        """L2 error, H1 seminorm error and H1 error of u against the scene's exact solution.

        Integrated by NGSolve over the mesh with ``bonus_intorder`` = intorder, against
        :meth:`Scene.exact_coefficients` (the radial scene's written-out u and grad u, or the scene's own
        exact solution differentiated by NGSolve).  ValueError for a scene without an exact solution.
        """
        u_ex, grad_ex = self.scene.exact_coefficients()
        gf = self.gridfunction(u)
        l2 = ng.Integrate((gf - u_ex) ** 2 * ng.dx(bonus_intorder=intorder), self.mesh)
        semi = ng.Integrate(ng.InnerProduct(ng.grad(gf) - grad_ex, ng.grad(gf) - grad_ex)
                            * ng.dx(bonus_intorder=intorder), self.mesh)
        return {"L2": math.sqrt(max(l2, 0.0)), "H1_semi": math.sqrt(max(semi, 0.0)),
                "H1": math.sqrt(max(l2 + semi, 0.0))}


def _inf(v) -> float:
    return float(np.max(np.abs(v), initial=0.0))


def solve_with_cvxpy(problem: ObstacleProblem, solver: str = "CLARABEL", **options) -> tuple[np.ndarray, np.ndarray]:
    """Reference solve of the same discrete QP with cvxpy; returns (u, lam) in admmkit's convention."""
    import cvxpy as cp  # reference dependency, imported on use

    u = cp.Variable(problem.n)
    bound = problem.sign * (u - problem.psi) >= 0
    objective = 0.5 * cp.quad_form(u, cp.psd_wrap(problem.K)) - problem.F @ u
    prob = cp.Problem(cp.Minimize(objective), [bound])
    prob.solve(solver=solver, **options)
    if prob.status not in ("optimal", "optimal_inaccurate"):
        raise RuntimeError(f"cvxpy/{solver} did not solve the obstacle problem: status {prob.status}")
    mu = np.asarray(bound.dual_value)         # K u - F = sign * mu, mu >= 0
    return np.asarray(u.value), -problem.sign * mu / problem.m


__all__ = ["ObstacleProblem", "build_mesh", "csr_of", "x_step_of", "solve_with_cvxpy", "A_STAR"]
