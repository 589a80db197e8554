"""The operator cache: a scene's assembled discrete problem kept on disk, like numba's kernel cache.

A fresh ``admmkit solve contact`` process spends most of its time importing
NGSolve (0.4-0.8 s on a quiet machine) to assemble a problem whose solve takes
milliseconds (issue #49).  The first process that assembles a 2D scene from a
scene file stores what the solve and the printed output need; a later process
with the same key reads it back and imports no NGSolve at all:

- K, f, B, mc, g, xc, the normals, the free dofs, with friction T, the
  tangents; the free dofs' coordinates (the condensed set-up's nested
  dissection); the mesh's dimension, cell, vertex and dof counts;
- not the mesh: an output that needs it (``--plot``, ``--vtk``, ``--json``,
  ``--balance``, ``--mode iterative``) rebuilds mesh and space with NGSolve
  when it asks for them (:class:`StoredOperators`), and checks that they
  match the stored ones (vertices, dofs and free dofs): a mismatch is an
  error, never a silent wrong map.

The arrays are the assembly's own, bit for bit, so the iterates are those of a
process that assembled (tests/problems/test_contact_cache.py compares u and
lambda bitwise).

**Key.** A SHA-256 of: the scene file's bytes, the scene's fields after the
command line's changes (``--h``, ``--fe-order``, the friction options), the
versions of admmkit, NGSolve and netgen, the cache's format, and the source
of the modules that build the operators (an edit of the assembly makes a new
key without a version change).

**Files.** ``<cache dir>/contact/<key>.npz``, the cache dir being
``$ADMMKIT_CACHE_DIR``, else ``$XDG_CACHE_HOME/admmkit``, else
``~/.cache/admmkit``.  An entry is written whole or not at all (a temporary
file renamed into place, :func:`admmkit.io.atomic_path`), and carries its key
and a SHA-256 of its arrays: an entry that is unreadable, truncated, of
another key or whose arrays do not hash to the stored digest is reported on
stderr, assembled again and overwritten, never used.  A cache folder that
cannot be written costs nothing but the note.

**Bypass.** ``--no-cache`` on the command line, or ``ADMMKIT_NO_CACHE=1`` in
the environment: the scene is assembled and nothing is read or written.
"""
from __future__ import annotations

import hashlib
import json
import os
import sys
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from admmkit.problems.contact.model.operators import ContactOperators

#: bump when the stored arrays or their meaning change
FORMAT = 1
#: the modules whose source decides the operators
SOURCES = tuple(f"admmkit.problems.contact.{name}" for name in (
    "model.assembly", "model.operators", "model.mesh", "model.fastpaths", "model.scene", "model.scene_file",
    "model.operator_cache", "solvers.friction", "solvers.dissection", "solvers.schur")) + (
    "admmkit.problems.expressions", "admmkit.problems.fe", "admmkit.linalg.submatrix")
#: the sparse matrices stored as their CSR arrays, and the dense arrays (None fields are left out)
MATRICES = ("K", "B", "T")
ARRAYS = ("f", "mc", "g", "xc", "normals", "free", "tangents", "coordinates", "vertices", "condensed_order")
#: the environment variables of the cache
CACHE_DIR_ENV, NO_CACHE_ENV = "ADMMKIT_CACHE_DIR", "ADMMKIT_NO_CACHE"


class CacheMismatch(RuntimeError):
    """The mesh rebuilt for an output differs from the one the cached operators were assembled on."""


def cache_disabled() -> bool:
    """True when ``ADMMKIT_NO_CACHE`` is set to anything but ``""``, ``0``, ``no``, ``false`` or ``off``."""
    return os.environ.get(NO_CACHE_ENV, "").strip().lower() not in ("", "0", "no", "false", "off")


def cache_dir() -> Path:
    """The folder of the operator cache: ``$ADMMKIT_CACHE_DIR``, ``$XDG_CACHE_HOME/admmkit`` or ``~/.cache/admmkit``,
    with ``contact`` below it."""
    root = os.environ.get(CACHE_DIR_ENV) or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"), "admmkit")
    return Path(root) / "contact"


def _version(dist: str) -> str:
    """The installed version of distribution ``dist`` (without importing it, nor importlib.metadata:
    :mod:`admmkit.installed`), or "absent"."""
    from admmkit.installed import version
    return version(dist) or "absent"


def cacheable(scene) -> bool:
    """Whether a scene's operators may be cached: a 2D Scene without a netgen geometry object, every field a
    number, a string, an expression with its text, or a tuple or table of them (a Python callable has no text to
    key on, and a 3D scene is assembled by another module)."""
    from admmkit.problems.contact.model.scene import Scene
    if type(scene) is not Scene or scene.geometry is not None:
        return False
    try:
        _scene_text(scene)
    except TypeError:
        return False
    return True


def _scene_text(scene) -> str:
    """The scene's fields as canonical JSON (expressions by their text); TypeError for a value without a text."""
    import dataclasses

    def plain(value):
        if value is None or isinstance(value, (bool, int, float, str)):
            return value
        if isinstance(value, (tuple, list)):
            return [plain(v) for v in value]
        if isinstance(value, dict):
            return {str(k): plain(v) for k, v in sorted(value.items())}
        text = getattr(value, "expression", None)      # admmkit.problems.expressions: an expression in x, y
        if isinstance(text, str):
            return {"expression": text}
        raise TypeError(f"{type(value).__name__} has no text to key a cache entry on")
    fields = {f.name: plain(getattr(scene, f.name)) for f in dataclasses.fields(scene) if f.name != "geometry"}
    return json.dumps(fields, sort_keys=True)


def cache_key(scene, source: bytes) -> str:
    """The hex SHA-256 that names the entry of ``scene`` read from a file with the bytes ``source``."""
    import importlib.util

    import admmkit
    digest = hashlib.sha256()
    for part in (f"format {FORMAT}", f"admmkit {admmkit.__version__}", f"ngsolve {_version('ngsolve')}",
                 f"netgen {_version('netgen-mesher')}", _scene_text(scene)):
        digest.update(part.encode() + b"\0")
    digest.update(source + b"\0")
    for name in SOURCES:                                # found without importing them (NGSolve stays out)
        origin = importlib.util.find_spec(name).origin
        digest.update(Path(origin).read_bytes() + b"\0")
    return digest.hexdigest()


def _arrays_digest(arrays: dict[str, np.ndarray]) -> str:
    """SHA-256 of the arrays (names, dtypes, shapes and bytes, in sorted name order)."""
    digest = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        digest.update(f"{name} {a.dtype.str} {a.shape}".encode())
        digest.update(a.tobytes())
    return digest.hexdigest()


def _to_arrays(ops: ContactOperators) -> dict[str, np.ndarray]:
    """The arrays of an entry: the operators, the dofs' coordinates and the mesh's counts and vertices."""
    out: dict[str, np.ndarray] = {}
    for name in MATRICES:
        M = getattr(ops, name)
        if M is None:
            continue
        M = sp.csr_matrix(M)
        out |= {f"{name}.data": M.data, f"{name}.indices": M.indices, f"{name}.indptr": M.indptr,
                f"{name}.shape": np.array(M.shape, dtype=np.int64)}
    coordinates = ops.dof_coordinates()
    mesh = ops.mesh
    values = {"f": ops.f, "mc": ops.mc, "g": ops.g, "xc": ops.xc, "normals": ops.normals, "free": ops.free,
              "tangents": ops.tangents, "coordinates": coordinates,
              "condensed_order": getattr(ops, "condensed_order", None),
              "vertices": np.asarray(mesh.ngmesh.Coordinates(), dtype=float)}
    out |= {name: np.asarray(v) for name, v in values.items() if v is not None}
    out["counts"] = np.array([mesh.dim, mesh.ne, mesh.nv, ops.fes.ndof], dtype=np.int64)
    return out


def store(path: Path, key: str, ops: ContactOperators) -> Path:
    """Write the entry of ``ops`` under ``key`` to ``path``, whole or not at all."""
    from admmkit.io import atomic_path
    arrays = _to_arrays(ops)
    meta = np.frombuffer(json.dumps({"key": key, "format": FORMAT, "digest": _arrays_digest(arrays)}).encode(),
                         dtype=np.uint8)
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, meta=meta, **arrays)
    return path


def load(path: Path, key: str, scene) -> "StoredOperators":
    """The operators of the entry at ``path``; ValueError when it is not a whole, intact entry of ``key``."""
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except Exception as err:         # a truncated or garbled zip, a bad CRC, a member that is no array
        raise ValueError(f"unreadable ({type(err).__name__}: {err})") from None
    try:
        meta = json.loads(arrays.pop("meta").tobytes().decode())
    except Exception:
        raise ValueError("no readable key") from None
    if meta.get("format") != FORMAT or meta.get("key") != key:
        raise ValueError("written for another key or format")
    if meta.get("digest") != _arrays_digest(arrays):
        raise ValueError("its arrays do not match their digest")
    return StoredOperators(arrays, scene)


class StoredOperators(ContactOperators):
    """Operators read from the cache: the arrays of :class:`~admmkit.problems.contact.ContactOperators`, the
    mesh and the space rebuilt with NGSolve only when something asks for them (and checked against the stored
    counts and vertices)."""

    def __init__(self, arrays: dict[str, np.ndarray], scene):
        from admmkit.problems.contact.solvers.friction import friction_of

        def matrix(name):
            if f"{name}.data" not in arrays:
                return None
            return sp.csr_matrix((arrays[f"{name}.data"], arrays[f"{name}.indices"], arrays[f"{name}.indptr"]),
                                 shape=tuple(int(n) for n in arrays[f"{name}.shape"]))
        self.K, self.B, self.T = matrix("K"), matrix("B"), matrix("T")
        for name in ("f", "mc", "g", "xc", "normals", "free"):
            setattr(self, name, arrays[name])
        self.tangents = arrays.get("tangents")
        self.condensed_order = arrays.get("condensed_order")    # the condensed set-up's order (None: not stored)
        self.scene = scene
        self.friction = friction_of(scene, self.xc)
        self._coordinates = arrays.get("coordinates")
        self._vertices = arrays["vertices"]
        self._dim, self._n_cells, self._nv, self._ndof = (int(n) for n in arrays["counts"])
        self._space = None
        n, m = self.K.shape[0], self.B.shape[0]
        if (self.K.shape != (n, n) or self.B.shape[1] != n or self.f.shape != (n,) or self.free.shape != (n,)
                or self.mc.shape != (m,) or self.g.shape != (m,) or self.xc.shape[0] != m):
            raise ValueError("its arrays do not fit together")

    def __repr__(self) -> str:
        return (f"StoredOperators({getattr(self.scene, 'name', '') or 'scene'}, n_free={self.n_free}, "
                f"n_c={self.n_c}, from the operator cache)")

    @property
    def dim(self) -> int:
        """Dimension of the body (stored)."""
        return self._dim

    @property
    def n_cells(self) -> int:
        """Number of cells of the mesh (stored)."""
        return self._n_cells

    def dof_coordinates(self) -> np.ndarray | None:
        """The free dofs' coordinates, as stored (see ``ContactOperators.dof_coordinates``)."""
        return self._coordinates

    @property
    def mesh(self):
        """The NGSolve mesh, rebuilt from the scene on first use (NGSolve imported then)."""
        return self._rebuilt()[0]

    @property
    def fes(self):
        """The NGSolve displacement space, rebuilt on first use."""
        return self._rebuilt()[1]

    def _rebuilt(self):
        """(mesh, fes) built as :func:`~admmkit.problems.contact.model.assembly.assemble` builds them; CacheMismatch
        unless their vertices, cells, dofs and free dofs are the stored ones."""
        if self._space is None:
            from admmkit.problems.contact.model.assembly import build_mesh, displacement_space
            from admmkit.problems.contact.model.fastpaths import free_dofs
            mesh = build_mesh(self.scene)
            fes = displacement_space(self.scene, mesh, self.normals)
            vertices = np.asarray(mesh.ngmesh.Coordinates(), dtype=float)
            if (mesh.dim, mesh.ne, mesh.nv, fes.ndof) != (self._dim, self._n_cells, self._nv, self._ndof) \
                    or not np.array_equal(vertices, self._vertices) or not np.array_equal(free_dofs(fes), self.free):
                raise CacheMismatch("the mesh rebuilt from the scene differs from the one the cached operators were "
                                    "assembled on; run again with --no-cache (or ADMMKIT_NO_CACHE=1)")
            self._space = (mesh, fes)
        return self._space


def cached_operators(scene, scene_file, *, use_cache: bool = True, report=None,
                     mode: str = "auto") -> ContactOperators:
    """The operators of ``scene`` (read from ``scene_file``): from the cache when it holds a valid entry, else
    assembled (and stored when the scene is cacheable and the cache is on).

    When the solve's ``mode`` (as given to ``solve_scene``) will be the condensed one with SuperLU, the entry
    also holds the condensed set-up's order of the dofs (``condensed_order``, :func:`condensed_order`): a
    process that reads the entry back factorises in it without ordering again (the same order, so the same bits).

    ``use_cache=False`` or ``ADMMKIT_NO_CACHE=1``: assembled, nothing read or written.  ``report(text)`` receives
    the notes (default: printed to stderr): an entry rebuilt, a folder that could not be written.
    """
    report = report or (lambda text: print(f"admmkit: {text}", file=sys.stderr))
    if not use_cache or cache_disabled() or not cacheable(scene):
        return _assemble(scene)
    key = cache_key(scene, Path(scene_file).read_bytes())
    path = cache_dir() / f"{key[:40]}.npz"
    if path.exists():
        try:
            return load(path, key, scene)
        except ValueError as err:
            report(f"operator cache entry {path} {err}: assembled again and rewritten")
    ops = _assemble(scene)
    ops.condensed_order = condensed_order(ops, mode)
    try:
        store(path, key, ops)
    except OSError as err:
        report(f"operator cache: could not write {path} ({err.strerror or err}); the next run assembles again")
    return ops


def _assemble(scene) -> ContactOperators:
    """The assembly (NGSolve imported here)."""
    from admmkit.problems.contact.model.assembly import assemble
    return assemble(scene)


def condensed_order(ops: ContactOperators, mode: str = "auto") -> np.ndarray | None:
    """The order the condensed set-up factorises K in (:func:`admmkit.problems.contact.solvers.schur.contact_last`)
    when a solve in ``mode`` runs the condensed mode with SuperLU (or ``ldl``), else None (CHOLMOD orders itself)."""
    from admmkit.problems.contact.solvers.base import constraint_matrix
    from admmkit.problems.contact.solvers.problem import _coordinates, auto_mode
    from admmkit.problems.contact.solvers.schur import available_schur_backends, contact_last
    if mode not in ("auto", "condensed") or available_schur_backends()[0] == "cholmod":
        return None
    if mode == "auto" and auto_mode(ops) != "condensed":
        return None
    return contact_last(ops.K, constraint_matrix(ops), _coordinates(ops))
