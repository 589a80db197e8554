"""The docstrings build into the API reference without a warning.

The docs build in CI treats warnings as errors, and a docstring is the easiest
place to break it (an ``|x|`` that reStructuredText reads as a substitution, a
``:func:`` role to an undocumented function, "text: more text" on the first line
of a numpy-style parameter).  This test builds only the API reference of
docs/api.md, with docs/conf.py's autodoc settings, so that ``pytest`` reports
such a docstring in a few seconds, before the full docs build does.
"""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"

CONF = '''
import sys
sys.path.insert(0, {root!r})
_ns = {{"__file__": {conf!r}}}
exec(compile(open({conf!r}, encoding="utf-8").read(), {conf!r}, "exec"), _ns)
globals().update({{k: v for k, v in _ns.items() if k.startswith(("autodoc_", "napoleon_", "nitpick"))}})
extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon"]


def setup(app):
    _ns["prose_attribute_docstrings"](app)
'''


def test_api_reference_builds_without_warnings(tmp_path):
    blocks = re.findall(r"```\{eval-rst\}\n(.*?)```", (DOCS / "api.md").read_text(encoding="utf-8"), flags=re.S)
    assert blocks, "docs/api.md has no automodule blocks"
    src = tmp_path / "src"
    src.mkdir()
    (src / "index.rst").write_text("API\n===\n\n" + "\n".join(blocks), encoding="utf-8")
    (src / "conf.py").write_text(CONF.format(root=str(ROOT), conf=str(DOCS / "conf.py")), encoding="utf-8")
    proc = subprocess.run([sys.executable, "-m", "sphinx", "-E", "-W", "--keep-going", "-q", "-b", "dummy",
                           str(src), str(tmp_path / "out")], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, "the API reference has warnings:\n" + proc.stderr
