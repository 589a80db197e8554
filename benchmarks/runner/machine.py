"""The machine and library versions recorded beside every benchmark figure, and the one timer of the studies."""
from __future__ import annotations

import datetime
import os
import platform
import statistics
import subprocess
import time
from pathlib import Path
from typing import Any, Callable, NamedTuple

LIBRARIES = ("numpy", "scipy", "ngsolve", "pyamg", "cvxpy", "clarabel", "osqp", "matplotlib")


#: what the sweeps' workers do to BLAS (said when ``pinned_blas``)
PINNED_BLAS = "1 per worker process (OMP/OPENBLAS_NUM_THREADS=1, threadpoolctl)"


def machine_info(*, pinned_blas: bool = False, libraries: tuple[str, ...] = LIBRARIES) -> dict:
    """Date, nproc, CPU model, memory, platform, git commit, library versions, sparse backends, load.

    The one description of the machine every study writes beside its figures.
    ``pinned_blas``: the study's runs pin BLAS to one thread per worker (the
    sweeps), said as ``BLAS threads``; ``libraries``: the versions reported
    (by distribution name: ``scikit-sparse``, not ``sksparse``).
    """
    cpu = platform.processor() or "?"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    info = {"date": datetime.datetime.now().strftime("%Y-%m-%d %H:%M"), "nproc": os.cpu_count(), "cpu": cpu,
            "platform": platform.platform(), "python": platform.python_version()}
    try:
        with open("/proc/meminfo") as fh:
            info["memory"] = f"{int(fh.readline().split()[1]) / 2**20:.1f} GiB"
    except (OSError, ValueError, IndexError):
        pass
    for library in libraries:
        info[library] = version_of(library)
    try:
        from admmkit import __version__
        from admmkit.linalg.linsolve import available_backends
        info["admmkit"] = __version__
        info["sparse backends (auto picks the first)"] = ", ".join(available_backends())
    except Exception:
        pass
    try:
        root = Path(__file__).resolve().parents[1]
        # only a checkout of admmkit has a meaningful commit: an installed copy in site-packages may sit
        # inside some other repository (pyenv's), whose commit would be reported instead
        top = subprocess.run(["git", "-C", str(root), "rev-parse", "--show-toplevel"], capture_output=True,
                             text=True, timeout=10).stdout.strip()
        commit = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, timeout=10).stdout.strip()
        if commit and top and Path(top).resolve() == root:
            info["git commit (when these files were written)"] = commit
    except Exception:
        pass
    try:
        info["load average (1 min) at the end"] = f"{os.getloadavg()[0]:.2f}"
    except OSError:
        pass
    if pinned_blas:
        info["BLAS threads"] = PINNED_BLAS
    return info


def version_of(library: str) -> str:
    """The installed version of ``library`` (its module's ``__version__``, else its distribution's), or
    ``not installed``."""
    try:
        return __import__(library).__version__
    except Exception:
        pass
    try:
        from importlib.metadata import version
        return version(library)
    except Exception:
        return "not installed"


class Timing(NamedTuple):
    """Median wall and CPU seconds over the repeats, the CPU seconds of each repeat, the last output."""

    wall: float
    cpu: float
    cpus: list[float]
    out: Any


def median_time(fn: Callable[[], Any], repeats: int, long_run: float = float("inf")) -> Timing:
    """Time ``fn()`` ``repeats`` times (fewer if the first call takes longer than ``long_run`` seconds).

    CPU seconds are those of this process (``time.process_time``): on a shared
    machine they are less distorted than wall seconds, which are kept beside them.
    """
    walls, cpus, out = [], [], None
    for _ in range(max(1, repeats)):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
        if walls[0] > long_run:
            break
    return Timing(statistics.median(walls), statistics.median(cpus), cpus, out)
