# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # 1. The paper's Example 1 with SADMM
#
# An elastic block $\Omega = (0,2)\times(0,1)$ is clamped on its left side,
# pressed down by a traction $(0,-10)$ on its top, and rests on a rigid
# foundation along its bottom, with an initial gap $g = 0.01$. Its material
# has $E = 2000$ and $\nu = 0.3$. The load pushes the bottom onto the
# foundation. What is the displacement, and where does the body touch?
#
# This is Example 1 of Yuan & Zhang (2023). Their self-adaptive ADMM (SADMM)
# solves it in a few dozen iterations from any starting penalty $\rho_0$.
# Here it is in a few lines.
#
# Run this page as a script (`python docs/tutorials/01_example1_sadmm.py`) or
# open it as a notebook with jupytext. `H` is the mesh size: the paper goes
# down to 1/40.

# %%
H = 1 / 40

# %%
from admmkit.problems.contact import example1, solve_scene

scene = example1(h=H)                            # geometry, material, loads, gap
sol = solve_scene(scene, "sadmm", rho=1e3)       # assemble, then run SADMM from rho_0 = 1e3
print(sol.result.summary())

# %% [markdown]
# `solve_scene` assembled the stiffness matrix `K`, the load `f`, the normal
# map `B` and the lumped boundary mass `mc` (see
# [the discrete contact model](../contact_model.md)). It then ran admmkit's
# loop in the order "zx" (z-step first: the paper's ADMM2) with the paper's
# summable rule for $\rho$. The run stopped by the paper's rule: the
# relative change of $u$ in the energy norm fell below $10^{-5}$.
#
# The summary also gives the KKT residuals of the discrete problem
# $\min \tfrac12 u^TKu - f^Tu$ subject to $Bu \le g$. They are small, so the
# stop is a solution and not merely a stall.
#
# Here are the numbers this page asserts. If the code drifts, the docs build
# fails.

# %%
result, ops = sol.result, sol.ops
print(f"{ops.n_free} unknowns, {ops.n_c} contact nodes, {sol.mode} mode")
print(f"iterations {result.iterations}, rho: {result.history['rho'][0]:g} -> {result.rho:g} "
      f"in {result.rho_changes} changes")
print(f"contact force sum(mc * lam) = {result.kkt['contact_force']:.4f}, "
      f"nodes in contact: {result.kkt['active_nodes']:.0f} of {ops.n_c}")

assert str(result.status) == "converged"
assert 25 <= result.iterations <= 60          # the reproduction: 29-47 for every rho_0 and h
assert result.kkt["penetration"] < 1e-4 * scene.gap_at(1.0, 0.0)   # 1.4e-7 against g = 0.01
assert result.kkt["stationarity"] < 1e-10
assert abs(result.kkt["contact_force"] - 10.30) < 0.1   # 10.296 at h = 1/40, 10.15 at h = 1/10

# %% [markdown]
# ## The deformed body
#
# The displacement is about a hundredth of the body's size, so we draw it
# magnified ten times. The red line is the foundation, $y = -g$, magnified
# the same way. The right part of the bottom edge lies on it; near the clamp
# the body is held up.

# %%
import matplotlib.pyplot as plt
from admmkit.problems.contact.output.plot import plot_deformed, plot_pressure_gap

fig, ax = plt.subplots(figsize=(9, 4.2))
pc = plot_deformed(ax, ops, sol.u, magnify=10, title=f"Example 1, SADMM, h = 1/{round(1 / H)}")
fig.colorbar(pc, ax=ax, label="|u|", fraction=0.025)
plt.show()

# %% [markdown]
# ## The contact pressure
#
# The multiplier `lam` is the contact pressure $-\sigma_n \ge 0$ at the
# contact nodes. It is positive exactly where the gap $g - u_n$ has closed,
# and zero where the body lifts off: complementarity, which the KKT residual
# above measured.

# %%
fig, axes = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
plot_pressure_gap(axes, ops, sol.u, sol.pressure, p=sol.result.z)   # p = g marks a node in contact
plt.show()

# %%
import numpy as np

gap = ops.g - ops.B @ sol.u
touching = gap < 1e-4 * ops.g.max()
print(f"touching for x in [{ops.xc[touching, 0].min():.3f}, {ops.xc[touching, 0].max():.3f}]")
print(f"largest pressure {sol.pressure.max():.2f} at x = {ops.xc[np.argmax(sol.pressure), 0]:.3f}")
assert np.all(sol.pressure >= 0)
# where the gap is open the pressure is at most 1e-3 of its peak (1.1e-3 against 15.3 at
# h = 1/40, at the edge of the contact zone: the stop is at a relative change of 1e-5)
assert np.all(sol.pressure[~touching] < 1e-3 * sol.pressure.max())
assert ops.xc[touching, 0].max() == ops.xc[:, 0].max()             # the free end touches

# %% [markdown]
# ## Where next
#
# - [Tutorial 2](02_rho_sweep.py) runs ADMM1, ADMM2 and SADMM over five
#   decades of $\rho_0$: the paper's Fig. 2.
# - `admmkit solve contact --scene ex1 --h 1/40 --method sadmm --rho 1e3 --plot out.png`
#   does the same from the command line.
