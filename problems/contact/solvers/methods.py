"""One call from a scene to a result, with the paper's methods by name.

The methods ADMM1, ADMM2 and SADMM are defined in :mod:`admmkit.policies.paper_methods`;
any other registered policy can be named too (order "zx" unless given).
"""
from __future__ import annotations

from dataclasses import dataclass

import admmkit
from admmkit import RelativeChange
from admmkit.policies.paper_methods import PAPER_METHODS as METHODS, method  # noqa: F401  (re-exported)

from admmkit.problems.contact.model.operators import ContactOperators
from admmkit.problems.contact.solvers.coulomb import CoulombReport, coulomb_fixed_point, warm_z0
from admmkit.problems.contact.model.memory import check_memory
from admmkit.problems.contact.solvers.problem import contact_problem
from admmkit.problems.contact.model.scene import Scene, is_scene3d


@dataclass
class ContactSolution:
    """A solved scene: the admmkit result, the operators, the mode and the setup time.

    With Coulomb friction ``coulomb`` reports the outer fixed point (None otherwise)
    and ``result`` is its last Tresca solve.
    """

    result: admmkit.Result
    ops: ContactOperators
    mode: str
    setup_time: float
    coulomb: CoulombReport | None = None
    stop: admmkit.StoppingRule | None = None     # the stopping rule of the run

    @property
    def u(self):
        """Displacement on the free dofs."""
        return self.result.x

    @property
    def pressure(self):
        """Contact pressure lam_n = -sigma_n at the contact nodes."""
        return self.result.lam[: self.ops.n_c]

    @property
    def tangential_traction(self):
        """(d-1, n_c): q = lam_t = -sigma_t along the tangents, the friction force per unit length the body
        exerts on the foundation (None without friction)."""
        if self.ops.friction is None:
            return None
        return self.result.lam[self.ops.n_c:].reshape(-1, self.ops.n_c)

    @property
    def slip(self):
        """(d-1, n_c): tangential displacement relative to the foundation, T u - w (None without friction)."""
        if self.ops.friction is None:
            return None
        w = self.ops.friction.slide
        return (self.ops.T @ self.u).reshape(-1, self.ops.n_c) - (0.0 if w is None else w.T)

    @property
    def zones(self):
        """(n_c,) 0 separated, 1 stick, 2 slip (from the last z-step; None without friction)."""
        from admmkit.problems.contact.solvers.friction import stick_slip
        if self.ops.friction is None:
            return None
        return stick_slip(self.result.z, self.ops.g, self.ops.friction.slide)

    @property
    def converged(self) -> bool:
        """The ADMM run converged (and, for Coulomb, the outer fixed point too)."""
        return bool(self.result.converged and (self.coulomb is None or self.coulomb.converged))

    def __repr__(self) -> str:
        r, ops = self.result, self.ops
        name = getattr(ops.scene, "name", "") or "scene"
        return (f"ContactSolution({name}, h={ops.scene.h:.4g}, n_free={ops.n_free}, n_c={ops.n_c}, mode={self.mode!r}, "
                f"status={r.status.value!r}, iterations={r.iterations}, active_nodes={self.active_nodes})")

    @property
    def active_nodes(self) -> int:
        """Number of active contact nodes (p = g; ``contact_status`` in problems/contact/output/export.py)."""
        from admmkit.problems.contact.output.export import contact_status
        return int(contact_status(self.ops, self.result.z).sum())

    def _repr_html_(self) -> str:
        """Jupyter: the scene and sizes, then the result's table."""
        import html
        ops = self.ops
        head = html.escape(f"{getattr(ops.scene, 'name', '') or 'scene'}: h = {ops.scene.h:.4g}, "
                           f"{ops.n_free} free dofs, {ops.n_c} contact nodes ({self.active_nodes} active), "
                           f"mode {self.mode}, setup {self.setup_time:.3g} s")
        return f"<div><b>ContactSolution</b> {head}{self.result._repr_html_()}</div>"


def solve_scene(scene, method_name: str = "sadmm", rho: float = 1e3, *,
                mode: str = "auto", stop: admmkit.StoppingRule | None = None, max_iter: int = 20_000,
                order: str | None = None, callback=None, coulomb_tol: float = 1e-4,
                coulomb_max_outer: int = 30, balance: float | None = None) -> ContactSolution:
    """Assemble (unless operators are given) and solve a scene with a named method.

    ``scene`` is a 2D :class:`Scene`, a 3D ``Scene3D`` (problems/contact/model/scene3d.py)
    or assembled :class:`ContactOperators`.
    The default stop is the paper's RelativeChange(1e-5) in the energy norm.
    A direct ``mode`` whose memory estimate exceeds the available memory is
    refused with the estimate before anything is assembled.  The scene's
    ``tangential`` picks the model: frictionless, stick, Tresca (one ADMM run)
    or Coulomb (the fixed point of problems/contact/solvers/coulomb.py, each step a
    warm-started ADMM run with a fresh rule, until the relative change of the
    slip bound is at most ``coulomb_tol`` or ``coulomb_max_outer`` steps).
    """
    import time

    default_order, policy = method(method_name)
    if isinstance(scene, Scene) and mode in ("full", "condensed", "iterative"):
        check_memory(scene, mode)
    if isinstance(scene, ContactOperators):
        ops = scene
    elif is_scene3d(scene):
        from admmkit.problems.contact.model.assembly3d import assemble3d
        ops = assemble3d(scene)
    else:
        from admmkit.problems.contact.model.assembly import assemble     # NGSolve: imported when it assembles
        ops = assemble(scene)
    t0 = time.perf_counter()
    problem = contact_problem(ops, mode=mode)
    setup = time.perf_counter() - t0
    if balance is not None:
        from admmkit.problems.contact.solvers.estimate import BalancedStop
        if stop is not None:
            raise ValueError("balance and stop are two stops: give one")
        stop = BalancedStop(problem, balance)
    stop = stop or RelativeChange(1e-5)
    if ops.friction is None or ops.friction.law == "tresca":
        result = admmkit.solve(problem, rho=rho, policy=policy, order=order or default_order,
                               stop=stop, max_iter=max_iter, callback=callback)
        return ContactSolution(result=result, ops=ops, mode=problem.mode, setup_time=setup, stop=stop)

    def run(warm):   # one Tresca solve, a fresh rule each time, warm-started from the last one
        order_, rule = method(method_name, order)
        z0 = None if warm is None else warm_z0(problem, warm)           # a z-step with the new slip bound
        return admmkit.solve(problem, rho=None if warm is not None else rho, policy=rule, order=order_ or default_order,
                             stop=stop, max_iter=max_iter, callback=callback, warm_start=warm, z0=z0)

    result, report = coulomb_fixed_point(problem, run, ops.friction.mu, tol=coulomb_tol, max_outer=coulomb_max_outer)
    return ContactSolution(result=result, ops=ops, mode=problem.mode, setup_time=setup, coulomb=report, stop=stop)
