"""Sphinx configuration of the admmkit documentation site.

Build (from the repository root; warnings are errors, as in CI):

    pip install ".[docs]" && python -m sphinx -W --keep-going -b html docs docs/_build/html

Sphinx with MyST-NB rather than MkDocs: the docstrings already use Sphinx
roles (:class:, :func:), which autodoc resolves and checks (nitpicky), and
MyST-NB executes the jupytext tutorials (docs/tutorials/*.py) through the
same jupyter-cache that tests/test_tutorials.py fills, so CI runs each
tutorial once.
"""
from __future__ import annotations

import os
import re
import sys
from pathlib import Path

from sphinx.ext import napoleon

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))  # document the source tree, installed or not
# ... and execute the tutorials against it too (the kernel inherits the environment)
os.environ["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)
os.environ.setdefault("MPLBACKEND", "Agg")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

project = "admmkit"
author = "admmkit developers"
copyright = "admmkit developers"
try:
    from admmkit import __version__ as release
except ImportError:  # pragma: no cover - autodoc will report the import error
    release = ""
version = release

extensions = [
    "myst_nb",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
]



def _untitled_results() -> list[str]:
    """Result fragments without a title (tables that another page includes).

    They are generated files, shown inside their guide page (e.g. the obstacle
    tables in obstacle.md), so they are not built as pages of their own.
    """
    out = []
    for path in sorted((DOCS / "results").rglob("*.md")):
        lines = [ln for ln in path.read_text(encoding="utf-8").splitlines() if ln.strip()]
        if not lines or not lines[0].startswith("# "):
            out.append(str(path.relative_to(DOCS)))
    return out


exclude_patterns = ["_build", "conf.py", "tutorials/_*", "**/.ipynb_checkpoints", "**/__pycache__", *_untitled_results()]

# ---------------------------------------------------------------- MyST
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3

# ---------------------------------------------------------------- notebooks
# Tutorials are jupytext percent-format scripts; no .ipynb lives in git.
nb_custom_formats = {".py": ["jupytext.reads", {"fmt": "py:percent"}]}
# Execute through the jupyter-cache that tests/test_tutorials.py fills: after
# `pytest` a docs build re-uses those outputs instead of running the
# tutorials again.  A tutorial whose source changed is executed here.
nb_execution_mode = "cache"
nb_execution_cache_path = str(DOCS / "_build" / ".jupyter_cache")
nb_execution_raise_on_error = True
nb_execution_show_tb = True
nb_execution_timeout = 600
nb_merge_streams = True

# ---------------------------------------------------------------- API reference
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
autodoc_default_options = {"members": True, "show-inheritance": True}
napoleon_google_docstring = False
napoleon_numpy_docstring = True
# Check every cross-reference, but not into packages whose inventories we
# cannot fetch (CI reaches only the package index, so no intersphinx).
nitpicky = True
nitpick_ignore_regex = [
    (r"py:.*", r"(np|numpy|scipy|sp|ng|ngsolve|cvxpy|abc|argparse|pathlib|typing|collections|enum|dataclasses)\..*"),
    (r"py:class", r".*\._[A-Za-z]\w*"),  # private base classes (e.g. admmkit.problems.contact.solvers.base._ContactBase)
    (r"py:class", r"(optional|callable|array-like|array_like|int|float|str|bool|dict|list|tuple|None)"),
    (r"py:class", r"(Path|Callable|Mapping|Any|Iterable|Sequence|ndarray|spmatrix|csr_matrix)"),
    (r"py:class", r"tuple\[.*"),  # Sphinx splits tuple[str, ...] at the Ellipsis
    # dataclass fields typed with the friction model and the Coulomb report (documented on docs/friction.md)
    (r"py:class", r"admmkit\.problems\.contact\.solvers\.(friction\.Friction|coulomb\.CoulombReport)"),
]

# ---------------------------------------------------------------- navigation
def _list_unlisted_pages(app, docname, source):
    """Append to the index a toctree of the top-level pages it does not list.

    Other work adds pages to docs/ (a page outside every toctree is a warning,
    hence an error here); they appear under "More" until the index lists them.
    """
    if docname != "index":
        return
    listed = set(re.findall(r"^([A-Za-z0-9_./-]+)$", source[0], flags=re.M))
    pages = sorted(p.stem for p in DOCS.glob("*.md") if p.stem != "index" and p.stem not in listed)
    if pages:
        source[0] += "\n```{toctree}\n:caption: More\n:maxdepth: 1\n\n" + "\n".join(pages) + "\n```\n"


def _reread_index(app, env, added, changed, removed):
    """Re-read the index on every build, so that its "More" toctree sees new pages."""
    return ["index"]


def _napoleon_except_attributes(app, what, name, obj, options, lines):
    """Napoleon for functions, classes and modules; attribute and property docstrings stay prose.

    Napoleon reads the first line of an attribute's docstring as "type: text",
    so "The multiplier of the x-step: ..." would become a broken type
    reference; this project's attribute docstrings are sentences.
    """
    if what not in ("attribute", "property"):
        napoleon._process_docstring(app, what, name, obj, options, lines)


def prose_attribute_docstrings(app):
    """Replace napoleon's docstring hook by :func:`_napoleon_except_attributes`."""
    for listener in list(app.events.listeners.get("autodoc-process-docstring", [])):
        if listener.handler is napoleon._process_docstring:
            app.disconnect(listener.id)
    app.connect("autodoc-process-docstring", _napoleon_except_attributes)


def setup(app):
    """Sphinx hook: the index's "More" toctree; napoleon without the attribute parsing."""
    app.connect("source-read", _list_unlisted_pages)
    app.connect("env-get-outdated", _reread_index)
    prose_attribute_docstrings(app)


# ---------------------------------------------------------------- math
# MathJax 3 from the sphinx-mathjax-offline wheel (in the docs extra) is copied
# into the site, so that the formulas render without a network too.
try:
    import importlib.util

    if importlib.util.find_spec("sphinx-mathjax-offline") is not None:
        extensions.append("sphinx-mathjax-offline")
except (ImportError, ValueError):  # pragma: no cover - the CDN is used instead
    pass


# ---------------------------------------------------------------- HTML
html_theme = "furo"
html_title = f"admmkit {release}"
html_static_path: list[str] = []
