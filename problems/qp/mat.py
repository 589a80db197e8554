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
    P, q, A, l, u = (field(path, data, name) for name in FIELDS)
    l = np.asarray(l, dtype=float).ravel()
    u = np.asarray(u, dtype=float).ravel()
    l[l <= -INFINITY_CUTOFF] = -np.inf
    u[u >= INFINITY_CUTOFF] = np.inf
    r_value = np.asarray(field(path, data, "r") if "r" in data else 0.0).ravel()
    if r_value.size > 1:
        raise ValueError(f"{path}: r must be one number, got {r_value.size} values")
    r = r_value[0] if r_value.size else 0.0        # an empty r (as some files store 0) is 0; the QP checks r
    try:
        return QP(sp.csc_matrix(P), np.ravel(q), sp.csc_matrix(A), l, u, r, name=path.stem, **qp_options)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{path}: {err}") from None


def field(path: Path, data: dict, name: str):
    """The field ``name`` of the MAT file ``path`` read into ``data``: a sparse matrix or an array of numbers as
    stored; a ValueError naming the file and the field when it holds text, a cell array or a struct."""
    value = data[name]
    if sp.issparse(value):
        return value
    value = np.asarray(value)
    kind = value.dtype.kind
    if kind in "biufc":                               # complex: the QP's own check names it ("must be real")
        return value
    if kind in "US":
        what = f"text {str(value.ravel()[0])[:40]!r}" if value.size else "text"
    elif value.dtype.names:
        what = f"a struct (fields {', '.join(value.dtype.names)})"
    elif kind == "O":
        what = f"a cell array of shape {value.shape}"
    else:
        what = f"data of type {value.dtype}"
    raise ValueError(f"{path}: the field {name} holds {what}, not {'a number' if name == 'r' else 'numbers'}")


def read_matrices(path: str | Path):
    """(P, A) of a MAT file as sparse matrices, read without the rest (for sizes and checks before a solve).

    An unreadable file (not MAT content, a truncated one, P or A missing) raises
    ValueError naming the file, so that a study lists it as skipped and goes on.
    """
    path = Path(path)
    try:
        data = scipy.io.loadmat(str(path), variable_names=["P", "A"])
    except Exception as err:  # scipy raises several types for non-MAT content
        raise ValueError(f"{path.name} is not a readable MAT file: {err}") from None
    missing = [name for name in ("P", "A") if name not in data]
    if missing:
        raise ValueError(f"{path.name} is not a readable MAT file: no field {', '.join(map(repr, missing))}")
    return sp.csc_matrix(field(path, data, "P")), sp.csc_matrix(field(path, data, "A"))


def list_problems(folder: str | Path) -> list[Path]:
    """The MAT files in ``folder``, sorted by name."""
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"QP folder not found: {folder}")
    return sorted(folder.glob("*.mat"))
