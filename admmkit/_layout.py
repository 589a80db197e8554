"""Where the subpackages of ``admmkit`` live in the repository.

The repository keeps ``policies/``, ``problems/`` and ``benchmarks/`` beside
``admmkit/``; ``setup.py`` installs them as ``admmkit.policies``,
``admmkit.problems`` and ``admmkit.benchmarks`` (setuptools' ``package_dir``),
so that the installed package owns one import name.

In a source checkout the folder ``admmkit/`` itself is imported whenever the
repository root is on ``sys.path`` (``python -m pytest``, ``python -c`` from
the root), and it shadows the installed copy.  :func:`map_source_tree` gives
that checkout the installed mapping: a meta-path finder that resolves exactly
these three names to the sibling folders.  An installed ``admmkit`` has the
subpackages inside it and is left alone.  Nothing here imports a subpackage:
the core still imports none of them.
"""
from __future__ import annotations

import importlib.abc
import importlib.util
import sys
from pathlib import Path

#: the repository folders that install as ``admmkit.<name>`` (setup.py reads this)
SUBPACKAGES = ("policies", "problems", "benchmarks")


class SiblingFinder(importlib.abc.MetaPathFinder):
    """Find ``admmkit.<name>`` in the folder ``<name>/`` beside ``admmkit/``."""

    def __init__(self, folders: dict[str, Path]):
        self.folders = folders

    def find_spec(self, fullname, path=None, target=None):
        """The spec of a mapped subpackage; None for every other name."""
        folder = self.folders.get(fullname)
        if folder is None:
            return None
        return importlib.util.spec_from_file_location(fullname, folder / "__init__.py",
                                                      submodule_search_locations=[str(folder)])

    def __repr__(self) -> str:
        return f"SiblingFinder({', '.join(f'{k} -> {v}' for k, v in self.folders.items())})"


def map_source_tree(package_dir: str) -> SiblingFinder | None:
    """Map the sibling folders of a source checkout's ``admmkit/``; None when installed.

    The folders are mapped only where the package has no subpackage of that
    name and the parent folder is the repository (its ``pyproject.toml`` and
    the sibling's ``__init__.py`` are there).
    """
    here = Path(package_dir)
    root = here.parent
    if not (root / "pyproject.toml").is_file():
        return None
    folders = {f"{here.name}.{name}": root / name for name in SUBPACKAGES
               if not (here / name).exists() and (root / name / "__init__.py").is_file()}
    if not folders:
        return None
    if any(isinstance(f, SiblingFinder) and f.folders == folders for f in sys.meta_path):
        return None
    finder = SiblingFinder(folders)
    sys.meta_path.insert(0, finder)
    return finder
