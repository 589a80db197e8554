"""What the wrapper rules share: resolving the wrapped rule from a name or an object."""
from __future__ import annotations

from admmkit import Policy, make_policy


def as_policy(inner, name: str = "inner") -> Policy:
    """A Policy object from a Policy or a registered name; ValueError naming ``name`` otherwise."""
    if isinstance(inner, Policy):
        return inner
    if isinstance(inner, str):
        return make_policy(inner)
    raise ValueError(f"{name} must be a Policy or a registered policy name, got {type(inner).__name__}")
