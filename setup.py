"""Packaging: one import name, ``admmkit``, for four folders.

The repository keeps the folders of the layout our users asked for side by
side (``admmkit/``, ``policies/``, ``problems/``, ``benchmarks/``); installed,
the last three are subpackages of ``admmkit`` (``admmkit.policies``, ...), so
site-packages gains one top-level name.  The mapping is written once, in
:mod:`admmkit._layout`, which also maps the folders in a source checkout.
Everything else is in ``pyproject.toml``.
"""
import importlib.util
from pathlib import Path

from setuptools import find_packages, setup

ROOT = Path(__file__).resolve().parent
_spec = importlib.util.spec_from_file_location("_layout", ROOT / "admmkit" / "_layout.py")
_layout = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_layout)

package_dir = {"admmkit": "admmkit"}
packages = ["admmkit"] + [f"admmkit.{p}" for p in find_packages("admmkit")]
for folder in _layout.SUBPACKAGES:
    package_dir[f"admmkit.{folder}"] = folder
    packages += [f"admmkit.{folder}"] + [f"admmkit.{folder}.{p}" for p in find_packages(folder)]

setup(package_dir=package_dir, packages=packages)
