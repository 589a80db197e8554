"""``admmkit warm-up``: compile (or load from numba's cache) the compiled kernels now, group by group.

A fresh install has an empty numba cache: the first solve that runs compiled
code compiles its kernels then (HS21: about 20 s on a loaded 2-core
machine), and every later process loads them from the cache in a fraction
of a second.  This command does that compile when the user chooses, with a
line per group of kernels and the time it took:

- the QP plug-in's (``solve_qp`` with ``compiled=True``: Ruiz scaling, the
  KKT matrix, the segment, the residuals, the infeasibility certificates, the
  symmetry test, the KKT and neutral residuals of the result);
- the building blocks' segment (:class:`admmkit.SplitProblem`, a LASSO);
- the sparse LDL' factorisation (:mod:`admmkit.linalg.ldl`) and AMD's ordering
  (:mod:`admmkit.linalg.amd`);
- the finite element plug-ins' (small contact and obstacle runs that reach
  them): the AMG V-cycles and their set-up, CG, the 3-D finest level, the
  condensed set-up's ordering.

The kernels are those every route uses: the QP's matrices have int32
indices whatever route they come by (docs/qp.md, "First call").  The finite element group
imports NGSolve (the 2-D scenes are assembled with it) and compiles the
kernels of the cycles at the sizes where they run: a V-cycle of three levels
or more, 2x2 node blocks in 2-D, 3x3 and 6x6 blocks in 3-D.
"""
from __future__ import annotations

import time

import numpy as np


def qp_kernels() -> None:
    """Every QP kernel, through ``solve_qp(..., compiled=True)`` on QPs that reach each of them: OSQP's settings
    with its polish, a callback that reads the tested iterations (the segment without the test in its kernel: bench
    qp's and bench rules' harness), admmkit's preset (polishing during the run, a penalty per row), Anderson's and
    fast ADMM's steps in the segment, the infeasibility certificates."""
    from admmkit.kernels import compiled_code
    from admmkit.problems.qp import admmkit_settings, solve_qp
    from admmkit.problems.qp.generate import infeasible_qp, random_qp, unbounded_qp
    from admmkit.problems.qp.residuals import neutral_residuals
    from admmkit.problems.qp.sparse_kernels import symmetry_defect
    qp = random_qp(30, 40, seed=0)
    res = solve_qp(qp, compiled=True, polish=True)

    def tested(rec):                    # a callback that reads the tested iterations (bench qp's and rules' watch)
        return False
    tested.every_record, tested.every_tested = False, True
    solve_qp(qp, compiled=True, callback=tested)      # the segment that stops at each of them (segment._xz_kkt)
    solve_qp(qp, admmkit_settings(1e-6, 0.0), compiled=True)
    solve_qp(qp, compiled=True, acceleration="anderson")
    solve_qp(qp, compiled=True, acceleration="fast")
    solve_qp(infeasible_qp(seed=0), compiled=True)
    solve_qp(unbounded_qp(seed=0), compiled=True)
    with compiled_code(True):
        symmetry_defect(qp.P.indptr, qp.P.indices, qp.P.data)
        neutral_residuals(qp, res.x, res.y)
        qp.kkt(res.x, qp.A @ res.x, res.y)


def split_kernels() -> None:
    """The building blocks' compiled segment, through a LASSO with the direct x-step."""
    import admmkit
    from admmkit import QuadraticXStep, SplitProblem
    from admmkit.blocks import prox
    rng = np.random.default_rng(0)
    D, b = rng.standard_normal((50, 30)), rng.standard_normal(50)
    mu = 0.1 * np.abs(D.T @ b).max()
    problem = SplitProblem(QuadraticXStep(D.T @ D, -D.T @ b, None, n=30, solver="direct", backend="qdldl"),
                           prox.L1(mu))
    admmkit.solve(problem, policy="osqp", check_every=25, max_iter=100)


def ldl_kernels() -> None:
    """The sparse LDL' factorisation and its solve (:mod:`admmkit.linalg.ldl`), and AMD's ordering
    (:mod:`admmkit.linalg.amd`: about 18 s to compile)."""
    import scipy.sparse as sp

    from admmkit.linalg.amd import amd_order
    from admmkit.linalg.ldl import ldl_factor
    A = sp.diags([-np.ones(29), 4 * np.ones(30), -np.ones(29)], [-1, 0, 1], format="csc")
    ldl_factor(A, amd_order(A.indptr, A.indices, 30)).solve(np.ones(30))


def fe_kernels() -> None:
    """The finite element plug-ins' kernels, through runs small enough to take seconds and large enough for a
    V-cycle of three levels: contact Example 1 at h = 1/80 iterative (2-D AMG in 2x2 node blocks, CG) and
    condensed (the nested dissection ordering), the 3-D block at h = 1/16 iterative (the compiled stiffness and
    finest AMG level, the 3x3 block Gauss-Seidel and 6x6 coarse level) and the obstacle with the iterative
    backend (the scalar V-cycle)."""
    import admmkit
    from admmkit.problems.contact.model.scene import SCENES_DIR
    from admmkit.problems.contact.model.scene_file import load_scene
    from admmkit.problems.contact.solvers.methods import solve_scene
    from admmkit.problems.obstacle.discrete import make_problem
    from admmkit.problems.obstacle.scene import radial
    for name, h, modes in (("ex1", 1 / 80, ("iterative", "condensed")), ("block3d", 1 / 16, ("iterative",))):
        for mode in modes:
            solve_scene(load_scene(SCENES_DIR / f"{name}.toml", h=h), mode=mode, max_iter=200)
    admmkit.solve(make_problem(radial(1 / 32), backend="iterative"), rho=1.0, max_iter=50)


#: (name, what it runs), in the order they are warmed
GROUPS = (("QP plug-in (solve_qp, the cvxpy and qpsolvers routes)", qp_kernels),
          ("building blocks (SplitProblem's compiled segment)", split_kernels),
          ("sparse LDL' and AMD's ordering (admmkit.linalg.ldl, admmkit.linalg.amd)", ldl_kernels),
          ("finite elements (contact and obstacle: AMG V-cycles, CG, the 3-D finest level)", fe_kernels))


def kernels_ready() -> int:
    """How many of admmkit's kernels are compiled or loaded in this process (those only other kernels call are
    compiled inside them, or loaded with them from the cache, and not counted)."""
    from admmkit.kernels import KERNELS
    return sum(k._dispatcher is not None and bool(k._dispatcher.signatures) for ks in KERNELS.values() for k in ks)


def run(args) -> int:
    """Warm every group, a line each; exit code 0."""
    from admmkit import kernels
    if not kernels.AVAILABLE:
        print("admmkit warm-up: numba is not installed: every run takes the Python path, nothing to compile")
        return 0
    kernels._noted = True              # no "compiling ..." note: this command says what it compiles
    start = time.perf_counter()
    for name, warm in GROUPS:
        t0 = time.perf_counter()
        print(f"  {name} ...", end="", flush=True)
        warm()
        print(f" ready in {time.perf_counter() - t0:.1f} s", flush=True)
    print(f"admmkit warm-up: {kernels_ready()} kernels compiled or loaded from numba's cache in "
          f"{time.perf_counter() - start:.1f} s; later processes load them from the cache")
    return 0


def register(subparsers) -> None:
    """``admmkit warm-up``: the top-level command (entry point ``warm-up`` in pyproject.toml)."""
    p = subparsers.add_parser(
        "warm-up", help="compile (or load from numba's cache) every compiled kernel now, so that no later call "
                        "waits for it",
        description="Compile the numba kernels now, with a line per group and the time it took: on a fresh "
                    "install the first solve that runs compiled code would compile them (about 20 s for the "
                    "QP's); afterwards every process loads them from numba's cache. Small problems never need "
                    "them (docs/qp.md, \"First call\"). The finite element group covers the contact and obstacle "
                    "plug-ins (AMG V-cycles, CG, the 3-D set-up).\n\ntypical: 2-4 minutes after an install (half of "
                    "it the QP's, most of the rest the finite element group), under 10 s after.")
    p.set_defaults(func=run)
