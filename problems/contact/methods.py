"""One call from a scene to a result, with the paper's methods by name.

The methods ADMM1, ADMM2 and SADMM are defined in :mod:`policies.paper_methods`;
any other registered policy can be named too (order "zx" unless given).
"""
from __future__ import annotations

from dataclasses import dataclass

import admmkit
from admmkit import RelativeChange
from policies.paper_methods import PAPER_METHODS as METHODS, method  # noqa: F401  (re-exported)

from .assembly import ContactOperators, assemble
from .problem import contact_problem
from .memory import check_memory
from .scene import Scene

@dataclass
class ContactSolution:
    """A solved scene: the admmkit result, the operators, the mode and the setup time."""

    result: admmkit.Result
    ops: ContactOperators
    mode: str
    setup_time: float

    @property
    def u(self):
        """Displacement on the free dofs."""
        return self.result.x

    @property
    def pressure(self):
        """Contact pressure lam at the contact nodes."""
        return self.result.lam

    def __repr__(self) -> str:
        r, ops = self.result, self.ops
        name = getattr(ops.scene, "name", "") or "scene"
        return (f"ContactSolution({name}, h={ops.scene.h:.4g}, n_free={ops.n_free}, n_c={ops.n_c}, mode={self.mode!r}, "
                f"status={r.status.value!r}, iterations={r.iterations}, active_nodes={self.active_nodes})")

    @property
    def active_nodes(self) -> int:
        """Number of active contact nodes (p = g; ``contact_status`` in problems/contact/export.py)."""
        from .export import contact_status
        return int(contact_status(self.ops, self.result.z).sum())

    def _repr_html_(self) -> str:
        """Jupyter: the scene and sizes, then the result's table."""
        import html
        ops = self.ops
        head = html.escape(f"{getattr(ops.scene, 'name', '') or 'scene'}: h = {ops.scene.h:.4g}, "
                           f"{ops.n_free} free dofs, {ops.n_c} contact nodes ({self.active_nodes} active), "
                           f"mode {self.mode}, setup {self.setup_time:.3g} s")
        return f"<div><b>ContactSolution</b> {head}{self.result._repr_html_()}</div>"


def solve_scene(scene: Scene | ContactOperators, method_name: str = "sadmm", rho: float = 1e3, *,
                mode: str = "auto", stop: admmkit.StoppingRule | None = None, max_iter: int = 20_000,
                order: str | None = None, callback=None) -> ContactSolution:
    """Assemble (unless operators are given) and solve a scene with a named method.

    The default stop is the paper's RelativeChange(1e-5) in the energy norm.
    A direct ``mode`` whose memory estimate exceeds the available memory is
    refused with the estimate before anything is assembled.
    """
    import time

    default_order, policy = method(method_name)
    if isinstance(scene, Scene) and mode in ("full", "condensed", "iterative"):
        check_memory(scene, mode)
    ops = scene if isinstance(scene, ContactOperators) else assemble(scene)
    t0 = time.perf_counter()
    problem = contact_problem(ops, mode=mode)
    setup = time.perf_counter() - t0
    result = admmkit.solve(problem, rho=rho, policy=policy, order=order or default_order,
                           stop=stop or RelativeChange(1e-5), max_iter=max_iter, callback=callback)
    return ContactSolution(result=result, ops=ops, mode=problem.mode, setup_time=setup)
