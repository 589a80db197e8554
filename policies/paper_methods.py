"""The paper's three named methods, defined once: each is an update order and a penalty rule.

- ``admm1``: order "xz" with a fixed rho (Koko 2020, the paper's reference [8]);
- ``admm2``: order "zx" with a fixed rho (the paper's Algorithm 1);
- ``sadmm``: order "zx" with the summable rule, tau = 2, c_max = 100 (Algorithm 2, eq. (17)).

Every caller (the contact plug-in, the command line, the benchmarks) builds
them through :func:`method`, which also accepts any registered rule name and a
rule's class as ``module:Class`` or ``path/to/file.py:Class`` (in the order given,
default "zx").
"""
from __future__ import annotations

from admmkit import Policy, make_policy, policy_names
from admmkit.policy import canonical_spec, is_spec

from .fixed import Fixed
from .summable import Summable

#: name -> (order, rule factory)
PAPER_METHODS = {
    "admm1": ("xz", lambda: Fixed()),
    "admm2": ("zx", lambda: Fixed()),
    "sadmm": ("zx", lambda: Summable(tau=2.0, c_max=100)),
}
#: display names
LABELS = {"admm1": "ADMM1", "admm2": "ADMM2", "sadmm": "SADMM"}
#: (registered rule name, order) of each paper method, for labelling sweeps over every rule
PAPER_NAMES = {("fixed", "xz"): "admm1", ("fixed", "zx"): "admm2", ("summable", "zx"): "sadmm"}


def method(name: str, order: str | None = None) -> tuple[str, Policy]:
    """(order, fresh rule) of ``admm1``, ``admm2``, ``sadmm``, a registered rule name or a rule's class given as
    ``module:Class`` or ``path/to/file.py:Class``.

    A rule runs in ``order`` (default "zx"); for a paper method ``order``
    overrides the method's own order.
    """
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f"method must be a name: {', '.join(PAPER_METHODS)} or a registered rule "
                         f"({', '.join(policy_names())}), got {name!r}")
    if is_spec(name):                        # module:Class or path/to/file.py:Class, as --policy takes it everywhere
        return order or "zx", make_policy(canonical_spec(name))
    key = name.strip().lower().replace("-", "_")
    if key in PAPER_METHODS:
        own_order, make = PAPER_METHODS[key]
        return order or own_order, make()
    try:
        return order or "zx", make_policy(key)
    except ValueError:
        raise ValueError(f"unknown method {name!r}; methods: {', '.join(PAPER_METHODS)}, "
                         f"or a rule: {', '.join(policy_names())}") from None
