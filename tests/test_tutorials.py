"""Every tutorial in docs/tutorials/ runs as a notebook and passes its own asserts.

The tutorials assert their key numbers, so a tutorial that drifts from the code
fails here.  Each one is executed as the docs build would execute it
(jupytext percent format -> notebook -> a Python kernel, with the tutorial's
folder as the working directory).  The executed notebooks are stored in the
jupyter-cache that the docs build reads (docs/conf.py, nb_execution_mode =
"cache"), so in CI (`pytest`, then the docs build) every tutorial runs once.

The tutorials run two at a time, each in its own process with its own kernel
(the machine has two cores); the cache is written by this process only.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TUTORIALS = sorted((ROOT / "docs" / "tutorials").glob("[0-9]*.py"))
CACHE = ROOT / "docs" / "_build" / ".jupyter_cache"   # = nb_execution_cache_path in docs/conf.py
WORKERS = 2
TIMEOUT = 600

# Executes one tutorial: argv = source .py, output .ipynb; prints the run time,
# writes the traceback to stderr and exits 1 if a cell failed.
_EXECUTE = r"""
import os, sys, jupytext, nbformat
from jupyter_cache.executors.utils import single_nb_execution
src, out = sys.argv[1], sys.argv[2]
with open(src, encoding="utf-8") as fh:
    nb = jupytext.reads(fh.read(), fmt="py:percent")       # as docs/conf.py reads it
run = single_nb_execution(nb, cwd=os.path.dirname(src), timeout=int(sys.argv[3]),
                          allow_errors=False, meta_override=True)
if run.err is not None:
    sys.stderr.write(run.exc_string or repr(run.err))
    sys.exit(1)
nbformat.write(nb, out)
print(run.time)
"""


def _environment() -> dict:
    """This checkout's code, one BLAS thread, inline figures (CI exports MPLBACKEND=Agg)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH", "")) if p)
    env["MPLBACKEND"] = "module://matplotlib_inline.backend_inline"
    env["OMP_NUM_THREADS"] = env["OPENBLAS_NUM_THREADS"] = "1"
    return env


@pytest.fixture(scope="module")
def executed(tmp_path_factory):
    """Run every tutorial (WORKERS at a time): {path: (returncode, executed .ipynb, stdout, stderr)}."""
    pytest.importorskip("jupytext", reason="pip install '.[test]' installs jupytext")
    out_dir, env = tmp_path_factory.mktemp("tutorials"), _environment()

    def run(path: Path):
        out = out_dir / f"{path.stem}.ipynb"
        proc = subprocess.run([sys.executable, "-c", _EXECUTE, str(path), str(out), str(TIMEOUT)],
                              env=env, capture_output=True, text=True, timeout=TIMEOUT + 60)
        return path, (proc.returncode, out, proc.stdout, proc.stderr)

    with ThreadPoolExecutor(WORKERS) as pool:
        return dict(pool.map(run, TUTORIALS))


def test_there_are_tutorials():
    assert len(TUTORIALS) >= 1


@pytest.mark.study                     # every tutorial executed as a notebook: minutes (python -m pytest -m study)
@pytest.mark.parametrize("path", TUTORIALS, ids=lambda p: p.stem)
def test_tutorial_runs(path: Path, executed):
    import nbformat
    from jupyter_cache import get_cache
    from jupyter_cache.base import CacheBundleIn

    returncode, notebook_path, stdout, stderr = executed[path]
    assert returncode == 0, f"{path.name} failed:\n" + re.sub(r"\x1b\[[0-9;]*m", "", stderr)

    notebook = nbformat.read(notebook_path, as_version=4)
    CACHE.mkdir(parents=True, exist_ok=True)
    get_cache(str(CACHE)).cache_notebook_bundle(
        CacheBundleIn(notebook, str(path), data={"execution_seconds": float(stdout.split()[-1])}),
        check_validity=False, overwrite=True)
