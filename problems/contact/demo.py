"""The main job (``admmkit demo``): the paper's two examples solved with SADMM."""
from __future__ import annotations

from pathlib import Path

from admmkit.problems.contact.solvers.methods import solve_scene
from admmkit.problems.contact.output.plot import figure_solution
from admmkit.problems.contact.model.scene import example1, example2


def run_demo(out: str | Path = "out/demo", h: float = 1 / 40, rho: float = 1e3) -> int:
    """Solve Examples 1 and 2 at mesh size h with SADMM, print the summaries, write figures to ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    for name, scene, magnify in (("Example 1", example1(h=h), 10), ("Example 2", example2(h=h), 20)):
        sol = solve_scene(scene, "sadmm", rho=rho)
        ops = sol.ops
        print(f"== {name} of Yuan & Zhang (2023): h = 1/{round(1 / h)}, SADMM from rho_0 = {rho:g}")
        print(f"mesh         {ops.n_free} free dofs, {ops.n_c} contact nodes, {sol.mode} mode "
              f"(setup {sol.setup_time:.3f} s)")
        print(sol.result.summary())
        path = out / f"{scene.name}.png"
        figure_solution(ops, sol.result.x, sol.result.lam, magnify,
                        f"{name}: SADMM, rho_0 = {rho:g}, h = 1/{round(1 / h)}, u x{magnify:g}", path,
                        p=sol.result.z)
        print(f"figure       {path}\n")
    return 0
