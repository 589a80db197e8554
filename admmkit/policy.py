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
"""
from __future__ import annotations

import inspect
from abc import ABC, abstractmethod
from importlib.metadata import entry_points
from typing import Callable

from .record import IterationRecord

_REGISTRY: dict[str, Callable[..., "Policy"]] = {}
#: the entry-point group in which an installed package names its rules (admmkit's own are in pyproject.toml)
GROUP = "admmkit.policies"


class Policy(ABC):
    """Base class of penalty rules."""

    #: record fields the rule reads that a problem might not provide
    #: (only "dual_residual" can be missing: order "xz" needs ``adjoint_norm``)
    requires: tuple[str, ...] = ()

    def reset(self, rho0: float) -> None:
        """Start a new run from rho0 (clear any state)."""
        self.rho0 = rho0

    @abstractmethod
    def update(self, rec: IterationRecord) -> float:
        """Return rho_{k+1} from the record of iteration k (``rec.rho`` is rho_k)."""

    def __repr__(self) -> str:
        names = [p for p in inspect.signature(type(self).__init__).parameters if p != "self"]
        params = ", ".join(f"{k}={getattr(self, k)!r}" for k in names if hasattr(self, k))
        return f"{type(self).__name__}({params})"


def register_policy(name: str):
    """Class decorator: make a policy constructible by name (``make_policy(name)``)."""

    def deco(cls):
        _REGISTRY[name] = cls
        cls.registered_name = name
        return cls

    return deco


def _declared() -> dict:
    """The rules installed packages declare in the entry-point group :data:`GROUP`, by name."""
    return {ep.name.strip().lower().replace("-", "_"): ep for ep in entry_points(group=GROUP)}


def policy_names() -> list[str]:
    """Names of the known policies: registered in this process, or declared by an installed package."""
    return sorted(set(_REGISTRY) | set(_declared()))


def _lookup(key: str):
    """The class registered or declared under ``key`` (loading its entry point on first use), or None."""
    if key not in _REGISTRY:
        declared = _declared().get(key)
        if declared is None:
            return None
        _REGISTRY[key] = declared.load()
    return _REGISTRY[key]


def make_policy(name: str, **params) -> Policy:
    """Construct a policy by name with its parameters (registered, or declared by an installed package)."""
    if not isinstance(name, str):
        known = ", ".join(policy_names()) or "none registered"
        raise TypeError(f"policy name must be a string, one of: {known}; got {type(name).__name__}")
    cls = _lookup(name.strip().lower().replace("-", "_"))
    if cls is None:
        known = ", ".join(policy_names()) or "none registered"
        raise ValueError(f"unknown policy {name!r}; known policies: {known}")
    return cls(**params)
