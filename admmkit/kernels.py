"""Compiled kernels (numba): how a kernel is made, and when it runs compiled or as the Python it is written as.

A plug-in may run the iterations that no stopping rule, policy or callback
reads in one compiled call (a *segment*, :mod:`admmkit.loop.segments`), and
the large problems' linear algebra runs hand-written kernels
(``admmkit.linalg``).  Each is written so that every floating-point
operation is the one the Python path does, in the same order: a segment's
iterates are those of the Python loop bit for bit.  This module is the
machinery they share (the loop's, the building blocks', the linear
algebra's and the plug-ins'); :mod:`admmkit.linalg.compiled` holds the
kernels of sparse linear algebra (qdldl's solve, CSC products).

Why numba: it compiles these loops to machine code at the first call (cached
on disk, so later processes load them in milliseconds), is pip-installable
with wheels for every platform NumPy has, and needs no compiler on the user's
machine; a C extension would.  ``fastmath`` stays off: no reassociation, no
fused multiply-add, so the bits are the Python path's.  Without numba
(``AVAILABLE`` False) every run takes the Python path.

Compiled only where it pays (docs/qp.md, "First call"): importing numba
costs about 0.6 s and loading a cached kernel about 0.1 s (compiling one,
on a fresh install, 1-3 s), more than a small problem's whole solve.  So
importing this module imports no numba: each kernel here is a
:class:`Kernel`, compiled (or loaded from numba's cache) at its first
compiled call.  A kernel made with :func:`kernel` follows
:func:`compiled_code`: inside ``with compiled_code(False)`` it runs as the
Python function it is written as (the same operations in the same order:
the same bits, at Python's speed, fine for a small problem), inside
``compiled_code(True)`` compiled; outside either, compiled when numba is
already imported in this process and as Python otherwise.  :func:`njit`
makes a kernel that is always compiled (the kernels of the large problems).
The first compile in a process whose numba cache is cold prints one line on
stderr saying so and that ``admmkit warm-up`` does it ahead.

numba's on-disk cache of a kernel is keyed on its own file, not on the
kernels it calls; :mod:`admmkit.kernel_cache` adds the source of every
file that holds kernels to each kernel's key, so that an edited kernel
reaches the kernels that call it.
"""
from __future__ import annotations

import contextlib
import contextvars
import importlib.util
import os
import sys
import types

import numpy as np

#: True when numba is installed, asked without importing it (``import admmkit`` stays light)
AVAILABLE = importlib.util.find_spec("numba") is not None

#: inside :func:`compiled_code`: True (compiled kernels) or False (the kernels as Python); None: not set
_MODE: contextvars.ContextVar = contextvars.ContextVar("admmkit_compiled_code", default=None)
#: whether this process printed the cold-cache note already
_noted = False
#: every kernel made here, for ``admmkit warm-up``: {module name: [Kernel, ...]}
KERNELS: dict[str, list] = {}


@contextlib.contextmanager
def compiled_code(flag: bool):
    """Within the block, the kernels made with :func:`kernel` run compiled (``flag`` True, numba imported at the
    first call) or as Python (False: the same bits, no numba)."""
    token = _MODE.set(bool(flag) and AVAILABLE)
    try:
        yield
    finally:
        _MODE.reset(token)


def compiled_now() -> bool:
    """Whether a :func:`kernel` called here runs compiled: as :func:`compiled_code` says, else iff numba is already
    imported in this process (no call pays numba's import for a pass nobody asked compiled)."""
    mode = _MODE.get()
    return ("numba" in sys.modules and AVAILABLE) if mode is None else mode


#: the environment variable whose value ``library`` sends each hand-written kernel to its library path
KERNELS_VARIABLE = "ADMMKIT_KERNELS"
#: inside :func:`library_kernels`: True (the library paths) or False (the hand-written kernels); None: not set
_LIBRARY: contextvars.ContextVar = contextvars.ContextVar("admmkit_library_kernels", default=None)


@contextlib.contextmanager
def library_kernels(flag: bool = True):
    """Within the block, each hand-written kernel of the large problems takes the library path it replaces
    (``flag`` True) or the kernel (False), whatever ``ADMMKIT_KERNELS`` says.

    The pairs (docs/framework.md, "Hand-written kernels and their libraries"): the V-cycle of
    ``amg.AMGPreconditioner`` (pyamg's own cycle), CG's fused updates (numpy),
    ``submatrix.principal_submatrix`` (scipy's indexing) and ``symmetric.pencil_products`` (scipy's product).  The library path is the one a machine
    without numba runs; this switch keeps it exercised (tests/admmkit/test_library_paths.py).
    """
    token = _LIBRARY.set(bool(flag))
    try:
        yield
    finally:
        _LIBRARY.reset(token)


def hand_written() -> bool:
    """Whether the hand-written kernels run: numba is installed and neither :func:`library_kernels` nor
    ``ADMMKIT_KERNELS=library`` asks for the library paths."""
    flag = _LIBRARY.get()
    if flag is None:
        flag = os.environ.get(KERNELS_VARIABLE, "").strip().lower() == "library"
    return AVAILABLE and not flag


class Kernel:
    """A numba kernel compiled (or loaded from numba's cache) at its first compiled call, not at import.

    ``py_func`` is the Python function; ``switchable``: it runs as Python where
    :func:`compiled_now` is False (a :func:`kernel`), else it is always compiled
    (an :func:`njit`).  Inside another kernel it is typed as its numba
    dispatcher (``_numba_type_``), so kernels call kernels as numba's do.
    """

    def __init__(self, py_func, options: dict, switchable: bool) -> None:
        self.py_func, self.options, self.switchable = py_func, options, switchable
        self.__name__, self.__doc__ = py_func.__name__, py_func.__doc__
        self.__module__, self.__qualname__ = py_func.__module__, py_func.__qualname__
        self.__wrapped__ = py_func
        self._dispatcher = None
        KERNELS.setdefault(py_func.__module__, []).append(self)

    def dispatcher(self):
        """numba's dispatcher of this kernel (numba imported now if it was not)."""
        if self._dispatcher is None:
            from .kernel_cache import numba_stamped      # its cache stamped with every kernel file's source
            self._dispatcher = numba_stamped().njit(**known_options(self.options))(self.py_func)
        return self._dispatcher

    @property
    def _numba_type_(self):
        """The numba type of the kernel where another kernel calls it: its dispatcher's."""
        from numba.core import types
        return types.Dispatcher(self.dispatcher())

    def __call__(self, *args):
        """Run compiled (see the class) or as Python."""
        if self.switchable:                            # compiled_now(), inline: this runs at every call
            mode = _MODE.get()
            if not (("numba" in sys.modules and AVAILABLE) if mode is None else mode):
                return self.py_func(*args)
        dispatcher = self._dispatcher or self.dispatcher()
        if not dispatcher.overloads:                   # the first compiled call in this process (``signatures``
            _note_cold(self)                           # builds a list of hashed types: 0.1 ms a call)
        return dispatcher(*args)

    def __get__(self, obj, kind=None):
        """A kernel looked up on an instance is bound to it, as a function is (and tools see a routine)."""
        return self if obj is None else types.MethodType(self, obj)

    def __repr__(self) -> str:
        return f"<admmkit kernel {self.__module__}.{self.__qualname__}>"


def known_options(options: dict) -> dict:
    """``options`` without the private ones (a leading underscore, e.g. ``_nrt``) that this numba does not know: a
    numba that dropped one compiles the kernel without it (the same values; only the speed it bought is lost)."""
    private = [k for k in options if k.startswith("_")]
    if not private:
        return options
    try:
        from numba.core.cpu import CPUTargetOptions
    except ImportError:                                  # numba moved its options: keep none of the private ones
        return {k: v for k, v in options.items() if not k.startswith("_")}
    return {k: v for k, v in options.items() if not k.startswith("_") or hasattr(CPUTargetOptions, k)}


def _make(switchable: bool, args, options):
    """The decorator of :func:`kernel` and :func:`njit` (bare or with options)."""
    if args and callable(args[0]):
        return Kernel(args[0], {}, switchable)
    return lambda func: Kernel(func, options, switchable)


def kernel(*args, **options):
    """Decorator: a :class:`Kernel` that runs compiled or as Python, as :func:`compiled_now` says (numba's
    ``njit`` options, e.g. ``cache=True``)."""
    return _make(True, args, options)


def njit(*args, **options):
    """Decorator: a :class:`Kernel` that always runs compiled (numba imported at its first call)."""
    return _make(False, args, options)


def cache_index(k: Kernel) -> str | None:
    """The path of the numba cache index (``*.nbi``) of kernel ``k``, or None where numba does not say."""
    try:
        return k.dispatcher()._cache._cache_file._index_path
    except AttributeError:
        return None


def _note_cold(k: Kernel) -> None:
    """At the first compile of a process whose numba cache has no index for ``k``: one line on stderr."""
    global _noted
    if _noted:
        return
    index = cache_index(k)
    if index is None or os.path.exists(index):
        return
    _noted = True
    print(f"admmkit: compiling numba kernels (first {k.__module__}.{k.__name__}): seconds after an install or an "
          f"upgrade, then cached for later processes; `admmkit warm-up` compiles them all ahead", file=sys.stderr)


@kernel(cache=True, inline="always")
def _u(i):
    """An index as unsigned: no negative-index wraparound test where it is used (indices here are >= 0)."""
    return np.uint64(i)


@kernel(cache=True)
def all_finite(v, start, stop):
    """Whether v[start:stop] holds only finite numbers."""
    for i in range(start, stop):
        if not np.isfinite(v[i]):
            return False
    return True
