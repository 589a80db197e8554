"""numba's on-disk cache of admmkit's kernels, stamped with the source of every module that holds kernels.

numba keys a cached kernel on its own file only (its content in numba 0.68, its time and size before). A
kernel that calls, or inlines, a kernel of another file keeps that kernel's machine code in its own cache
entry: after the other file changes, numba would load the stale code and run it, silently (an edited
``_u`` or ``anderson_update`` would not reach the kernels that call them). Here each cached admmkit
kernel's stamp also holds a hash of every file of :data:`KERNEL_FILES`, so that a change to any of
them compiles every kernel anew at its next first call. An install writes every file anew and changes
nothing here; in a source checkout the ``*.nbi``/``*.nbc`` files no longer need deleting by hand.

The stamp goes through numba's cache locators (``numba.core.caching``, not a public API): a locator of
admmkit's wraps the one numba would choose (the same directory and file names) and adds the hash to its
stamp. Where numba's caching module is not the one this was written for, nothing is installed and numba's
own stamps apply. ``import admmkit`` imports none of this: a module imports numba through
:func:`numba_stamped`, and :class:`admmkit.kernels.Kernel` installs the locator before it makes a
dispatcher.
"""
from __future__ import annotations

import hashlib
import importlib.util
import os

from ._layout import SUBPACKAGES

#: every file that holds kernels, by the package whose folder it lies in (tests/test_kernel_cache.py checks the
#: list against the sources: a kernel in a file left out here would again be stamped by its own file only)
KERNEL_FILES: dict[str, tuple[str, ...]] = {
    "admmkit": (
        "kernels.py", "blocks/split_kernels.py", "loop/anderson_kernel.py", "loop/fast_kernel.py",
        "linalg/amd.py", "linalg/amg_finest3d.py", "linalg/cg.py", "linalg/compiled.py", "linalg/ldl.py",
        "linalg/submatrix.py", "linalg/symmetric.py", "linalg/vcycle.py", "linalg/vcycle_blockgs3d.py",
        "linalg/vcycle_blocks.py", "linalg/vcycle_blocks3.py", "linalg/vcycle_blocks3d.py",
        "linalg/vcycle_jacobi3d.py"),
    "admmkit.problems": (
        "contact/model/stiffness3d.py", "contact/solvers/condensed_segment.py", "contact/solvers/dissection.py",
        "qp/infeasibility_kernel.py", "qp/residual_kernel.py", "qp/rows.py", "qp/ruiz_kernel.py", "qp/segment.py",
        "qp/segment_checks.py", "qp/sparse_kernels.py", "qp/termination.py", "qp/validate_kernel.py"),
}

#: admmkit and its subpackages (``admmkit._layout.SUBPACKAGES``): a file in one of their folders is admmkit's
PACKAGES = ("admmkit",) + tuple(f"admmkit.{name}" for name in SUBPACKAGES)

_installed = False
_stamp: bytes | None = None


def package_folders() -> dict[str, str]:
    """The folder of admmkit and of each subpackage (found without importing the subpackages; a source checkout
    keeps them beside ``admmkit/``, an install inside it)."""
    folders = {}
    for package in PACKAGES:
        spec = importlib.util.find_spec(package)
        folders[package] = os.path.realpath(list(spec.submodule_search_locations)[0])
    return folders


def kernel_files() -> dict[str, str]:
    """The path of each file of :data:`KERNEL_FILES`, by its name (``"admmkit/linalg/cg.py"``)."""
    folders = package_folders()
    return {f"{package.replace('.', '/')}/{name}": os.path.join(folders[package], name)
            for package, names in KERNEL_FILES.items() for name in names}


def sources_stamp() -> bytes:
    """sha256 over the names and contents of every kernel file (once per process: about 1 ms)."""
    global _stamp
    if _stamp is None:
        digest = hashlib.sha256()
        for name, path in kernel_files().items():
            with open(path, "rb") as f:
                digest.update(name.encode() + b"\0" + f.read())
        _stamp = digest.digest()
    return _stamp


def make_locator(default_classes: list):
    """The locator class: numba's own choice among ``default_classes`` for a file of admmkit's folders, with
    :func:`sources_stamp` added to its stamp; None (numba's choice stands) for any other file."""
    from numba.core.caching import _CacheLocator

    folders = tuple(folder + os.sep for folder in package_folders().values())

    class KernelSourcesLocator(_CacheLocator):
        """numba's locator of an admmkit kernel with the stamp of every kernel file added."""

        def __init__(self, inner):
            self._inner = inner

        def ensure_cache_path(self):
            """As numba's locator."""
            self._inner.ensure_cache_path()

        def get_cache_path(self):
            """As numba's locator."""
            return self._inner.get_cache_path()

        def get_disambiguator(self):
            """As numba's locator."""
            return self._inner.get_disambiguator()

        def get_source_stamp(self):
            """numba's stamp of the kernel's own file and the hash of every kernel file."""
            return self._inner.get_source_stamp(), sources_stamp()

        @classmethod
        def from_function(cls, py_func, py_file):
            """For a file of admmkit: numba's locator wrapped; else None."""
            if not os.path.realpath(py_file).startswith(folders):
                return None
            for other in default_classes:
                inner = other.from_function(py_func, py_file)
                if inner is not None:
                    return cls(inner)
            return None

    return KernelSourcesLocator


def install() -> bool:
    """Put admmkit's locator first among numba's (once); False where numba's caching module does not look as
    expected (numba's own stamps then apply)."""
    global _installed
    if _installed:
        return True
    try:
        from numba.core import caching
        impl = cache_impl()
        default = list(impl._locator_classes)
        if not (default and all(isinstance(c, type) and issubclass(c, caching._CacheLocator) for c in default)):
            return False
    except (ImportError, AttributeError):
        return False
    impl._locator_classes = [make_locator(default)] + default
    _installed = True
    return True


def cache_impl():
    """numba's class that picks a kernel's locator (``CacheImpl``; ``_CacheImpl`` before numba 0.68)."""
    from numba.core import caching
    return getattr(caching, "CacheImpl", None) or caching._CacheImpl


def numba_stamped():
    """numba, imported, with admmkit's locator installed: the import of every admmkit module that decorates
    with numba directly (``njit, prange = numba_stamped().njit, numba_stamped().prange``)."""
    import numba
    install()
    return numba
