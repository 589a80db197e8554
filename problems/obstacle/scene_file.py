"""Obstacle scenes by name or from a TOML file (docs/obstacle.md, "Your own obstacle"), as the contact
plug-in reads its scenes (problems/contact/model/scene_file.py).

A file's keys are the fields of :class:`~admmkit.problems.obstacle.scene.Scene`, every one optional
(defaults: the Scene's): ``name``, ``box = [x0, x1, y0, y1]``, ``h``, ``f``, ``psi``, ``u_D``, ``exact``
(numbers or expression strings in x and y, :mod:`.fields`) and ``side``.  They may stand at the top level
or inside one ``[scene]`` table.
"""
from __future__ import annotations

from pathlib import Path

from .fields import field
from .scene import SCENES, Scene
from admmkit.problems.scene_toml import scene_table

#: the scenes shipped as files: problems/obstacle/scenes/NAME.toml, read by their bare NAME
SCENES_DIR = Path(__file__).resolve().parent / "scenes"

_EXPRESSION = ((int, float, str), "a number or an expression in x, y")
TOML_KEYS = {  # key: (accepted types, description)
    "name": ((str,), "a string"),
    "box": ((list,), "four numbers [x0, x1, y0, y1]"),
    "h": ((int, float), "a number"),
    "f": _EXPRESSION, "psi": _EXPRESSION, "u_D": _EXPRESSION, "exact": _EXPRESSION,
    "side": ((str,), "'lower' or 'upper'"),
}


def scene_files() -> dict[str, Path]:
    """The shipped scene files by name (problems/obstacle/scenes/*.toml)."""
    return {path.stem: path for path in sorted(SCENES_DIR.glob("*.toml"))}


def known_scenes() -> dict[str, str]:
    """Every scene ``--scene`` knows by name, with where it comes from: the built-in ones (scene.py) and the
    shipped files."""
    built_in = {name: "built in: " + (make.__doc__ or "").strip().splitlines()[0] for name, make in SCENES.items()}
    return built_in | {name: f"file: {path}" for name, path in scene_files().items() if name not in SCENES}


def load_scene(name_or_path, **changes) -> Scene:
    """The scene of a built-in name (``"radial"``, ``"pyramid"``), a shipped file's name (``"ridge"``) or a
    path of a TOML file; ``changes`` override its fields (e.g. ``h=1/64``).

    Every problem raises ValueError: an unknown name, a missing file (``no such file``, naming the path), a
    directory, text that is not UTF-8 or not TOML, an unknown key, a value of the wrong type, a bad
    expression or a field out of range (naming the file and the key).
    """
    text = str(name_or_path)
    if text in SCENES:
        return SCENES[text](**changes)
    path = scene_files().get(text) or Path(text)
    if not path.exists():
        if path.suffix or len(path.parts) > 1:
            raise ValueError(f"{path}: no such file")
        import difflib
        close = difflib.get_close_matches(text, list(known_scenes()), n=1)
        hint = f" (did you mean {close[0]}?)" if close else ""
        raise ValueError(f"scene {text!r} is unknown and there is no such file{hint}; known scenes: "
                         f"{', '.join(known_scenes())} (or the path of a TOML scene file)")
    if not path.is_file():
        raise ValueError(f"{path}: not a file (a TOML scene file is needed)")
    try:
        return Scene(**(read_scene_file(path) | changes))
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from None


def read_scene_file(path) -> dict:
    """The keys of a TOML scene file, checked by name and type (ValueError naming the file and the key); the
    expressions read into callables (a bad one names its key), the values left to :class:`Scene` to check."""
    path = Path(path)
    data = scene_table(path)                   # the [scene] table, or one error naming the file
    for key, value in data.items():
        if key not in TOML_KEYS:
            raise ValueError(f"{path}: unknown key {key!r}; known keys: {', '.join(TOML_KEYS)}")
        types, what = TOML_KEYS[key]
        if isinstance(value, bool) or not isinstance(value, types):
            raise ValueError(f"{path}: key {key!r} must be {what}, got {value!r}")
    if "box" in data:
        box = data["box"]
        if len(box) != 4 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in box):
            raise ValueError(f"{path}: key 'box' must be four numbers [x0, x1, y0, y1], got {box!r}")
        data["box"] = tuple(float(v) for v in box)
    for key in ("f", "psi", "u_D", "exact"):
        if isinstance(data.get(key), str):
            try:
                data[key] = field(data[key])
            except ValueError as err:
                raise ValueError(f"{path}: key {key!r}: {err}") from None
    return data


__all__ = ["load_scene", "read_scene_file", "known_scenes", "scene_files", "SCENES_DIR", "TOML_KEYS"]
