"""Penalty (rho) rules for admmkit, one module per rule.

A built-in rule is named in one place only: its line in the entry-point group
``admmkit.policies`` of ``pyproject.toml``, ``name = "admmkit.policies.<file>:<Class>"``
(docs/policies.md lists them with their files, classes and papers).  From that
line ``admmkit.make_policy(name)``, ``--policy name`` and the sweeps over
:func:`admmkit.policy_names` find the rule, loading its module on first use;
``from admmkit.policies import Summable`` loads the class the same way.  Nothing
is imported for its side effect: no rule needs importing before it is named.
"""
from __future__ import annotations

import functools
import importlib
import warnings

from admmkit.policy import declared_rules, own_rules

#: class names kept for a while after a rename: {old: new}; the old one still works, with a DeprecationWarning
RENAMED = {"Spectral": "AADMM"}


def builtin_rules() -> dict[str, tuple[str, str]]:
    """The built-in rules: ``{name: (module, Class)}``, read from the entry-point group ``admmkit.policies``."""
    return dict(_builtin_rules())


@functools.lru_cache(maxsize=1)
def _builtin_rules() -> dict[str, tuple[str, str]]:
    """:func:`builtin_rules`, read once per process from admmkit's own distribution (``own_rules``; every
    installed package's entry points only where admmkit is not installed): scanning them all takes 20-80 ms,
    and ``from admmkit.policies import OSQPRule`` runs on every QP solve (a small QP's whole solve took 70 ms
    instead of 3 with a scan each time)."""
    rules = {}
    for name, point in (own_rules() or declared_rules()).items():     # admmkit's own distribution: 1 ms, not 20
        module, _, cls = point.value.partition(":")
        if module.startswith(__name__ + "."):
            rules[name] = (module, cls.strip())
    return rules


def __getattr__(attr: str):
    """The class ``attr`` of a built-in rule (``admmkit.policies.Summable``), imported on first use."""
    if attr in RENAMED:
        warnings.warn(f"admmkit.policies.{attr} is now admmkit.policies.{RENAMED[attr]}",
                      DeprecationWarning, stacklevel=2)
        return __getattr__(RENAMED[attr])
    for module, cls in _builtin_rules().values():
        if cls == attr:
            value = globals()[attr] = getattr(importlib.import_module(module), cls)   # later lookups: no search
            return value
    if attr in ("PAPER_METHODS", "method"):
        return getattr(importlib.import_module(f"{__name__}.paper_methods"), attr)
    raise AttributeError(f"module {__name__!r} has no attribute {attr!r}")


def __dir__() -> list[str]:
    """The module's names with the rules' classes (for completion and the API reference)."""
    return sorted(set(globals()) | set(__all__))


__all__ = sorted({cls for _, cls in builtin_rules().values()}) + ["PAPER_METHODS", "method", "builtin_rules"]
