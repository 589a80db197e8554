"""The ADMM methods a benchmark runs: every registered penalty policy in both update orders.

The list is built from ``admmkit.policy_names()`` (every rule registered or declared by entry point),
so a rule that registers itself appears in every chart without a change here.
The paper's three methods keep their names:

- ``admm1`` = policy ``fixed``, order ``xz`` (Koko 2020),
- ``admm2`` = policy ``fixed``, order ``zx`` (the paper's Algorithm 1),
- ``sadmm`` = policy ``summable`` (tau = 2, c_max = 100, its defaults), order ``zx`` (Algorithm 2);

every other method is named ``<policy>/<order>``, e.g. ``residual_balancing/xz``.
A policy that cannot be built without arguments is left out and reported by
:func:`skipped_policies`.
"""
from __future__ import annotations

import admmkit
from admmkit.policy import canonical_spec, is_spec
from admmkit.policies.paper_methods import PAPER_NAMES

ORDERS = ("xz", "zx")
_PAPER_BY_NAME = {v: k for k, v in PAPER_NAMES.items()}


def method_label(policy: str, order: str) -> str:
    """admm1 / admm2 / sadmm for the paper's methods, else '<policy>/<order>'."""
    return PAPER_NAMES.get((policy, order), f"{policy}/{order}")


def _buildable(name: str) -> bool:
    try:
        admmkit.make_policy(name)
    except (TypeError, ValueError):
        return False
    return True


def admm_methods(orders=ORDERS) -> list[str]:
    """Labels of every buildable registered policy in each order: the paper's three first."""
    for order in orders:
        if order not in ORDERS:
            raise ValueError(f"orders must be a subset of {ORDERS}, got {order!r}")
    labels = [method_label(p, o) for p in admmkit.policy_names() if _buildable(p) for o in orders]
    first = [m for m in ("admm1", "admm2", "sadmm") if m in labels]
    return first + [m for m in labels if m not in first]


def skipped_policies() -> list[str]:
    """Registered policies that need constructor arguments (left out of the benchmarks)."""
    return [p for p in admmkit.policy_names() if not _buildable(p)]


def resolve(label: str) -> tuple[str, str]:
    """(policy name, order) of a method label."""
    if label in _PAPER_BY_NAME:
        return _PAPER_BY_NAME[label]
    policy, sep, order = label.rpartition("/")
    if sep and order in ORDERS and is_spec(policy):     # a rule from anywhere: path/to/file.py:Class/zx
        admmkit.make_policy(policy)                      # ValueError/TypeError naming the rule, before any case
        return canonical_spec(policy), order
    if not sep or order not in ORDERS or policy not in admmkit.policy_names():
        raise ValueError(f"unknown method {label!r}; methods: {', '.join(admm_methods())}, or "
                         f"module:Class/order or path/to/file.py:Class/order")
    return policy, order


def policy_version(label: str) -> str:
    """8 hex digits of the SHA-1 of the source file of the method's policy class.

    Part of every benchmark case, so that a resumed sweep re-runs the cases of
    a rule whose code changed since they ran.
    """
    import hashlib
    import inspect
    import sys

    policy, _ = make(label)
    try:
        source = inspect.getsource(sys.modules[type(policy).__module__])
    except (OSError, TypeError, KeyError):
        source = repr(policy)
    return hashlib.sha1(source.encode()).hexdigest()[:8]


def make(label: str) -> tuple[admmkit.Policy, str]:
    """(fresh policy object, order) of a method label."""
    policy, order = resolve(label)
    return admmkit.make_policy(policy), order
