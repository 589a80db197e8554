"""The penalty-policy protocol and the name registry.

A policy is a small stateful object.  :func:`admmkit.solve` calls
``policy.reset(rho0)`` once at the start of a run and ``policy.update(record)``
after every iteration; ``update`` returns rho_{k+1}.  Policies must be
deterministic functions of the iteration history (never of wall time), and
they never rescale the multiplier: admmkit stores it unscaled, so a change of
rho needs nothing else.

Writing a rule takes a few lines::

    class Halve(Policy):
        def update(self, rec):
            return rec.rho / 2 if rec.k % 10 == 9 else rec.rho

A rule may also set a penalty per row of the constraint (RLQP's shape): it
declares ``per_row = True`` and its ``update`` returns, where it changes them,
:class:`RowPenalties` (rho_{k+1}, w): row i's penalty becomes rho_{k+1} w_i,
w the diagonal of the problem's inner product M (``rec.row_weights`` holds the
current one).  The loop makes it the one event of a change of rho
(:class:`admmkit.loop.steps.RhoEvent`); a problem without per-row weights
refuses such a rule at the start.
"""
from __future__ import annotations

import functools
import hashlib
import importlib
import importlib.util
import inspect
import sys
from abc import ABC, abstractmethod
from pathlib import Path
from typing import Callable, NamedTuple

import numpy as np

from .loop.record import IterationRecord
from .installed import own_entry_points

_REGISTRY: dict[str, Callable[..., "Policy"]] = {}
#: the entry-point group in which an installed package names its rules (admmkit's own are in pyproject.toml)
GROUP = "admmkit.policies"


class RowPenalties(NamedTuple):
    """What ``update`` of a rule with ``per_row = True`` returns where it sets a penalty per row.

    ``rho`` is rho_{k+1} (one number, checked as a scalar rule's answer) and
    ``weights`` the diagonal w of the problem's inner product M for the next
    iterations (shape of z, finite, > 0): row i's penalty is rho w_i.  The
    problem keeps the multiplier it reports (M lam) across the change
    (:meth:`admmkit.loop.steps.RhoEvent.change_rows`).
    """

    rho: float
    weights: np.ndarray


class Policy(ABC):
    """Base class of penalty rules."""

    #: record fields the rule reads that a problem might not provide
    #: (only "dual_residual" can be missing: order "xz" needs ``adjoint_norm``)
    requires: tuple[str, ...] = ()
    #: True: ``update`` may return :class:`admmkit.RowPenalties` (a penalty per row); the loop then refuses a problem
    #: without ``update_row_weights(rho, w)`` and ``inner_weights()`` before the first iteration
    per_row: bool = False

    def reset(self, rho0: float) -> None:
        """Start a new run from rho0 (clear any state)."""
        self.rho0 = rho0

    @abstractmethod
    def update(self, rec: IterationRecord) -> float:
        """Return rho_{k+1} from the record of iteration k (``rec.rho`` is rho_k); a rule with ``per_row = True``
        may return :class:`RowPenalties` (rho_{k+1}, row weights) instead."""

    def unchanged_until(self, k: int) -> int:
        """The first iteration j >= k whose record the rule reads.

        At iterations k .. j - 1 it would return rho unchanged without
        reading their records (nor keeping anything of them), so the loop
        may run them without records (:mod:`admmkit.loop.segments`).  The default,
        k, says the rule reads every record; a rule that acts every
        ``interval`` iterations, or never, says so here.
        """
        return k

    def __repr__(self) -> str:
        names = _init_names(type(self))
        params = ", ".join(f"{k}={getattr(self, k)!r}" for k in names if hasattr(self, k))
        return f"{type(self).__name__}({params})"


@functools.lru_cache(maxsize=None)
def _init_names(cls) -> tuple[str, ...]:
    """The parameters of ``cls.__init__`` (read once per class: every result names its rule)."""
    return tuple(p for p in inspect.signature(cls.__init__).parameters if p != "self")


def register_policy(name: str):
    """Class decorator: make a rule of yours constructible by name in this process (``make_policy(name)``).

    admmkit's own rules need no decorator: each is named once, by its line in the
    entry-point group ``admmkit.policies`` of ``pyproject.toml``, and loaded on first use.
    """

    def deco(cls):
        _REGISTRY[name] = cls
        cls.registered_name = name
        return cls

    return deco


def declared_rules() -> dict:
    """The rules installed packages declare in the entry-point group ``admmkit.policies``: ``{name: EntryPoint}``.

    admmkit's own rules are declared there too (``pyproject.toml``): it is the
    only place a built-in rule is named.
    """
    from importlib.metadata import entry_points
    return {ep.name.strip().lower().replace("-", "_"): ep for ep in entry_points(group=GROUP)}


@functools.lru_cache(maxsize=1)
def own_rules() -> dict:
    """The rules admmkit itself declares in ``pyproject.toml``: ``{name: EntryPoint}`` read from admmkit's own
    ``entry_points.txt`` (:mod:`admmkit.installed`: 1-6 ms without importing importlib.metadata, where
    :func:`declared_rules` reads every installed package's, 20-30 ms: twice per ``admmkit solve contact``
    before; issue #49), once per process; empty when admmkit is not installed as a distribution (a bare source
    tree: :func:`declared_rules` then finds what there is)."""
    points = own_entry_points(GROUP) or {}
    return {name.strip().lower().replace("-", "_"): ep for name, ep in points.items()}


def policy_names() -> list[str]:
    """Names of the known policies: registered in this process, or declared by an installed package."""
    return sorted(set(_REGISTRY) | set(declared_rules()))


def _lookup(key: str):
    """The class registered or declared under ``key`` (loading its entry point on first use), or None."""
    if key not in _REGISTRY:                    # admmkit's own rules first: no scan of every installed package
        declared = own_rules().get(key) or declared_rules().get(key)
        if declared is None:
            return None
        try:
            cls = declared.load()
        except KeyboardInterrupt:
            raise
        except BaseException as err:            # SystemExit too: a rule's import must not end the program
            raise ValueError(f"policy {key!r} (entry point {declared.value}) failed to import: "
                             f"{raised(err)}") from None
        _REGISTRY[key] = check_policy_class(cls, f"{key!r} (entry point {declared.value})")
    return _REGISTRY[key]


def is_spec(name: str) -> bool:
    """Whether ``name`` points at a class (``module:Class`` or ``path/to/file.py:Class``) rather than naming a rule."""
    return isinstance(name, str) and ":" in name


def canonical_spec(spec: str) -> str:
    """``spec`` with a file path made absolute, so that worker processes (local or Dask) load the same file."""
    target, _, cls_name = spec.strip().rpartition(":")
    if target.endswith(".py"):
        target = str(Path(target).expanduser().resolve())
    return f"{target}:{cls_name}"


def load_spec(spec: str):
    """The Policy class of ``module:Class`` or ``path/to/file.py:Class``; ValueError/TypeError naming the rule.

    A file is imported once per process under a module name made from its
    absolute path (``admmkit_rule_<hash>``), so that records and pickles refer
    to the same class in every process.
    """
    target, _, cls_name = canonical_spec(spec).rpartition(":")
    if not target or not cls_name.isidentifier():
        raise ValueError(f"policy {spec!r}: give module:Class or path/to/file.py:Class")
    if target.endswith(".py"):
        path = Path(target)
        if not path.is_file():
            raise ValueError(f"policy {spec!r}: no such file {path}")
        modname = "admmkit_rule_" + hashlib.sha1(str(path).encode()).hexdigest()[:12]
        module = sys.modules.get(modname)
        if module is None:
            found = importlib.util.spec_from_file_location(modname, path)
            module = importlib.util.module_from_spec(found)
            sys.modules[modname] = module
            try:
                found.loader.exec_module(module)
            except KeyboardInterrupt:
                del sys.modules[modname]
                raise
            except BaseException as err:        # SystemExit too: a rule file must not end the program
                del sys.modules[modname]
                raise ValueError(f"policy {spec!r}: importing {path} failed: {raised(err)}") from None
    else:
        try:
            module = importlib.import_module(target)
        except KeyboardInterrupt:
            raise
        except BaseException as err:
            raise ValueError(f"policy {spec!r}: module {target!r} failed to import: {raised(err)}") from None
    if not hasattr(module, cls_name):
        raise ValueError(f"policy {spec!r}: {target} has no {cls_name!r}")
    return check_policy_class(getattr(module, cls_name), repr(spec))


def raised(err: BaseException) -> str:
    """What user code raised, in one phrase: ``SystemExit: sys.exit(0)`` or ``ZeroDivisionError: division by zero``."""
    if isinstance(err, SystemExit):
        return f"SystemExit: sys.exit({err.code!r}) (a rule must not end the program)"
    return f"{type(err).__name__}: {err}"


def check_policy_class(cls, what: str):
    """``cls`` if it is a :class:`Policy` subclass with a callable ``update``; TypeError naming ``what`` otherwise."""
    if not (isinstance(cls, type) and issubclass(cls, Policy)):
        raise TypeError(f"policy {what} is {cls!r}, not a subclass of admmkit.Policy")
    if getattr(cls, "__abstractmethods__", None):
        raise TypeError(f"policy {what} does not implement {', '.join(sorted(cls.__abstractmethods__))}() "
                        f"of the admmkit.Policy protocol")
    if not callable(getattr(cls, "update", None)):
        raise TypeError(f"policy {what}: update is not callable")
    return cls


def make_policy(name: str, **params) -> Policy:
    """Construct a policy with its parameters from a name (registered, or declared by an installed package in the
    entry-point group ``admmkit.policies``) or a spec ``module:Class`` / ``path/to/file.py:Class``."""
    if not isinstance(name, str):
        known = ", ".join(policy_names()) or "none registered"
        raise TypeError(f"policy name must be a string, one of: {known}; got {type(name).__name__}")
    if is_spec(name):
        cls = load_spec(name)
        try:
            return cls(**params)
        except (KeyboardInterrupt, TypeError, ValueError):      # a bad parameter names itself
            raise
        except BaseException as err:
            raise ValueError(f"policy {name!r}: {cls.__name__}() raised {raised(err)}") from None
    cls = _lookup(name.strip().lower().replace("-", "_"))
    if cls is None:
        known = ", ".join(policy_names()) or "none registered"
        raise ValueError(f"unknown policy {name!r}; known policies: {known}, or give module:Class or "
                         f"path/to/file.py:Class")
    return cls(**params)
