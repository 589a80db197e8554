"""What is installed, read from the packages' ``dist-info`` folders without :mod:`importlib.metadata`.

A command line that names a built-in command (``admmkit solve contact ...``)
needs admmkit's own sub-commands only, a rule named by the user is looked up
among admmkit's own rules first (``admmkit.policy``), and the contact
operator cache keys its entries on the versions of NGSolve and netgen.
``importlib.metadata`` answers all three, but importing it imports the e-mail
parser (for the packages' ``METADATA``): 80-100 ms of a fresh process at load
5, against 1-6 ms for listing the folders of ``sys.path`` and reading one
small file (issue #49: a whole ``solve contact`` process within 0.6 s).

A distribution is found as ``importlib.metadata`` finds it: the first
``NAME-*.dist-info`` along ``sys.path``, NAME compared in its normalised
form (lower case, runs of ``-``, ``_`` and ``.`` as one ``_``).  Without one
(a source tree that is not installed) the callers fall back to
``importlib.metadata``.
"""
from __future__ import annotations

import functools
import importlib
import os
import re
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


def _normalised(name: str) -> str:
    """A distribution's name as dist-info folders spell it: lower case, runs of -, _ and . as one _."""
    return re.sub(r"[-_.]+", "_", name).lower()


def dist_info(name: str) -> str | None:
    """The folder ``NAME-VERSION.dist-info`` of distribution ``name`` first found along ``sys.path`` (None: not
    installed)."""
    want = _normalised(name)
    for folder in sys.path:
        try:
            found = _dist_infos(folder or ".", os.stat(folder or ".").st_mtime_ns).get(want)
        except OSError:
            continue
        if found:
            return os.path.join(folder or ".", found)
    return None


@functools.lru_cache(maxsize=64)
def _dist_infos(folder: str, mtime_ns: int) -> dict[str, str]:
    """{normalised name: the first of its dist-info folders, sorted} in ``folder`` as it was at ``mtime_ns`` (listed
    once per process and change of the folder, as importlib.metadata does: a site-packages of many packages is
    listed once for the several versions a process asks)."""
    found: dict[str, str] = {}
    for entry in sorted(os.listdir(folder)):
        if entry.endswith(".dist-info"):
            found.setdefault(_normalised(entry[:-len(".dist-info")].rpartition("-")[0]), entry)
    return found


def _read(name: str, file: str) -> list[str] | None:
    """The lines of ``file`` in the dist-info folder of ``name`` (None: no folder or no file)."""
    folder = dist_info(name)
    if folder is None:
        return None
    try:
        with open(os.path.join(folder, file), encoding="utf-8") as handle:
            return handle.read().splitlines()
    except OSError:
        return None


def version(name: str) -> str | None:
    """The installed version of distribution ``name`` (``Version:`` of its METADATA), or None."""
    for line in _read(name, "METADATA") or ():
        if not line.strip():                     # the headers end at the first blank line
            break
        if line.startswith("Version:"):
            return line.partition(":")[2].strip()
    return None


def own_entry_points(group: str, name: str = "admmkit") -> dict[str, EntryPoint] | None:
    """{name: EntryPoint} of ``group`` in the installed distribution ``name`` (None: no ``dist-info`` or no
    ``entry_points.txt`` there)."""
    lines = _read(name, "entry_points.txt")
    if lines is None:
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
