"""Pinning BLAS threads, cheaply enough to do around every solve.

On a 2-core machine shared with other work, a multithreaded BLAS can cost
milliseconds per small operation in thread hand-off (CHOLMOD with two
OpenBLAS threads took 0.45 s instead of 0.02 s for one factorisation of the
paper's Example 2 at h = 1/40 while the other core was busy).
``threadpoolctl.threadpool_limits`` enumerates the loaded libraries on every
call (about 0.5 ms; 3-6 ms in a fresh process); :func:`limit_blas` keeps one
controller and rebuilds it only when an extension module (a ``.so`` or
``.pyd`` file: it may have loaded another BLAS) has been imported since, which costs
about 15 microseconds when nothing was imported and a look at the new
modules' files otherwise.
"""
from __future__ import annotations

import contextlib
import sys

_controller = None
_modules_seen = -1


def _current_controller():
    """threadpoolctl's controller of the libraries loaded now: the one kept, unless an extension module came since."""
    global _controller, _modules_seen
    count = len(sys.modules)
    if _controller is None or count != _modules_seen and _new_extension(_modules_seen):
        from threadpoolctl import ThreadpoolController
        _controller = ThreadpoolController()
    _modules_seen = count
    return _controller


def _new_extension(seen: int) -> bool:
    """Whether a module imported after the first ``seen`` of ``sys.modules`` (which keeps the order of import) is
    an extension module; True when modules were removed (the order says nothing then)."""
    from importlib.machinery import EXTENSION_SUFFIXES
    names = list(sys.modules)
    if len(names) < seen:
        return True
    suffixes = tuple(EXTENSION_SUFFIXES)
    return any((getattr(sys.modules.get(name), "__file__", None) or "").endswith(suffixes) for name in names[seen:])


def limit_blas(threads: int | None):
    """A context manager running BLAS with ``threads`` threads (None: leave it as it is; nothing to do either when
    every BLAS already runs that many: threadpoolctl's limit would set and restore them, about 10 us)."""
    if threads is None:
        return contextlib.nullcontext()
    controller = _current_controller()
    if all(lib.num_threads == threads for lib in controller.lib_controllers if lib.user_api == "blas"):
        return contextlib.nullcontext()
    return controller.limit(limits=threads, user_api="blas")
