"""The memory model of the contact runs: estimates checked before anything is assembled.

2D (:class:`admmkit.problems.contact.model.scene.Scene`): :func:`estimate_memory` of the
assembled system and a factorisation or the AMG-CG solver, :func:`memory_need`
of a whole run in a mode, :func:`check_memory` that refuses a run that would
not fit.  3D (:class:`admmkit.problems.contact.model.scene3d.Scene3D`):
:func:`estimate_memory3d` and :func:`memory_need3d`.  The calibration runs are
in docs/results/scale/ (scale.md, contact3d.md).
"""
from __future__ import annotations

import math
from pathlib import Path

from admmkit.problems.contact.model.mesh import grid_counts


def available_memory() -> int:
    """Bytes of available memory (MemAvailable in /proc/meminfo; 8 GiB if unreadable)."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 8 * 2**30


SOLVERS = ("direct", "iterative")


def estimate_memory(area: float, perimeter: float, h: float, order: int, kind: str, solver: str = "direct") -> int:
    """Rough bytes for the assembled system (NGSolve + scipy copies) and a sparse LU.

    Vertices ~ area/h^2 (structured) or ~1.2 area/h^2 (netgen), dofs = 2 * order^2 *
    vertices; ~14 (P1) / ~26 (P2) nonzeros per row, 12 bytes each, 3 copies; fill of a
    nested-dissection factor of a 2D problem ~ 8 n log2 n nonzeros.  With
    ``solver="iterative"`` (the AMG-CG x-step, admmkit.blocks.iterative) the factor is
    replaced by what that solver holds, linear in n (:func:`iterative_solver_bytes`).
    """
    if solver not in SOLVERS:
        raise ValueError(f"solver = {solver!r}; accepted: {', '.join(SOLVERS)}")
    vertices = (1.0 if kind == "structured" else 1.2) * area / h**2 + perimeter / h
    n = 2 * order**2 * vertices
    nnz_row = 14 if order == 1 else 26
    system = 3 * 12 * nnz_row * n
    if solver == "iterative":
        return int(system + iterative_solver_bytes(n, nnz_row * n, blocksize=2))
    factor = 12 * 8 * n * math.log2(max(n, 2.0))
    return int(system + factor)


def iterative_solver_bytes(n: float, nnz: float, blocksize: int = 2) -> float:
    """Bytes the AMG-CG x-step holds for n unknowns and a matrix with nnz nonzeros.

    The permuted K and D (12 bytes a nonzero), K + rho D on one pattern (index,
    K, D and current values: 4 + 3 * 8 bytes a nonzero), the smoothed-aggregation
    hierarchy (coarse operators ~0.45 nnz and prolongators ~0.5 nnz at 12 bytes,
    block diagonal inverses) and temporaries of the setup, and ~40 vectors of n
    doubles (projection basis and K times it, CG, near-null space, right-hand
    sides), CSR copies of the coarse levels and their R D P.  Calibrated against
    ru_maxrss of Example 1: 2.52 GB measured at 1.0e6 unknowns, 1.16 GB at
    4.1e5 (docs/results/scale/scale.md).
    """
    per_nnz = 110.0
    return per_nnz * nnz + 40 * 8 * n + 8 * blocksize * n


#: resident memory of a Python process with numpy, scipy, NGSolve and pyamg loaded (measured: 0.17-0.18 GB)
PROCESS_BASELINE = 200_000_000
#: factorisations the full mode keeps: one per rho value, and SADMM changed rho 3-6 times in the runs measured
CACHED_FACTORS = 4


def memory_need(scene, mode: str) -> int:
    """Estimated peak bytes of a contact run of the scene in a mode (0 if the geometry is not a rectangle).

    The process baseline (Python and the libraries) plus: ``"iterative"`` the
    iterative estimate; ``"full"`` the system and CACHED_FACTORS sparse
    factorisations (one per rho value met); ``"condensed"`` the system, one LU
    (L and U: twice a Cholesky factor), the copy of U that S is read from,
    and the dense n_c x n_c matrices (about 5 n_c^2 doubles).  For Example 1
    at 4.1e5 unknowns the runs peaked at 0.96 (iterative), 1.54 (condensed,
    METIS-ordered then) and 2.92 GB (full); the condensed set-up with
    SuperLU's minimum degree ordering peaked at 4.1 GB at 6.4e5 unknowns,
    which this estimate gives.
    """
    if scene.geometry is not None:
        return 0
    area, perim = rectangle_measure(scene)
    if mode == "iterative":
        return PROCESS_BASELINE + estimate_memory(area, perim, scene.h, scene.order, scene.mesh_kind, solver="iterative")
    if mode not in ("full", "condensed"):
        raise ValueError(f"mode = {mode!r}; accepted: full, condensed, iterative")
    direct = estimate_memory(area, perim, scene.h, scene.order, scene.mesh_kind)
    vertices = (1.0 if scene.mesh_kind == "structured" else 1.2) * area / scene.h**2 + perim / scene.h
    n = 2 * scene.order**2 * vertices
    system = 3 * 12 * (14 if scene.order == 1 else 26) * n
    factor = direct - system
    if mode == "full":
        return int(PROCESS_BASELINE + system + CACHED_FACTORS * factor)
    n_c = scene.order * (scene.L if scene.contact in ("bottom", "top") else scene.H) / scene.h
    return int(PROCESS_BASELINE + system + 3 * factor + 5 * 8 * n_c**2)


class InsufficientMemory(ValueError):
    """A scene or a mode refused because the estimated memory exceeds what the machine has available now."""


def check_memory(scene, mode: str) -> None:
    """Raise InsufficientMemory (a ValueError) with the estimate if a run in ``mode`` would not fit in the
    available memory."""
    need, have = memory_need(scene, mode), available_memory()
    if need > have:
        other = "" if mode == "iterative" else \
            f"; mode 'iterative' needs about {memory_need(scene, 'iterative') / 2**30:.3g} GiB"
        raise InsufficientMemory(f"mode = {mode!r} at h = {scene.h:g} needs about {need / 2**30:.3g} GiB, only "
                         f"{have / 2**30:.3g} GiB available{other}; choose a larger h or another mode")


def rectangle_measure(scene) -> tuple[float, float]:
    """Area and perimeter of the meshed rectangle of a 2D Scene (the structured mesh rounds L/h and H/h)."""
    if scene.mesh_kind == "structured":
        nx, ny = grid_counts(scene.L, scene.H, scene.h)
        return nx * ny * scene.h**2, 2 * (nx + ny) * scene.h
    return scene.L * scene.H, 2 * (scene.L + scene.H)


# ---------------------------------------------------------------- 3D
#: nonzeros per row of the 3D stiffness in the interior of the Kuhn mesh: P1 (a vertex has 14 neighbours,
#: 3 x 15) and P2 (measured on the unit cube: 77.4, 81.6, 83.1 at 8, 16, 24 cubes a side, tending to ~85)
NNZ_ROW_3D = {1: 45, 2: 85}


def dofs3d(nx: int, ny: int, nz: int, order: int = 1) -> float:
    """Dofs (clamped ones included) of VectorH1 of ``order`` on the Kuhn mesh of nx x ny x nz cubes: 3 per vertex,
    and with P2 3 per edge (the cubes' edges, one diagonal per square face, one per cube)."""
    vertices = (nx + 1) * (ny + 1) * (nz + 1)
    if order == 1:
        return 3.0 * vertices
    edges = (nx * (ny + 1) * (nz + 1) + (nx + 1) * ny * (nz + 1) + (nx + 1) * (ny + 1) * nz
             + nx * ny * (nz + 1) + nx * (ny + 1) * nz + (nx + 1) * ny * nz + nx * ny * nz)
    return 3.0 * (vertices + edges)


#: resident memory of a 3D run's process before its arrays: the 2D baseline and NGSolve's meshes, the compiled
#: kernels of the 3D block V-cycle and assembly (measured: 0.31 GB peak for the whole run at 5.8e3 unknowns)
PROCESS_BASELINE_3D = 300_000_000


#: bytes a 3D iterative run holds per stored nonzero of K (P1: 45 a row, so about 3,960 bytes per unknown);
#: fitted on P1 runs, taken the same per nonzero for P2 (not measured)
ITERATIVE_BYTES_PER_NNZ_3D = 88.0


def estimate_memory3d(nx: int, ny: int, nz: int, solver: str = "direct", order: int = 1) -> int:
    """Rough bytes of a 3D contact run on nx x ny x nz cubes, P1 or P2 (``order``).

    n = :func:`dofs3d` dofs, NNZ_ROW_3D nonzeros per row, 12 bytes each.  With
    ``solver="iterative"``: ITERATIVE_BYTES_PER_NNZ_3D bytes per stored nonzero of K, the whole run's
    arrays (K once: the compiled assembly frees its element blocks before the AMG set-up, where the peak
    is; the hierarchy, CG's product and V-cycle layouts, the projection basis).  Fitted to the peaks of
    ``admmkit bench contact3d --growth-only`` (docs/results/scale/contact3d_growth.md) and of the target
    command (``admmkit solve contact --scene block3d --mode iterative``): with the process baseline
    (:func:`memory_need3d`) 1.54 GB at 3.1e5 unknowns (measured 1.36 GB in the bench, 1.37 GB from the
    command) and 4.41 GB at 1.04e6 (measured 3.95 and 4.24 GB).  The model of 2D's AMG-CG
    (:func:`iterative_solver_bytes`) gave 6.4 GB there, 50 % above.  Otherwise three copies and a
    sparse Cholesky factor of ~ 20 n^(4/3) nonzeros for P1 (CHOLMOD, nested
    dissection: 11.8, 13.5 and 14.4 n^(4/3) measured at 5.8e3, 1.8e4 and 4.2e4
    unknowns; SuperLU's MMD ordering filled 44, 30 and 70 n^(4/3), so without
    CHOLMOD this is an underestimate).  P2's factor is taken denser in
    proportion to its rows (85/45), not measured.
    """
    n = dofs3d(nx, ny, nz, order)
    nnz_row = NNZ_ROW_3D[order]
    if solver == "iterative":
        return int(ITERATIVE_BYTES_PER_NNZ_3D * nnz_row * n)
    system = 3 * 12 * nnz_row * n
    return int(system + 12 * 20.0 * (nnz_row / NNZ_ROW_3D[1]) * n ** (4 / 3))


def memory_need3d(scene, mode: str) -> int:
    """Estimated peak bytes of a run of the scene in a contact mode (as :func:`memory_need` in 2D:
    the full mode keeps CACHED_FACTORS factorisations, the condensed one an LU and 5 n_c^2 doubles), P1 or P2."""
    nx, ny, nz = scene.counts
    order = getattr(scene, "order", 1)
    if mode == "iterative":
        return PROCESS_BASELINE_3D + estimate_memory3d(nx, ny, nz, "iterative", order)
    if mode not in ("full", "condensed"):
        raise ValueError(f"mode = {mode!r}; accepted: full, condensed, iterative")
    n = dofs3d(nx, ny, nz, order)
    system = 3 * 12 * NNZ_ROW_3D[order] * n
    factor = estimate_memory3d(nx, ny, nz, order=order) - system
    if mode == "full":
        return int(PROCESS_BASELINE + system + CACHED_FACTORS * factor)
    n_c = (order * nx + 1) * (order * ny + 1)          # the contact face's vertices, with P2 also its midpoints
    return int(PROCESS_BASELINE + system + 2 * factor + 5 * 8 * n_c ** 2)
