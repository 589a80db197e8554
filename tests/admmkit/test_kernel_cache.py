"""admmkit.kernel_cache: a cached kernel is compiled anew when a kernel file it does not live in changes."""
import os
import re
import subprocess
import sys
import textwrap

import pytest

from admmkit import kernel_cache

pytest.importorskip("numba")

#: a line that makes a kernel: a decorator of admmkit.kernels or numba, or numba's njit called on a function
KERNEL_LINE = re.compile(r"^@(njit|kernel)\b|^@numba\.njit\b|^\w+ = (njit|kernel)\(")


def test_every_file_with_kernels_is_stamped():
    assert set(kernel_cache.package_folders()) == {"admmkit", "admmkit.problems", "admmkit.policies",
                                                   "admmkit.benchmarks"}        # kernels anywhere in admmkit
    found = set()
    for package, folder in kernel_cache.package_folders().items():
        for root, _, files in os.walk(folder):
            for name in files:
                path = os.path.join(root, name)
                if name.endswith(".py") and any(KERNEL_LINE.match(line) for line in open(path, encoding="utf-8")):
                    found.add(f"{package.replace('.', '/')}/{os.path.relpath(path, folder)}")
    assert found == set(kernel_cache.kernel_files())


def test_the_stamp_is_of_the_sources_and_numba_takes_the_locator():
    stamp = kernel_cache.sources_stamp()
    assert isinstance(stamp, bytes) and len(stamp) == 32 and kernel_cache.sources_stamp() is stamp
    from admmkit.linalg import vcycle  # noqa: F401  (a module that decorates with numba directly)
    assert kernel_cache.install() and kernel_cache.cache_impl()._locator_classes[0].__name__ == "KernelSourcesLocator"
    from admmkit.linalg.cg import _step_kernel
    locator = _step_kernel.dispatcher()._cache._impl.locator
    assert type(locator).__name__ == "KernelSourcesLocator" and locator.get_source_stamp()[1] == stamp
    assert locator.get_cache_path().endswith("__pycache__")              # beside the file, as numba's own


CALLER = "from numba import njit\nfrom pkgx.callee import g\n\n@njit(cache=True)\ndef f(x):\n    return g(x) * 10\n"
CALLEE = "from numba import njit\n\n@njit(cache=True)\ndef g(x):\n    return x + {}\n"


def _run(tmp_path, stamped: bool) -> tuple[int, int]:
    """f(1) in a fresh process and the number of f's signatures loaded from numba's cache."""
    code = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(tmp_path)!r})
        if {stamped}:
            from admmkit import kernel_cache
            kernel_cache.PACKAGES, kernel_cache.KERNEL_FILES = ("pkgx",), {{"pkgx": ("caller.py", "callee.py")}}
            assert kernel_cache.install()
        from pkgx.caller import f
        print(f(1), f.stats.cache_hits.get(f.signatures[0], 0) if f.signatures else 0)
        """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    value, hits = done.stdout.split()
    return int(value), int(hits)


@pytest.mark.parametrize("stamped", [True, False])
def test_a_kernel_is_compiled_anew_when_the_kernel_it_calls_changes(tmp_path, stamped):
    package = tmp_path / "pkgx"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "caller.py").write_text(CALLER)
    (package / "callee.py").write_text(CALLEE.format(1))
    assert _run(tmp_path, stamped) == (20, 0)                 # compiled and cached
    assert _run(tmp_path, stamped) == (20, 1)                 # loaded from the cache
    (package / "callee.py").write_text(CALLEE.format(2))      # g changes, f's file does not
    if stamped:
        assert _run(tmp_path, stamped) == (30, 0)             # compiled anew with the new g
    else:
        assert _run(tmp_path, stamped) == (20, 1)             # numba alone: f's stale copy of g, silently


def test_a_numba_whose_caching_looks_otherwise_keeps_its_own_stamps(monkeypatch):
    class Unexpected:
        _locator_classes = [object]                    # not numba's locators: nothing is installed
    monkeypatch.setattr(kernel_cache, "_installed", False)
    monkeypatch.setattr(kernel_cache, "cache_impl", lambda: Unexpected)
    assert kernel_cache.install() is False and Unexpected._locator_classes == [object]
