"""Every tutorial in docs/tutorials/ runs as a notebook and passes its own asserts.

The tutorials assert their key numbers, so a tutorial that drifts from the code
fails here.  Each one is executed exactly as the docs build would execute it
(jupytext percent format -> notebook -> a Python kernel, with the tutorial's
folder as the working directory), and the executed notebook is stored in the
jupyter-cache that the docs build reads (docs/conf.py, nb_execution_mode =
"cache").  So in CI (`pytest`, then the docs build) every tutorial runs once.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TUTORIALS = sorted((ROOT / "docs" / "tutorials").glob("[0-9]*.py"))
CACHE = ROOT / "docs" / "_build" / ".jupyter_cache"   # = nb_execution_cache_path in docs/conf.py


def test_there_are_tutorials():
    assert len(TUTORIALS) >= 1


@pytest.mark.parametrize("path", TUTORIALS, ids=lambda p: p.stem)
def test_tutorial_runs(path: Path, monkeypatch):
    jupytext = pytest.importorskip("jupytext", reason="pip install '.[test]' installs jupytext")
    from jupyter_cache import get_cache
    from jupyter_cache.base import CacheBundleIn
    from jupyter_cache.executors.utils import single_nb_execution

    # the kernel inherits the environment: this checkout's code, one BLAS thread,
    # and inline figures (CI exports MPLBACKEND=Agg, which would drop them)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p))
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "1")

    notebook = jupytext.reads(path.read_text(encoding="utf-8"), fmt="py:percent")  # as docs/conf.py reads it
    run = single_nb_execution(notebook, cwd=str(path.parent), timeout=600, allow_errors=False, meta_override=True)
    assert run.err is None, f"{path.name} failed:\n" + re.sub(r"\x1b\[[0-9;]*m", "", run.exc_string or "")

    CACHE.mkdir(parents=True, exist_ok=True)
    get_cache(str(CACHE)).cache_notebook_bundle(
        CacheBundleIn(notebook, str(path), data={"execution_seconds": run.time}),
        check_validity=False, overwrite=True)
