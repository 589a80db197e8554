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
# \min_x\; \tfrac12\|Ax - b\|^2 + \lambda\|x\|_1 .
# $$
#
# Split as $x - z = 0$ with $f(x) = \frac12 x^TA^TAx - (A^Tb)^Tx$ (up to a
# constant) and $g(z) = \lambda\|z\|_1$, ADMM needs two steps (with the
# multiplier written $y$, to keep $\lambda$ for the LASSO's weight):
#
# - **x-step:** $(A^TA + \rho I)\,x = A^Tb + \rho z - y$, one
#   factorisation per value of $\rho$;
# - **z-step:** $z = \mathrm{soft}(x + y/\rho,\ \lambda/\rho)$, the proximal
#   operator of $g/\rho$;
#
# and the dual update $y \leftarrow y + \rho\,(x - z)$, which the loop does.
# With the building blocks both steps are one line each:
# {class}`admmkit.QuadraticXStep` is the x-step of any quadratic $f$ with a
# constraint map (here the identity), cached per $\rho$, and
# {mod}`admmkit.blocks.prox` has the soft-thresholding:
#
# ```python
# x_step = admmkit.QuadraticXStep(A.T @ A, -A.T @ b)          # (A'A + rho I) x = A'b + rho z - y
# lasso = admmkit.SplitProblem(x_step, admmkit.blocks.prox.L1(lam))  # z = soft(x + y/rho, lam/rho)
# ```
#
# {class}`admmkit.SplitProblem` derives the rest, including the adjoint norm
# that Boyd's dual residual needs in the order xz. The plug-in
# `admmkit.problems.lasso` (the folder `problems/lasso/`, about a hundred
# lines) wraps these two lines with what a plug-in should have: input checks
# that name the parameter, the LASSO's own objective, a measure of its
# optimality, $\lambda_{\max}$ and a cvxpy reference. It is the plug-in to
# copy for a new problem.

# %%
import numpy as np

import admmkit
from admmkit.problems.lasso import Lasso, lam_max, solve_with_cvxpy

rng = np.random.default_rng(0)
m, n = 80, 200                                     # more unknowns than data: the l1 term picks a sparse x
truth = np.zeros(n)
truth[rng.choice(n, 8, replace=False)] = rng.choice([-2.0, 2.0], 8)
A = rng.standard_normal((m, n)) / np.sqrt(m)
b = A @ truth + 0.05 * rng.standard_normal(m)
lam = 0.1 * lam_max(A, b)                          # lam_max = ||A'b||_inf: above it, x = 0

lasso = Lasso(A, b, lam)
result = admmkit.solve(lasso, policy="summable", order="zx")   # default stop: Boyd's residuals
print(result.summary())

# %% [markdown]
# z is the soft-thresholded copy of x, so its zeros are exact; x itself
# still has entries of size 1e-5 where the solution is 0.
#
# The default stop is Boyd's residual test (`ResidualTolerance(1e-6, 1e-5)`,
# {func}`admmkit.default_stop`). When it fires, the result compares the
# problem's relative KKT measures with the tolerance and would say
# `converged_inaccurate` if they were more than ten times larger. The
# plug-in's measures are those of the LASSO itself: `primal`,
# $\|x - z\| / \max(\|x\|, \|z\|)$, and `subgradient`, the distance of 0 to
# $A^T(Az - b) + \lambda\,\partial\|z\|_1$ relative to
# $\max(\|A^TAz\|, \|A^Tb\|)$ (at z, whose zeros are exact).
#
# ## Check it with cvxpy

# %%
x_star = solve_with_cvxpy(A, b, lam)               # Clarabel to 1e-12

error = lambda r: np.linalg.norm(r.x - x_star) / np.linalg.norm(x_star)  # noqa: E731
print(f"default stop: {result.status}, {result.iterations} iterations, relative error {error(result):.1e}")
print(f"KKT measures: {', '.join(f'{k} {v:.1e}' for k, v in result.accuracy.items())}")
support = lambda v, eps: [int(i) for i in np.flatnonzero(np.abs(v) > eps)]  # noqa: E731
print(f"support: admmkit z {support(result.z, 0.0)}\n         cvxpy x   {support(x_star, 1e-6)}")
assert result.status is admmkit.Status.CONVERGED and error(result) < 1e-3
assert max(result.accuracy.values()) < 1e-5            # below the tolerance asked
assert support(result.z, 0.0) == support(x_star, 1e-6)
assert abs(result.objective - lasso.objective(x_star)) < 1e-5 * lasso.objective(x_star)

# %% [markdown]
# At $\lambda \ge \lambda_{\max} = \|A^Tb\|_\infty$ the solution is $x = 0$:
# $-A^Tb$ is then in $\lambda\,\partial\|0\|_1$. z is exactly 0; x is 0 to
# the absolute tolerance of Boyd's primal residual, $\sqrt{n}\,\epsilon_{abs}
# = 1.4 \cdot 10^{-5}$ (a relative measure of $\|x - z\|$ would be 1 here, so
# the plug-in's `primal` measures $x - z$ through the gradient $A^TA(x - z)$).

# %%
zero = admmkit.solve(Lasso(A, b, lam_max(A, b)))
print(f"lam = lam_max: {zero.status}, {zero.iterations} iterations, nonzeros of z: {np.count_nonzero(zero.z)}, "
      f"||x|| = {np.linalg.norm(zero.x):.1e}")
assert zero.converged and not np.any(zero.z) and np.linalg.norm(zero.x) < 2 * np.sqrt(n) * 1e-6

# %% [markdown]
# To 1e-8, with every registered rule in both orders, from a small, a
# medium and a large $\rho_0$ (an `*` marks a run stopped by the cap).  A
# rule with a penalty per row (`per_row`, such as `rowwise`) needs a problem
# that takes one (the QP plug-in); the LASSO takes one $\rho$, so those are
# left out:

# %%
tight = admmkit.ResidualTolerance(1e-12, 1e-12)
worst = 0.0
one_rho = [n for n in admmkit.policy_names() if not getattr(admmkit.make_policy(n), "per_row", False)]
for rule in one_rho:
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
# here for a slightly larger $\lambda$:

# %%
lasso2 = Lasso(A, b, 1.05 * lam)
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
#
# ## Writing your own
#
# Copy `problems/lasso/` and change the two lines: the x-step (any quadratic
# $f$ and map $A$, {class}`admmkit.QuadraticXStep`) and the z-step (any
# {mod}`admmkit.blocks.prox` operator); then the checks, the objective and the
# optimality measure of the new problem. [The layout](../layout.md) says
# where the rest goes.
