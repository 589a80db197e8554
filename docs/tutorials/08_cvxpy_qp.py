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
# # 8. Your own QP from cvxpy, with any penalty rule
#
# Most people write a QP in cvxpy, not as matrices. cvxpy reduces the
# problem to $\min \tfrac12 x^TPx + q^Tx$ subject to $Ax = b$, $Fx \le g$ and
# hands it to a QP solver. `ADMMKIT` is such a solver: it stacks the data into
# OSQP's form $l \le [A; F]x \le u$ and solves it with admmkit's QP plug-in
# (OSQP's machinery) and the penalty rule you choose. cvxpy then gets back its
# own statuses, the primal values and the duals.
#
# A portfolio problem: minimise risk minus return, fully invested, long only,
# at most 30 % in one asset.

# %%
import cvxpy as cp
import numpy as np

from admmkit.problems.qp.cvxpy_interface import ADMMKIT

rng = np.random.default_rng(0)
n = 40
F = rng.standard_normal((n, 5)) / 4
Sigma = F @ F.T + np.diag(rng.uniform(0.01, 0.05, n))     # a factor model of the covariance
mu = rng.uniform(0.0, 0.1, n)                             # expected returns
w = cp.Variable(n)
budget, long_only, cap = cp.sum(w) == 1, w >= 0, w <= 0.3
portfolio = cp.Problem(cp.Minimize(cp.quad_form(w, Sigma) - 0.5 * mu @ w), [budget, long_only, cap])

portfolio.solve(solver=ADMMKIT(policy="osqp"), eps_abs=1e-8, eps_rel=0.0)
mine = portfolio.value, w.value.copy(), budget.dual_value
print(portfolio.status, f"objective {portfolio.value:.8f}", f"{portfolio.solver_stats.num_iters} iterations")

# %% [markdown]
# The same problem with Clarabel, an interior-point solver, for comparison:
# the objective, the weights and the dual of the budget constraint (the
# marginal value of one more unit of capital) agree.

# %%
portfolio.solve(solver=cp.CLARABEL)
print(f"Clarabel objective {portfolio.value:.8f}, budget dual {budget.dual_value:.6f} (admmkit {mine[2]:.6f})")
assert abs(mine[0] - portfolio.value) <= 1e-6 * max(1, abs(portfolio.value))
assert np.abs(mine[1] - w.value).max() <= 1e-4 and abs(mine[2] - budget.dual_value) <= 1e-4

# %% [markdown]
# Any rule works the same way, by name, as `module:Class`, or as
# `path/to/file.py:Class` (see the penalty-rule pages); here the paper's
# summable rule in order zx and the spectral rule.

# %%
for rule in ("summable", "aadmm"):
    portfolio.solve(solver=ADMMKIT(policy=rule, order="zx"), eps_abs=1e-8, eps_rel=0.0)
    print(f"{rule:10s} {portfolio.status}  objective {portfolio.value:.8f}  "
          f"{portfolio.solver_stats.num_iters} iterations")
    assert portfolio.status == cp.OPTIMAL and abs(portfolio.value - mine[0]) <= 1e-6

# %% [markdown]
# A problem with no feasible point is reported as cvxpy's `infeasible`
# (admmkit declares it only after an exact certificate is confirmed), and an
# unbounded one as `unbounded`.

# %%
too_much = cp.Problem(cp.Minimize(cp.quad_form(w, Sigma)), [cp.sum(w) == 1, w <= 0.01])
too_much.solve(solver=ADMMKIT())
print("40 assets of at most 1 % each, fully invested:", too_much.status)
assert too_much.status == cp.INFEASIBLE
