"""Pinning BLAS threads, cheaply enough to do around every solve.

On a 2-core machine shared with other work, a multithreaded BLAS can cost
milliseconds per small operation in thread hand-off (CHOLMOD with two
OpenBLAS threads took 0.45 s instead of 0.02 s for one factorisation of the
paper's Example 2 at h = 1/40 while the other core was busy).
``threadpoolctl.threadpool_limits`` enumerates the loaded libraries on every
call (about 0.5 ms); :func:`limit_blas` keeps one controller and rebuilds it
only when new Python modules have been imported since (a new extension module
may have loaded another BLAS), which costs about 15 microseconds.
"""
from __future__ import annotations

import contextlib
import sys

_controller = None
_modules_seen = -1


def _current_controller():
    global _controller, _modules_seen
    if _controller is None or len(sys.modules) != _modules_seen:
        from threadpoolctl import ThreadpoolController
        _controller = ThreadpoolController()
        _modules_seen = len(sys.modules)
    return _controller


def limit_blas(threads: int | None):
    """A context manager running BLAS with ``threads`` threads (None: leave it as it is; nothing to do either when
    every BLAS already runs that many: threadpoolctl's limit would set and restore them, about 10 us)."""
    if threads is None:
        return contextlib.nullcontext()
    controller = _current_controller()
    if all(lib.num_threads == threads for lib in controller.lib_controllers if lib.user_api == "blas"):
        return contextlib.nullcontext()
    return controller.limit(limits=threads, user_api="blas")
