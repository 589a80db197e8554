"""admmkit.loop.blas keeps threadpoolctl's controller until an extension module is imported."""
import sys
import types

from admmkit.loop import blas


def test_the_controller_is_kept_across_pure_python_imports_and_rebuilt_after_an_extension(monkeypatch):
    first = blas._current_controller()
    assert blas._current_controller() is first
    monkeypatch.setitem(sys.modules, "admmkit_test_pure", types.ModuleType("admmkit_test_pure"))
    assert blas._current_controller() is first                   # a pure-Python module: the same libraries
    ext = types.ModuleType("admmkit_test_ext")
    ext.__file__ = "/nowhere/admmkit_test_ext.cpython-311-x86_64-linux-gnu.so"
    monkeypatch.setitem(sys.modules, "admmkit_test_ext", ext)
    assert blas._current_controller() is not first              # an extension module may have loaded a BLAS


def test_limit_blas_still_limits():
    with blas.limit_blas(1):
        assert all(lib.num_threads == 1 for lib in blas._current_controller().lib_controllers
                   if lib.user_api == "blas")
