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
# # 6. A new problem in a few lines: the LASSO
#
# The LASSO fits a sparse linear model,
#
# $$
# \min_x\; \tfrac12\|Dx - b\|^2 + \mu\|x\|_1 .
# $$
#
# Split as $x - z = 0$ with $f(x) = \frac12 x^TD^TDx - (D^Tb)^Tx$ (up to a
# constant) and $g(z) = \mu\|z\|_1$, ADMM needs two steps:
#
# - **x-step:** $(D^TD + \rho I)\,x = D^Tb + \rho z - \lambda$, one
#   factorisation per value of $\rho$;
# - **z-step:** $z = \mathrm{soft}(x + \lambda/\rho,\ \mu/\rho)$, the proximal
#   operator of $g/\rho$.
#
# With the building blocks both are one line each:
# {class}`admmkit.QuadraticXStep` is the x-step of any quadratic $f$ with a
# constraint map $A$ (here the identity), cached per $\rho$, and
# {mod}`admmkit.prox` has the soft-thresholding. {class}`admmkit.SplitProblem`
# derives the rest, including the adjoint norm that Boyd's dual residual
# needs in the order xz, and relative KKT residuals that every result is
# checked against.

# %%
import numpy as np

import admmkit
from admmkit import policies  # noqa: F401  (registers the penalty rules by name)

rng = np.random.default_rng(0)
m, n = 80, 200                                     # more unknowns than data: the l1 term picks a sparse x
truth = np.zeros(n)
truth[rng.choice(n, 8, replace=False)] = rng.choice([-2.0, 2.0], 8)
D = rng.standard_normal((m, n)) / np.sqrt(m)
b = D @ truth + 0.05 * rng.standard_normal(m)
mu = 0.1 * np.abs(D.T @ b).max()

lasso = admmkit.SplitProblem(admmkit.QuadraticXStep(D.T @ D, -D.T @ b), admmkit.prox.L1(mu))
result = admmkit.solve(lasso, policy="summable", order="zx")   # default stop: Boyd's residuals
print(result.summary())

# %% [markdown]
# z is the soft-thresholded copy of x, so its zeros are exact; x itself
# still has entries of size 1e-5 where the solution is 0.
#
# The default stop is Boyd's residual test (`ResidualTolerance(1e-6, 1e-5)`,
# {func}`admmkit.default_stop`). When it fires, the result compares the
# problem's relative KKT residuals with the tolerance and would say
# `converged_inaccurate` if they were more than ten times larger.
#
# ## Check it with cvxpy

# %%
import cvxpy as cp

x = cp.Variable(n)
reference = cp.Problem(cp.Minimize(0.5 * cp.sum_squares(D @ x - b) + mu * cp.norm1(x)))
reference.solve(solver=cp.CLARABEL, tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12)
x_star = x.value

error = lambda r: np.linalg.norm(r.x - x_star) / np.linalg.norm(x_star)  # noqa: E731
print(f"default stop: {result.status}, {result.iterations} iterations, relative error {error(result):.1e}")
support = lambda v, eps: [int(i) for i in np.flatnonzero(np.abs(v) > eps)]  # noqa: E731
print(f"support: admmkit z {support(result.z, 0.0)}\n         cvxpy x   {support(x_star, 1e-6)}")
assert result.status is admmkit.Status.CONVERGED and error(result) < 1e-3
assert support(result.z, 0.0) == support(x_star, 1e-6)

# %% [markdown]
# To 1e-8, with every registered rule in both orders, from a small, a
# medium and a large $\rho_0$ (an `*` marks a run stopped by the cap):

# %%
tight = admmkit.ResidualTolerance(1e-12, 1e-12)
worst = 0.0
for rule in admmkit.policy_names():
    cells = []
    for order in ("xz", "zx"):
        for rho0 in (1e-3, 1.0, 1e3):
            r = admmkit.solve(lasso, rho=rho0, policy=rule, order=order, stop=tight, max_iter=20_000)
            cells.append(f"{r.iterations:>6}{' ' if r.converged else '*'}")
            if rule != "fixed":
                worst = max(worst, error(r))
    print(f"{rule:>20}  xz: {' '.join(cells[:3])}   zx: {' '.join(cells[3:])}")
print(f"largest error of an adaptive rule: {worst:.1e}")
assert worst < 1e-8

# %% [markdown]
# Fixed $\rho$ needs the right $\rho_0$; the adaptive rules find one.
#
# ## Over-relaxation
#
# `alpha` in $(0, 2)$ relaxes the iteration (Eckstein & Bertsekas 1992;
# [the mathematics](../math.md) derives it for both orders). OSQP uses 1.6.
# The paper's methods keep `alpha = 1`.

# %%
for alpha in (1.0, 1.6):
    r = admmkit.solve(lasso, rho=1.0, policy="residual_balancing", order="xz", stop=tight, alpha=alpha, max_iter=20_000)
    print(f"alpha = {alpha}: {r.iterations} iterations, error {error(r):.1e}")
    assert r.converged and error(r) < 1e-8

# %% [markdown]
# ## Warm starts
#
# `result.x` is the solution and `result.x_iterate` the ADMM iterate it came
# from (the same here; a condensed plug-in maps one to the other). Passing a
# result as `warm_start` continues from its iterate, multiplier and $\rho$,
# here for a slightly larger $\mu$:

# %%
lasso2 = admmkit.SplitProblem(admmkit.QuadraticXStep(D.T @ D, -D.T @ b), admmkit.prox.L1(1.05 * mu))
cold = admmkit.solve(lasso2, policy="summable", order="zx", stop=tight, max_iter=20_000)
warm = admmkit.solve(lasso2, policy="summable", order="zx", stop=tight, max_iter=20_000,
                     warm_start=admmkit.solve(lasso, policy="summable", order="zx", stop=tight, max_iter=20_000))
print(f"cold start {cold.iterations} iterations, warm start {warm.iterations}")
assert warm.converged and np.allclose(warm.x, cold.x, atol=1e-8)
assert warm.iterations <= cold.iterations

# %% [markdown]
# The saving is small here (a few iterations of about 130): at a tolerance
# of 1e-12 most of ADMM's iterations are its linear tail, which a nearby
# start does not shorten.
