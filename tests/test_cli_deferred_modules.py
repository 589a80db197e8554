"""The command line's process loads numpy.f2py, testing, ma, polynomial, ... at first use (admmkit/cli/deferred_modules.py)."""
import subprocess
import sys

SCRIPT = """
import sys
sys.argv = ["admmkit", "solve", "contact", "--scene", "ex1", "--h", "1/8", "--rho", "1e3", "--quiet"]
from admmkit.cli import main
code = main()
ran = [m for m in ("numpy.f2py.crackfortran", "numpy.testing._private.utils", "charset_normalizer", "numpy.ma.core",
                   "numpy.polynomial.polynomial", "numpy._core.defchararray", "importlib.metadata") if m in sys.modules]
import numpy as np
np.testing.assert_array_equal([1.0], [1.0])                 # the module runs at its first use, whole
from numpy.f2py import crackfortran  # noqa: F401
assert np.ma.masked_array([1.0], mask=[True]).mask[0] and np.polynomial.Polynomial([1.0, 2.0])(1.0) == 3.0
print(code, "scipy.sparse" in sys.modules, ran, "numpy.testing._private.utils" in sys.modules)
"""


def test_the_console_script_runs_neither_module_until_used(tmp_path):
    """The second process finds the operators in the cache (the first assembles them with NGSolve, which imports
    importlib.metadata)."""
    import os
    env = dict(os.environ, ADMMKIT_CACHE_DIR=str(tmp_path))
    for _ in range(2):
        out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=300, env=env)
        assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines()[-1].split() == ["0", "True", "[]", "True"]


def test_a_call_of_main_with_arguments_leaves_numpy_alone():
    script = ("import sys\nfrom admmkit.cli import main\nmain(['--version'])\n"
              "from admmkit.cli.deferred_modules import DeferredFinder\n"
              "print(any(isinstance(f, DeferredFinder) for f in sys.meta_path))")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert out.stdout.split()[-1] == "False", out.stderr


def test_no_finder_once_numpy_is_imported():
    from admmkit.cli.deferred_modules import defer_unused_numpy_modules
    import numpy  # noqa: F401
    assert defer_unused_numpy_modules() is False
