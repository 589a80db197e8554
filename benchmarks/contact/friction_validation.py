"""Friction validation: Cattaneo-Mindlin partial slip under refinement, and every rule across rho_0.

    python -m admmkit.benchmarks.contact.friction_validation [--out out/friction_validation] [--quick]

1. **Cattaneo-Mindlin** (:mod:`admmkit.problems.contact.validation.cattaneo`): the Hertz
   half-cylinder (R = 1, E = 1, a ~ 0.02) pressed onto a rigid plane and
   sheared by moving the plane by ``--slide`` along x, Coulomb friction mu,
   nu = 0.49 (Dundurs' beta = 0.0196), P2, contact mesh sizes h_c = a/5,
   a/10, a/20.  Measured: the loads P and Q, the stick half-width c, the peak
   pressure p0 and the peak tangential traction q_max, against Cattaneo-Mindlin
   at the measured P and Q (c = a sqrt(1 - Q/(mu P)), q_max = mu p0 sqrt(Q/(mu P)),
   a and p0 Hertz's at P).  The coupling left at nu = 0.49: the shift of the
   stick zone off the centre and the change of the peak pressure against the
   frictionless run.
2. **Stability**: every ADMM method (:mod:`admmkit.benchmarks.fixtures.methods`) on Example 1
   with Tresca friction (s = 2) and with Coulomb friction (mu = 0.3, pushed
   sideways by a traction (2, 0) on the right edge), h = 1/20, rho_0 = s E for
   s = 1e-4 ... 1e4, the paper's stop (relative change 1e-5 in the energy
   norm) or 5000 iterations per ADMM run; outcome ``converged`` when the
   error ||u - u*||_K / ||u*||_K <= 1e-3 against a tight reference u*
   (Tresca: Clarabel; Coulomb: SADMM to 1e-11 with the fixed point to 1e-10).

Written to ``--out``: cattaneo.csv, cattaneo_traction.png, cattaneo_errors.png,
stability.csv, stability.png and README.md with the command line and the tables.
"""
from __future__ import annotations


from admmkit.cli import Parser
import csv
import math
import sys
import time
from pathlib import Path

import numpy as np

from admmkit.io import atomic_open, atomic_path, write_text
from admmkit.benchmarks.runner.costs import typical

HC_FACTORS = (5, 10, 20)       # h_c = a_target / factor
RHO_SCALES = tuple(10.0 ** k for k in range(-4, 5))


def cattaneo_study(mu: float, slide: float, nu: float, factors) -> tuple[list[dict], dict]:
    """Rows of the refinement study and the finest solution's profiles."""
    import dataclasses

    from admmkit.problems.contact import solve_scene
    from admmkit.problems.contact.validation.cattaneo import cattaneo_scene, dundurs_beta, measure_stick
    from admmkit.problems.contact.validation.hertz import HertzCase

    case = HertzCase(nu=nu)
    rows, finest = [], {}
    for factor in factors:
        h_c = case.a_target / factor
        t0 = time.perf_counter()
        scene = dataclasses.replace(cattaneo_scene(case, h_c, mu, slide), order=2)
        sol = solve_scene(scene, "sadmm", rho=case.E)
        m = measure_stick(sol, case, mu)
        free = solve_scene(dataclasses.replace(scene, tangential="frictionless", mu=None, obstacle_slide=0.0),
                           "sadmm", rho=case.E)
        coupling = float(np.abs(sol.pressure - free.pressure).max() / free.pressure.max())
        rows.append({"h_c": h_c, "a_over_h_c": factor, "n_c": sol.ops.n_c, "n_free": sol.ops.n_free,
                     "outer": sol.coulomb.outer_iterations, "admm_iterations": sol.coulomb.total_iterations,
                     "last_change_s": sol.coulomb.changes[-1], "converged": sol.converged,
                     **m, "stick_shift_over_a": m["stick_shift"] / m["a_hertz"],
                     "pressure_change_vs_frictionless": coupling, "beta": dundurs_beta(nu),
                     "seconds": time.perf_counter() - t0})
        finest = {"x": sol.ops.xc[:, 0], "p": sol.pressure, "q": np.abs(sol.tangential_traction[0]),
                  "zones": sol.zones, "m": m, "case": case}
        print(f"  h_c = a/{factor:<3} n_c {sol.ops.n_c:4}  outer {sol.coulomb.outer_iterations}  "
              f"Q/(mu P) {m['Q_over_muP']:.3f}  c {m['c_h']:.5f} vs {m['c_ref']:.5f} ({m['c_err']:+.2%})  "
              f"p0 {m['p0_err']:+.2%}  q_max {m['q_max_err']:+.2%}  shift/a {rows[-1]['stick_shift_over_a']:+.3f}  "
              f"({rows[-1]['seconds']:.1f} s)", flush=True)
    return rows, finest


def _scenes(h: float):
    from admmkit.problems.contact import example1
    return {"ex1_tresca": example1(h=h, tangential="tresca", slip_bound=2.0),
            "ex1_coulomb": example1(h=h, tangential="coulomb", mu=0.3,
                                    tractions={"top": (0.0, -10.0), "right": (2.0, 0.0)})}


def stability_study(h: float, scales, max_iter: int) -> list[dict]:
    """Every method x rho_0 on the two frictional examples."""
    from admmkit import ResidualTolerance
    from admmkit.benchmarks.fixtures.methods import admm_methods, resolve
    from admmkit.problems.contact import assemble, solve_scene
    from admmkit.problems.contact.solvers.tresca_qp import tresca_cvxpy

    rows = []
    for name, scene in _scenes(h).items():
        ops = assemble(scene)
        if scene.tangential == "tresca":
            u_ref = tresca_cvxpy(ops)[0]
        else:
            u_ref = solve_scene(ops, "sadmm", rho=scene.E, stop=ResidualTolerance(1e-11, 1e-11),
                                coulomb_tol=1e-10, coulomb_max_outer=100).u
        energy = lambda v: math.sqrt(max(v @ (ops.K @ v), 0.0))  # noqa: E731
        for label in admm_methods():
            policy, order = resolve(label)
            for s in scales:
                t0 = time.perf_counter()
                try:
                    sol = solve_scene(ops, policy, rho=s * scene.E, order=order, max_iter=max_iter)
                    err = energy(sol.u - u_ref) / energy(u_ref)
                    status = str(sol.result.status)
                    outer = sol.coulomb.outer_iterations if sol.coulomb else 1
                    iters = sol.coulomb.total_iterations if sol.coulomb else sol.result.iterations
                    fp_ok = sol.coulomb.converged if sol.coulomb else True
                except Exception as exc:   # a rule that raises is a failure of that rule, recorded as such
                    err, status, outer, iters, fp_ok = float("nan"), f"error: {type(exc).__name__}", 0, 0, False
                ended = status in ("converged", "converged_inaccurate")
                outcome = ("converged" if ended and fp_ok and err <= 1e-3 else
                           "false_convergence" if ended and fp_ok else
                           "fixed_point_not_converged" if ended else status)
                rows.append({"scene": name, "method": label, "rho_scale": s, "rho0": s * scene.E,
                             "status": status, "outcome": outcome, "iterations": iters, "outer": outer,
                             "error": err, "seconds": time.perf_counter() - t0})
        ok = sum(r["outcome"] == "converged" for r in rows if r["scene"] == name)
        total = sum(r["scene"] == name for r in rows)
        print(f"  {name}: {ok}/{total} runs converged", flush=True)
    return rows


def _write_csv(path: Path, rows: list[dict]) -> None:
    with atomic_open(path, "w", newline="") as fh:       # whole or not at all (admmkit/io.py)
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})


def _figures(out: Path, rows: list[dict], finest: dict, stab: list[dict], scales) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from admmkit.problems.contact.validation.cattaneo import cattaneo_traction
    from admmkit.problems.contact.validation.hertz import hertz_pressure

    m, case = finest["m"], finest["case"]
    x, order = finest["x"], np.argsort(finest["x"])
    xs = np.linspace(x.min(), x.max(), 800)
    fig, ax = plt.subplots(figsize=(8, 4.2))
    a = m["a_hertz"]
    ax.plot(xs / a, hertz_pressure(xs, m["P"], case.R, case.E, case.nu), "k-", lw=1, label="Hertz p(x)")
    ax.plot(x[order] / a, finest["p"][order], "o", ms=3, color="C0", label="computed pressure p_n")
    mu = rows[0]["Q"] / (rows[0]["Q_over_muP"] * rows[0]["P"])
    ax.plot(xs / a, mu * hertz_pressure(xs, m["P"], case.R, case.E, case.nu), "k:", lw=1, label="mu p (Hertz)")
    ax.plot(xs / a, cattaneo_traction(xs, m["P"], m["Q"], mu, case.R, case.E, case.nu), "r-", lw=1,
            label="Cattaneo-Mindlin |q(x)|")
    ax.plot(x[order] / a, finest["q"][order], "s", ms=3, color="C3", label="computed |q|")
    stick = finest["zones"] == 1
    ax.axvspan(x[stick].min() / a, x[stick].max() / a, color="C2", alpha=0.12, label="computed stick zone")
    for sgn in (-1, 1):
        ax.axvline(sgn * m["c_ref"] / a, color="C2", ls="--", lw=1)
    ax.set(xlim=(-1.4, 1.4), xlabel="x / a (Hertz)", ylabel="traction",
           title=f"Cattaneo-Mindlin, nu = {case.nu}, mu = {mu:g}, Q/(mu P) = {m['Q_over_muP']:.3f}, "
                 f"h_c = a/{rows[-1]['a_over_h_c']} (dashed: c theory)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    with atomic_path(out / "cattaneo_traction.png") as tmp:
        fig.savefig(tmp, dpi=130, format="png")
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6, 4))
    hc = np.array([r["a_over_h_c"] for r in rows])
    for key, label in (("c_err", "stick half-width c"), ("q_max_err", "peak |q|"), ("p0_err", "peak pressure p0"),
                       ("a_err", "contact half-width a")):
        ax.loglog(hc, [abs(r[key]) for r in rows], "o-", label=label)
    ax.set(xlabel="a / h_c", ylabel="|relative error| vs Hertz / Cattaneo-Mindlin",
           title=f"Refinement, nu = {case.nu} (P2)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    with atomic_path(out / "cattaneo_errors.png") as tmp:
        fig.savefig(tmp, dpi=130, format="png")
    plt.close(fig)

    scenes = sorted({r["scene"] for r in stab})
    methods = list(dict.fromkeys(r["method"] for r in stab))
    fig, axes = plt.subplots(1, len(scenes), figsize=(5.2 * len(scenes), 0.32 * len(methods) + 1.8), sharey=True)
    for ax, name in zip(np.atleast_1d(axes), scenes):
        grid = np.full((len(methods), len(scales)), np.nan)
        for r in stab:
            if r["scene"] == name:
                i, j = methods.index(r["method"]), scales.index(r["rho_scale"])
                grid[i, j] = r["iterations"]
                if r["outcome"] != "converged":
                    ax.text(j, i, "x", ha="center", va="center", color="red", fontsize=9, fontweight="bold")
        im = ax.imshow(np.log10(np.maximum(grid, 1)), aspect="auto", cmap="viridis")
        ax.set_xticks(range(len(scales)), [f"{s:.0e}" for s in scales], rotation=60, fontsize=7)
        ax.set_yticks(range(len(methods)), methods, fontsize=7)
        ax.set(title=f"{name}: ADMM iterations (x = failed)", xlabel="rho_0 / E")
        fig.colorbar(im, ax=ax, label="log10 iterations")
    fig.tight_layout()
    with atomic_path(out / "stability.png") as tmp:
        fig.savefig(tmp, dpi=130, format="png")
    plt.close(fig)


def _readme(out: Path, argv: list[str], rows, stab, seconds: float, args) -> None:
    from admmkit.problems.contact.validation.cattaneo import dundurs_beta
    lines = [f"# Friction validation", "",
             f"Produced by `python -m admmkit.benchmarks.contact.friction_validation {' '.join(argv)}` in {seconds:.0f} s "
             f"(BLAS on one thread, a shared 2-core machine).", "",
             "## Cattaneo-Mindlin partial slip (Coulomb)", "",
             f"Hertz half-cylinder R = 1, E = 1, nu = {args.nu} (Dundurs' beta = {dundurs_beta(args.nu):.4f}; "
             f"0 at nu = 1/2), P2 elements, mu = {args.mu}, the plane raised by Hertz's delta guess and moved by "
             f"{args.slide:g} along x; SADMM, rho_0 = E, each Tresca step stopped by the paper's rule, the fixed point "
             f"at a relative change of s of 1e-4. References at the measured loads P and Q: "
             f"c = a sqrt(1 - Q/(mu P)) with Hertz's a(P), q_max = mu p0 sqrt(Q/(mu P)), p0 = Hertz's.", "",
             "| a/h_c | n_c | outer | ADMM it. | Q/(mu P) | c computed | c reference | c error | p0 error | "
             "q_max error | a error | stick shift / a | pressure change vs frictionless |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['a_over_h_c']} | {r['n_c']} | {r['outer']} | {r['admm_iterations']} | "
                     f"{r['Q_over_muP']:.3f} | {r['c_h']:.5f} | {r['c_ref']:.5f} | {r['c_err']:+.2%} | "
                     f"{r['p0_err']:+.2%} | {r['q_max_err']:+.2%} | {r['a_err']:+.2%} | "
                     f"{r['stick_shift_over_a']:+.4f} | {r['pressure_change_vs_frictionless']:.2%} |")
    lines += ["", "![tractions](cattaneo_traction.png)", "", "![errors](cattaneo_errors.png)", "",
              "## Stability: every method across rho_0", "",
              f"Example 1, h = {args.h:g}, with Tresca (s = 2) and Coulomb (mu = 0.3, right-edge traction (2, 0)) "
              f"friction; rho_0 = s E; the paper's stop or {args.max_iter} iterations per ADMM run. "
              "`converged` = the run ended by its rule (and the fixed point converged) with an energy-norm error "
              "<= 1e-3 against the reference.", "",
              "| scene | method | converged / runs | failures (rho_0 / E: outcome) | median iterations |",
              "|---|---|---:|---|---:|"]
    for name in sorted({r["scene"] for r in stab}):
        for method in dict.fromkeys(r["method"] for r in stab):
            rs = [r for r in stab if r["scene"] == name and r["method"] == method]
            ok = [r for r in rs if r["outcome"] == "converged"]
            fails = ", ".join(f"{r['rho_scale']:.0e}: {r['outcome']}" for r in rs if r["outcome"] != "converged")
            med = int(np.median([r["iterations"] for r in ok])) if ok else "-"
            lines.append(f"| {name} | {method} | {len(ok)}/{len(rs)} | {fails or '-'} | {med} |")
    lines += ["", "![stability](stability.png)", ""]
    write_text(out / "README.md", "\n".join(lines))


def main(argv=None, prog: str = "admmkit bench friction") -> int:
    """Run both studies, print the tables, write CSV, PNG and README.md to --out."""
    parser = Parser(prog=prog, description=__doc__.split("\n\n")[0] +   # one-line usage errors (admmkit.cli)
                    typical("bench friction") + " needs: ngsolve, matplotlib")
    parser.add_argument("--out", default="out/friction_validation", help="output folder (default out/friction_validation)")
    parser.add_argument("--mu", type=float, default=0.3, help="Coulomb coefficient of the Cattaneo case (default 0.3)")
    parser.add_argument("--nu", type=float, default=0.49, help="Poisson ratio of the Cattaneo case (default 0.49)")
    parser.add_argument("--slide", type=float, default=3e-4, help="tangential move of the plane (default 3e-4)")
    parser.add_argument("--h", type=float, default=1 / 20, help="mesh size of the stability examples (default 1/20)")
    parser.add_argument("--max-iter", type=int, default=5000, help="iteration cap per ADMM run (default 5000)")
    parser.add_argument("--quick", action="store_true", help="two meshes, three rho_0 (a smoke run)")
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(argv)
    if not (0 < args.mu and math.isfinite(args.mu)):
        parser.error(f"--mu must be a finite number > 0, got {args.mu}")
    if not (0 < args.slide and math.isfinite(args.slide)):
        parser.error(f"--slide must be a finite number > 0, got {args.slide}")
    if args.max_iter < 1:
        parser.error(f"--max-iter must be >= 1, got {args.max_iter}")
    from admmkit.benchmarks.runner.harness import require
    require(prog.removeprefix("admmkit "), "cvxpy", "clarabel")     # the Tresca references
    from admmkit.loop.blas import limit_blas
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    factors = HC_FACTORS[:2] if args.quick else HC_FACTORS
    scales = RHO_SCALES[::4] if args.quick else RHO_SCALES
    t0 = time.perf_counter()
    with limit_blas(1):
        print("Cattaneo-Mindlin under refinement")
        rows, finest = cattaneo_study(args.mu, args.slide, args.nu, factors)
        print("Stability: every method across rho_0")
        stab = stability_study(args.h, list(scales), args.max_iter)
    _write_csv(out / "cattaneo.csv", rows)
    _write_csv(out / "stability.csv", stab)
    _figures(out, rows, finest, stab, list(scales))
    _readme(out, argv, rows, stab, time.perf_counter() - t0, args)
    print(f"wrote {out}/README.md, cattaneo.csv, stability.csv, cattaneo_traction.png, cattaneo_errors.png, "
          f"stability.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
