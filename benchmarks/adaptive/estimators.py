"""``admmkit bench estimators``: the ZZ and the residual estimators against the true discretisation error.

Uniform refinement, the discrete solutions solved tightly (independent of
the estimators):

- **radial obstacle** (h = 1/2 ... 1/32): u_h from cvxpy + Clarabel (gap and
  feasibility 1e-12), the true error ``|u - u_h|_{H1}`` against the exact
  solution;
- **contact Example 1**, P1 and P2 (h = 1/5 ... 1/40): u_h and the pressure
  from SADMM to Boyd residuals 1e-10 (mode condensed), the true error
  ``sqrt(2 (J(u_h) - J_ref))`` with J_ref the energy of the same order on h =
  1/80 (J(u_h) - J(u) >= ||u_h - u||_a^2 / 2; the reference's own error makes
  the smallest h's true error a little small).

Each row: the true error, both estimates and their effectivity indices
(estimate / true error).  Writes estimators.csv, estimators.md and
estimators.png (convergence of the three quantities, and the effectivities).
"""
from __future__ import annotations

import math
from pathlib import Path

import admmkit
from admmkit.figures import pyplot, save_figure
from admmkit.io import write_text

from admmkit.benchmarks.runner.report import fmt, md_table, write_csv

OBSTACLE_N = (8, 16, 32, 64, 128)                  # h = 4/N on (-2, 2)^2
CONTACT_H = (1 / 5, 1 / 10, 1 / 20, 1 / 40)
CONTACT_REFERENCE_H = 1 / 80


def obstacle_rows(meshes=OBSTACLE_N) -> list[dict]:
    """One row per mesh of the radial obstacle."""
    from admmkit.problems.obstacle import make_problem, radial, solve_with_cvxpy
    from admmkit.problems.obstacle.estimate import zz_estimate
    from admmkit.problems.obstacle.estimate_residual import residual_estimate
    rows = []
    for N in meshes:
        problem = make_problem(radial(h=4 / N))
        u_h, _ = solve_with_cvxpy(problem, tol_gap_abs=1e-12, tol_gap_rel=1e-12, tol_feas=1e-12)
        rows.append(_row("radial obstacle", "P1", 4 / N, problem.n, problem.errors(u_h)["H1_semi"],
                         zz_estimate(problem, u_h), residual_estimate(problem, u_h)))
    return rows


def contact_rows(order: int, meshes=CONTACT_H) -> list[dict]:
    """One row per mesh of contact Example 1 in P1 or P2."""
    from admmkit.problems.contact import assemble, example1, solve_scene
    from admmkit.problems.contact.solvers.estimate import zz_estimate
    from admmkit.problems.contact.solvers.estimate_residual import residual_estimate
    from admmkit.problems.contact.validation.reference import energy

    def tight(ops):
        sol = solve_scene(ops, "sadmm", 1e3, mode="condensed", stop=admmkit.ResidualTolerance(1e-10, 1e-10),
                          max_iter=50_000)
        return sol.result.x, sol.result.lam

    fine = assemble(example1(h=CONTACT_REFERENCE_H, order=order))
    J_ref = energy(fine, tight(fine)[0])
    rows = []
    for h in meshes:
        ops = assemble(example1(h=h, order=order))
        u, lam = tight(ops)
        rows.append(_row("contact Example 1", f"P{order}", h, ops.n_free, math.sqrt(2 * max(energy(ops, u) - J_ref, 0.0)),
                         zz_estimate(ops, u), residual_estimate(ops, u, lam)))
    return rows


def _row(scene, order, h, n, error, zz, residual) -> dict:
    row = {"scene": scene, "order": order, "h": h, "unknowns": n, "true_error": error, "zz": zz, "residual": residual,
           "zz_effectivity": zz / error, "residual_effectivity": residual / error}
    print(f"  {scene:18s} {order}  h = {h:.4g}  n = {n:6d}  error {error:.3e}  ZZ {zz:.3e} ({zz / error:.2f})  "
          f"residual {residual:.3e} ({residual / error:.2f})", flush=True)
    return row


def markdown(rows: list[dict]) -> str:
    """The table of every (scene, order, mesh)."""
    body = [[r["scene"], r["order"], f"1/{round(1 / r['h'])}" if r["h"] < 1 else fmt(r["h"], "g"), r["unknowns"],
             fmt(r["true_error"], ".3e"), fmt(r["zz"], ".3e"), fmt(r["zz_effectivity"], ".2f"), fmt(r["residual"], ".3e"),
             fmt(r["residual_effectivity"], ".2f")] for r in rows]
    return md_table(["scene", "order", "h", "unknowns", "true error", "ZZ", "ZZ effectivity", "residual",
                     "residual effectivity"], body)


def plot(rows: list[dict], path: Path) -> Path:
    """Left and middle: true error and both estimates against h; right: the effectivity indices."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.2))
    groups = [("radial obstacle", "P1"), ("contact Example 1", "P1"), ("contact Example 1", "P2")]
    for (scene, order), colour in zip(groups, ("C0", "C1", "C2")):
        sub = [r for r in rows if r["scene"] == scene and r["order"] == order]
        if not sub:
            continue
        h = [r["h"] for r in sub]
        ax = axes[0] if scene.startswith("radial") else axes[1]
        style = "-" if order == "P1" else "--"
        ax.loglog(h, [r["true_error"] for r in sub], "k" + style, marker="o", label=f"true error {order}")
        ax.loglog(h, [r["zz"] for r in sub], style, color="C0", marker="s", label=f"ZZ {order}")
        ax.loglog(h, [r["residual"] for r in sub], style, color="C3", marker="^", label=f"residual {order}")
        label = f"{scene} {order}"
        axes[2].semilogx(h, [r["zz_effectivity"] for r in sub], "s-", color=colour, label=f"ZZ, {label}")
        axes[2].semilogx(h, [r["residual_effectivity"] for r in sub], "^--", color=colour, label=f"residual, {label}")
    axes[0].set_title("radial obstacle: |u - u_h|_H1 (exact solution)")
    axes[1].set_title("contact Example 1: ||u - u_h||_a (h = 1/80 reference)")
    axes[2].set_title("effectivity = estimate / true error")
    axes[2].axhline(1.0, color="grey", lw=0.8)
    axes[2].set_yscale("log")
    for ax in axes:
        ax.set_xlabel("h")
        ax.grid(True, which="both", alpha=0.3)
        ax.xaxis.set_minor_formatter(plt.NullFormatter())
        ax.legend(fontsize=7)
    fig.tight_layout()
    return save_figure(fig, path, ("png",), dpi=110)[0]


def run(out: Path, command: str, quick: bool = False) -> list[Path]:
    """Run the study and write estimators.csv, .md and .png to ``out`` (quick: the three coarsest meshes)."""
    out = Path(out)
    cut = 3 if quick else None
    print("estimators against the true error (uniform refinement):", flush=True)
    rows = obstacle_rows(OBSTACLE_N[:cut]) + contact_rows(1, CONTACT_H[:cut]) + contact_rows(2, CONTACT_H[:cut])
    write_csv(out / "estimators.csv", rows)
    write_text(out / "estimators.md", "# The ZZ and the residual estimators against the true error\n\n"
               + markdown(rows) + f"\n\nMade by `{command}`.\n")
    return [out / "estimators.csv", out / "estimators.md", plot(rows, out / "estimators.png")]
