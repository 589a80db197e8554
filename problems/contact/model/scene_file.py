"""Scene files: a contact scene read from TOML (docs/scenes.md), 2D or 3D.

The keys are the fields of :class:`~admmkit.problems.contact.model.scene.Scene`
(2D) or :class:`~admmkit.problems.contact.model.scene3d.Scene3D` (``dim = 3``);
this module reads both, so neither scene module imports the other's.
"""
from __future__ import annotations

from pathlib import Path

from admmkit.problems.contact.solvers.friction import TANGENTIAL
from admmkit.problems.contact.model.scene import SCENES_DIR, Scene
from admmkit.problems.scene_toml import scene_table


TOML_KEYS = {  # key: (accepted types, description); every key is optional, defaults are Scene's (docs/scenes.md)
    "name": ((str,), "a string"),
    "L": ((int, float), "a number"), "H": ((int, float), "a number"),
    "h": ((int, float), "a number"),
    "mesh_kind": ((str,), "a string"), "order": ((int,), "an integer"),
    "E": ((int, float), "a number"), "nu": ((int, float), "a number"),
    "dirichlet": ((list, str), "a list of labels"),
    "tractions": ((dict,), "a table label = [tx, ty]"),
    "body_force": ((list,), "a pair [fx, fy]"),
    "contact": ((str,), "a label"),
    "gap": ((int, float, str), "a number or an expression in x, y"),
    "tangential": ((str,), f"one of {', '.join(TANGENTIAL)}"),
    "contact_normal": ((list,), "a pair [nx, ny]"),
    "slip_bound": ((int, float, str), "a number or an expression in x, y (tangential = 'tresca')"),
    "mu": ((int, float), "a number (tangential = 'coulomb')"),
    "obstacle_slide": ((int, float), "a number"),
}
#: the keys of a 3D scene file (``dim = 3``: a :class:`admmkit.problems.contact.model.scene3d.Scene3D`)
TOML_KEYS_3D = {
    "name": ((str,), "a string"), "dim": ((int,), "2 or 3"),
    "Lx": ((int, float), "a number"), "Ly": ((int, float), "a number"), "Lz": ((int, float), "a number"),
    "h": ((int, float), "a number"), "order": ((int,), "an integer"),
    "E": ((int, float), "a number"), "nu": ((int, float), "a number"),
    "dirichlet": ((list, str), "a list of faces"),
    "symmetry": ((list, str), "a list of faces (symmetry planes: u.n = 0)"),
    "tractions": ((dict,), "a table face = [tx, ty, tz]"),
    "contact": ((str,), "a face"),
    "gap": ((int, float, str), "a number or an expression in x, y"),
    "tangential": ((str,), f"one of {', '.join(TANGENTIAL)}"),
    "slip_bound": ((int, float, str), "a number or an expression in x, y (tangential = 'tresca')"),
    "mu": ((int, float), "a number (tangential = 'coulomb')"),
    "obstacle_slide": ((list,), "a pair [wx, wy]"),
}


def load_scene(path, **changes):
    """Read a Scene from a TOML file (keys = Scene fields, all optional; docs/scenes.md).

    A bare name such as ``"ex1"`` refers to problems/contact/scenes/ex1.toml.
    ``dim = 3`` makes it a 3D block scene (``Scene3D`` (problems/contact/model/scene3d.py),
    keys ``TOML_KEYS_3D``); otherwise a 2D :class:`Scene`.  The keys may sit at the top level or in a ``[scene]`` table.  ``changes``
    override file values (e.g. ``h=1/80``).  Every problem with the file (not
    found, not UTF-8 text, malformed TOML, an unknown key, a value of the
    wrong type or out of range) raises ValueError naming the file and the key.
    """
    path = Path(path)
    if not path.exists() and (SCENES_DIR / f"{path.name}.toml").exists():
        path = SCENES_DIR / f"{path.name}.toml"
    if not path.is_file():
        known = ", ".join(sorted(p.stem for p in SCENES_DIR.glob("*.toml")))
        raise ValueError(f"{path}: no such scene file; give the path of a TOML file or one of {known}")
    data = scene_table(path)                   # the [scene] table, or one error naming the file
    dim = data.get("dim", 2)
    if dim not in (2, 3) or isinstance(dim, bool):
        raise ValueError(f"{path}: key 'dim' must be 2 or 3, got {dim!r}")
    keys = TOML_KEYS_3D if dim == 3 else TOML_KEYS
    for key, value in data.items():
        if key not in keys and not (key == "dim" and dim == 2):
            raise ValueError(f"{path}: unknown key {key!r}; known keys: {', '.join(keys)}")
        types, what = keys.get(key, ((int,), "2 or 3"))
        if isinstance(value, bool) or not isinstance(value, types):
            raise ValueError(f"{path}: key {key!r} must be {what}, got {value!r}")
    for label, t in data.get("tractions", {}).items():
        if not (isinstance(t, list) and len(t) == dim and all(isinstance(c, (int, float, str)) for c in t)):
            what = "a pair [tx, ty]" if dim == 2 else "a triple [tx, ty, tz]"
            raise ValueError(f"{path}: key 'tractions.{label}' must be {what}, got {t!r}")
    for key in ("dirichlet", "symmetry"):
        if key in data and isinstance(data[key], list):
            data[key] = tuple(data[key])
    for key in ("contact_normal", "body_force", "obstacle_slide"):
        if key in data and isinstance(data[key], list):
            data[key] = tuple(data[key])
    data.pop("dim", None)
    try:
        if dim == 3:
            from admmkit.problems.contact.model.scene3d import Scene3D     # imported for a 3D scene only
            data["tractions"] = {k: tuple(v) for k, v in data.get("tractions", {}).items()} or Scene3D().tractions
            return Scene3D(**(data | changes))
        return Scene(**(data | changes))
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from None
