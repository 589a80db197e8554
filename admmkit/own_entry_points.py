"""admmkit's own entry points, read from its installed ``entry_points.txt`` without :mod:`importlib.metadata`.

A command line that names a built-in command (``admmkit solve contact ...``)
needs admmkit's own sub-commands only, and a rule named by the user is looked
up among admmkit's own rules first (``admmkit.policy``).  ``importlib.metadata`` finds them too,
but importing it imports the e-mail parser (for the packages' ``METADATA``):
80-100 ms of a fresh process at load 5, against 1-6 ms for listing the folders
of ``sys.path`` and reading one small file (issue #49: a whole ``solve
contact`` process within 0.6 s).  The file is the one the installer wrote
from ``pyproject.toml``'s ``[project.entry-points]``, found as
``importlib.metadata`` finds a distribution: the first ``admmkit-*.dist-info``
along ``sys.path``.  Without one (a source tree that is not installed) the
host searches every package by ``importlib.metadata``.
"""
from __future__ import annotations

import importlib
import os
import sys
from typing import NamedTuple


class EntryPoint(NamedTuple):
    """``name = value`` of an entry-point group, ``value`` being ``module:attribute``."""

    name: str
    value: str

    def load(self):
        """The object the entry point names, its module imported now."""
        module, _, attribute = self.value.partition(":")
        obj = importlib.import_module(module.strip())
        for part in attribute.split("[")[0].strip().split(".") if attribute else ():
            obj = getattr(obj, part)
        return obj


def dist_info(name: str = "admmkit") -> str | None:
    """The folder ``NAME-*.dist-info`` first found along ``sys.path`` (None: not installed)."""
    for folder in sys.path:
        try:
            found = sorted(entry for entry in os.listdir(folder or ".")
                           if entry.startswith(name + "-") and entry.endswith(".dist-info"))
        except OSError:
            continue
        if found:
            return os.path.join(folder or ".", found[0])
    return None


def own_entry_points(group: str, name: str = "admmkit") -> dict[str, EntryPoint] | None:
    """{name: EntryPoint} of ``group`` in the installed distribution ``name`` (None: no ``dist-info`` or no
    ``entry_points.txt`` there)."""
    folder = dist_info(name)
    if folder is None:
        return None
    try:
        with open(os.path.join(folder, "entry_points.txt"), encoding="utf-8") as file:
            lines = file.read().splitlines()
    except OSError:
        return None
    found, section = {}, None
    for line in lines:
        line = line.strip()
        if not line or line[0] in "#;":
            continue
        if line.startswith("[") and line.endswith("]"):
            section = line[1:-1].strip()
        elif section == group and "=" in line:
            key, _, value = line.partition("=")
            found[key.strip()] = EntryPoint(key.strip(), value.strip())
    return found
