"""numpy's submodules that ``import scipy`` runs and no command uses, loaded at first use in the command line's process.

Every ``import scipy.sparse`` runs, through scipy's vendored
``array_api_compat``, ``from numpy import *``; numpy 2's ``__all__`` names its
submodules, so that line executes all of them: among them ``f2py`` (and,
through ``numpy.f2py.crackfortran``, ``charset_normalizer`` where it is
installed), ``testing``, ``ma``, ``polynomial``, ``char`` and ``strings``,
which neither scipy.sparse nor an admmkit command uses: 0.15-0.3 s of a
``solve contact`` process at load 3-4, whose whole budget is 0.6 s (issue
#49; ``admmkit bench first-call``).  (``numpy.random`` and ``numpy.fft`` are
not deferred: scipy uses them while it is imported.  ``np.unique`` loads
``numpy.ma``: the contact set-up finds its dofs without it.)

:func:`defer_unused_numpy_modules` puts a finder first on ``sys.meta_path``
that gives these modules the standard library's
:class:`importlib.util.LazyLoader`: the import binds the name and the module
runs at the first access to one of its attributes, the same module then.
Only the console script (and ``python -m admmkit``) calls it, before anything
imports numpy; ``import admmkit`` in a user's program changes nothing in
numpy.
"""
from __future__ import annotations

import importlib.machinery
import importlib.util
import sys

#: the modules loaded at their first use instead of at ``import scipy``
DEFERRED = ("numpy.f2py", "numpy.testing", "numpy.ma", "numpy.polynomial", "numpy.char", "numpy.strings")


class DeferredFinder:
    """A ``sys.meta_path`` finder: the spec the path finder gives for a module of ``DEFERRED``, with its loader
    wrapped in :class:`importlib.util.LazyLoader`; None (the next finder) for any other module."""

    def find_spec(self, name, path, target=None):
        """The lazily loaded spec of ``name`` when it is one of :data:`DEFERRED` and found on ``path``."""
        if name not in DEFERRED:
            return None
        spec = importlib.machinery.PathFinder.find_spec(name, path)
        if spec is None or not hasattr(spec.loader, "exec_module"):
            return None
        spec.loader = importlib.util.LazyLoader(spec.loader)
        return spec


def defer_unused_numpy_modules() -> bool:
    """Install :class:`DeferredFinder` unless numpy is imported already (then the modules are, or the finder would
    come too late to matter); True when installed."""
    if "numpy" in sys.modules or any(isinstance(f, DeferredFinder) for f in sys.meta_path):
        return False
    sys.meta_path.insert(0, DeferredFinder())
    return True
