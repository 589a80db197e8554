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
# # 9. Rank your own rule against all of ours
#
# A penalty rule you write need not live in admmkit. Here we write one in a
# file of its own, outside the repository, and rank it against every built-in
# rule, with and without Anderson acceleration, on every family of
# `admmkit bench rules`: the Maros-Meszaros QPs under OSQP's machinery,
# contact Examples 1 and 2, the radial obstacle, Example 1 with Tresca
# friction, the four framework problems and the paper's stability grid.
# This is the quick suite; the command line runs the same thing:
#
# ```bash
# admmkit bench rules --quick --rules aadmm,fixed,osqp,quantized,residual_balancing,summable,summable_steps,wohlberg,jump.py:Jump
# ```
#
# ## The rule: jump to the balance
#
# SADMM's rule (eq. (17)) measures
# $w_k = \|\lambda^{k+1}-\lambda^k\|_M / (\rho_k\|Ax^{k+1}-Ax^k\|_M)$ and
# multiplies $\rho$ by a fixed factor $1+\tau$ when $w_k$ leaves
# $[1/(1+\tau), 1+\tau]$. Our idea: $w_k = 1$ is the balance the rule aims
# at, so jump there at once, $\rho_{k+1} = \rho_k w_k$, clipped to a factor
# 100, at most `budget` times; after that $\rho$ stays fixed and the method
# is plain ADMM, so it converges. It is twenty lines:

# %%
import tempfile
from pathlib import Path

RULE = '''
"""Jump to the balance of the paper's w_k (a tutorial rule)."""
from admmkit import Policy


class Jump(Policy):
    """rho_{k+1} = rho_k * clip(w_k, 1/100, 100) when w_k leaves [1/(1+tau), 1+tau], at most budget times."""

    def __init__(self, tau=2.0, budget=30):
        self.tau, self.budget = tau, budget

    def reset(self, rho0):
        super().reset(rho0)
        self.changes = 0

    def update(self, rec):
        if rec.rho_Ax_change <= 0 or self.changes >= self.budget:
            return rec.rho                                  # w_k undefined, or the budget spent
        w = rec.lam_change / rec.rho_Ax_change              # the paper's w_k
        if 1 / (1 + self.tau) <= w <= 1 + self.tau:
            return rec.rho                                  # balanced enough: keep rho
        self.changes += 1
        return rec.rho * min(max(w, 1e-2), 1e2)
'''
work = Path(tempfile.mkdtemp(prefix="admmkit_rank_"))
(work / "jump.py").write_text(RULE)
spec = f"{work / 'jump.py'}:Jump"
print(spec)

# %% [markdown]
# `spec` is all admmkit needs: `admmkit.solve(problem, policy=spec)`,
# `--policy` and `--rules` take a `path/to/file.py:Class` (or a
# `module:Class`, or a name that an installed package declares in the
# entry-point group `admmkit.policies`). The rule is checked before anything
# runs; a typo in the class name is refused with one message:

# %%
import admmkit

admmkit.make_policy(spec)                       # imports the file, checks the Policy protocol
try:
    admmkit.make_policy(f"{work / 'jump.py'}:Jmp")
except ValueError as err:
    print(err)

# %% [markdown]
# ## The ranking
#
# `admmkit bench rules` builds the grid (every rule in every family, each
# with and without acceleration), runs it on two local worker processes
# (`--dask-workers 8` puts it on Dask), and writes the report: about 1,100
# runs, a minute or two on two cores. The QP family reads the
# Maros-Meszaros files from `--data`; without them it is left out, and the
# report says so. We run the command as a user would (`python -m admmkit`
# is the `admmkit` command); in Python,
# {func}`admmkit.benchmarks.rules.study.run` is the function behind it.

# %%
import subprocess
import sys

# every rule with one rho (a rule with a penalty per row, such as rowwise, runs on the QPs only) and ours
rules = [*(n for n in admmkit.policy_names() if not getattr(admmkit.make_policy(n), "per_row", False)), spec]
data = Path("../../../shared/data/maros_meszaros")   # the QP test set beside the repository, if there
command = [sys.executable, "-m", "admmkit", "bench", "rules", "--quick", "--rules", ",".join(rules),
           "--out", str(work / "out"), "-q"] + (["--data", str(data)] if data.is_dir() else [])
run = subprocess.run(command, capture_output=True, text=True)
print(run.stdout[-1500:], run.stderr[-1500:])
assert run.returncode == 0

# %% [markdown]
# The report's README ranks every configuration (a rule, or a rule with an
# accelerator) by its Dolan-Moré performance profile of iterations, averaged
# over the families so that each family weighs the same; it also gives the
# time score, the solved counts per family (each family's own truthful
# "solved": a QP must pass OSQP's test *and* the neutral criteria, an FE run
# must reach 1e-6 relative error against an independent reference), the
# spread of iterations across $\rho_0$, and what acceleration does.

# %%
from IPython.display import Image, Markdown, display

readme = (work / "out" / "README.md").read_text()
table = readme.split("| rank |")[1].split("\n\n")[0]
display(Markdown("| rank |" + table))

# %%
display(Image(str(work / "out" / "profiles_iterations.png")))

# %% [markdown]
# The numbers behind it are in `runs.csv`, one row per run; pandas reads it.
# Where does our rule stand, family by family, against SADMM's rule
# (`summable`) and OSQP's?

# %%
import pandas as pd

runs = pd.read_csv(work / "out" / "runs.csv")
runs["rule"] = runs["rule"].replace({r: "jump" for r in runs["rule"].unique() if r.endswith(":Jump")})
plain = runs[runs["acceleration"] == "none"]
solved = plain.pivot_table(index="family", columns="rule", values="solved", aggfunc="mean")
print(solved[["jump", "summable", "osqp", "fixed"]].round(2))
its = plain[plain.solved].pivot_table(index="family", columns="rule", values="iterations", aggfunc="median")
print(its[["jump", "summable", "osqp", "fixed"]].round(0))

# %% [markdown]
# The ranking treats our rule as it treats the built-in ones: the same
# problems for every configuration (a run it does not solve counts as a
# failure at that problem), and every failure listed in `failures.md` with
# its status.

# %%
ranked = [line.split("|")[2].strip() for line in table.splitlines()[2:] if line.startswith("|")]
assert any(c.endswith(":Jump") for c in ranked), ranked
for rank, c in enumerate(ranked, 1):
    if c.endswith(":Jump"):
        print(f"{c.split('/')[-1]}: rank {rank} of {len(ranked)}")
assert len(ranked) == 2 * len(rules)                      # every rule, with and without Anderson
counts = plain.groupby("rule").size()
assert counts.nunique() == 1, counts                       # the same problems for every rule
assert solved.loc["framework", "jump"] > 0.5 and solved.loc["contact", "jump"] > 0.5
failures = (work / "out" / "failures.md").read_text()
print(failures.count("\n| ") - 1, "failed runs listed")
