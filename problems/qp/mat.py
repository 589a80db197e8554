"""Loader for QPs stored as MAT files (P, q, r, A, l, u), e.g. the Maros-Meszaros set.

The files of the osqp_benchmarks / qpbenchmark conversion store infinite bounds
as +-1e20, some of them rounded to 9.999999999999998e19 (1036 bounds in 13
problems, e.g. QPILOTNO, QSIERRA, POWELL20); every bound within a relative
1e-9 of 1e20 is read as +-inf.  The data stays where it is: pass the folder.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.io
import scipy.sparse as sp

from .problem import QP

INFINITY = 1e20
#: bounds at least this large in magnitude are infinite (1e20 and its rounded forms)
INFINITY_CUTOFF = INFINITY * (1 - 1e-9)
FIELDS = ("P", "q", "A", "l", "u")


def load_mat(path: str | Path, **qp_options) -> QP:
    """Read one MAT file into a :class:`QP` (``qp_options`` go to the constructor)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"QP file not found: {path}")
    try:
        data = scipy.io.loadmat(str(path))
    except Exception as err:  # scipy raises several types for non-MAT content
        raise ValueError(f"{path} is not a readable MAT file: {err}") from None
    missing = [f for f in FIELDS if f not in data]
    if missing:
        raise ValueError(f"{path} lacks the field(s) {', '.join(missing)}; a QP file needs P, q, A, l, u (and r)")
    l = np.asarray(data["l"], dtype=float).ravel()
    u = np.asarray(data["u"], dtype=float).ravel()
    l[l <= -INFINITY_CUTOFF] = -np.inf
    u[u >= INFINITY_CUTOFF] = np.inf
    r_value = np.asarray(data.get("r", 0.0)).ravel()
    if r_value.size > 1:
        raise ValueError(f"{path}: r must be one number, got {r_value.size} values")
    r = float(r_value[0]) if r_value.size else 0.0        # an empty r (as some files store 0) is 0
    try:
        return QP(sp.csc_matrix(data["P"]), np.ravel(data["q"]), sp.csc_matrix(data["A"]), l, u, r,
                  name=path.stem, **qp_options)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{path}: {err}") from None


def read_matrices(path: str | Path):
    """(P, A) of a MAT file as sparse matrices, read without the rest (for sizes and checks before a solve).

    An unreadable file (not MAT content, a truncated one, P or A missing) raises
    ValueError naming the file, so that a study lists it as skipped and goes on.
    """
    path = Path(path)
    try:
        data = scipy.io.loadmat(str(path), variable_names=["P", "A"])
        return sp.csc_matrix(data["P"]), sp.csc_matrix(data["A"])
    except Exception as err:  # scipy raises several types for non-MAT content; KeyError for a missing field
        what = f"no field {err}" if isinstance(err, KeyError) else str(err)
        raise ValueError(f"{path.name} is not a readable MAT file: {what}") from None


def list_problems(folder: str | Path) -> list[Path]:
    """The MAT files in ``folder``, sorted by name."""
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"QP folder not found: {folder}")
    return sorted(folder.glob("*.mat"))
