"""The table of a TOML scene file, read once for every plug-in (contact and obstacle scenes).

A scene file holds its keys at the top level or inside one ``[scene]`` table.
:func:`scene_table` returns that table, or raises one ``ValueError`` naming
the file: not UTF-8, malformed TOML, a ``scene`` key that is no table, or
keys outside the ``[scene]`` table.  Each plug-in then checks its own keys.
"""
from __future__ import annotations

import tomllib
from pathlib import Path


def scene_table(path: str | Path) -> dict:
    """The keys of the scene file at ``path`` (its ``[scene]`` table where it has one)."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_bytes().decode("utf-8"))
    except UnicodeDecodeError as err:
        raise ValueError(f"{path}: not a TOML text file (not UTF-8: {err.reason} at byte {err.start})") from None
    except tomllib.TOMLDecodeError as err:
        raise ValueError(f"{path}: malformed TOML: {err}") from None
    if "scene" in data:
        if not isinstance(data["scene"], dict):
            raise ValueError(f"{path}: key 'scene' must be a table [scene] holding the scene's keys, "
                             f"got {data['scene']!r}")
        if len(data) > 1:
            raise ValueError(f"{path}: keys {', '.join(sorted(set(data) - {'scene'}))} outside the [scene] table")
        data = data["scene"]
    return data
