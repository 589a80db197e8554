"""Checks made once at the start of a run: arguments, starting point, and what the rules need."""
from __future__ import annotations

import math

import numpy as np

from .policy import Policy, make_policy
from .problem import Problem

ORDERS = {"xz": "xz", "zx": "zx", "admm1": "xz", "admm2": "zx"}
#: record fields that order "xz" can only give with ``Problem.adjoint_norm``
NEEDS_ADJOINT = ("dual_residual", "dual_scale", "dual_residual_rel")


class Fixed(Policy):
    """Keeps rho constant (used when no policy is given)."""

    def update(self, rec) -> float:
        """Return rho_k."""
        return rec.rho


#: the penalties admmkit accepts, from the user (rho_0) and from a policy (a rho outside ends the run as
#: diverged): 60 decades, wide enough for any unit system, narrow enough that rho * ||r|| cannot under- or
#: overflow silently (a rule returning 1e-300 or 1e300 has failed, whatever the iterates say)
RHO_RANGE = (1e-30, 1e30)


def rho_in_range(rho) -> bool:
    """Whether ``rho`` is a number in :data:`RHO_RANGE`."""
    return (isinstance(rho, (float, int, np.floating, np.integer)) and not isinstance(rho, bool)
            and RHO_RANGE[0] <= rho <= RHO_RANGE[1])


def check_rho(rho, name: str) -> float:
    """float(rho) if it is a number in :data:`RHO_RANGE`, else ValueError naming ``name``."""
    try:
        value = float(rho) if not isinstance(rho, (bool, str, bytes)) else math.nan
    except (TypeError, ValueError):
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {rho!r}")
    if not rho_in_range(value):
        raise ValueError(f"{name} must be in [{RHO_RANGE[0]:g}, {RHO_RANGE[1]:g}] (admmkit's rho range), got {rho!r}")
    return value


def check_order(order) -> str:
    """'xz' or 'zx' from an order name (also 'admm1', 'admm2')."""
    key = str(order).lower()
    if key not in ORDERS:
        raise ValueError(f"order must be 'xz' (ADMM1, x-step first) or 'zx' (ADMM2, z-step first), got {order!r}")
    return ORDERS[key]


def check_alpha(alpha) -> float:
    """The over-relaxation parameter, a number in (0, 2)."""
    try:
        value = float(alpha)
    except (TypeError, ValueError):
        value = math.nan
    if isinstance(alpha, bool) or not (0.0 < value < 2.0):
        raise ValueError(f"alpha must be a number in (0, 2) (1: no relaxation; OSQP uses 1.6), got {alpha!r}")
    return value


def check_int(name: str, value, low: int) -> int:
    """value if it is an integer >= low, else ValueError naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    return int(value)


def make(policy) -> Policy:
    """A Policy from an object, a registered name or None (fixed rho)."""
    if policy is None:
        return Fixed()
    if isinstance(policy, str):
        return make_policy(policy)
    if isinstance(policy, Policy):
        return policy
    raise TypeError(f"policy must be a Policy object, a registered name or None, got {type(policy).__name__}")


def starting_point(problem, x0, z0, lam0):
    """(x0, z0, lam0) as float arrays: the given ones (checked) or the problem's defaults."""
    own_start = type(problem).initial_point is not Problem.initial_point
    if x0 is None and not own_start and not isinstance(getattr(problem, "n", None), (int, np.integer)):
        raise TypeError(f"{type(problem).__name__} must set the attribute n (the number of x unknowns, an int) "
                        f"or override initial_point(), or solve() must be given x0")
    dx, dz, dlam = problem.initial_point()
    out = []
    for name, given, default in (("x0", x0, dx), ("z0", z0, dz), ("lam0", lam0, dlam)):
        if given is not None and np.iscomplexobj(given):
            raise ValueError(f"{name} must be real, got complex values")
        try:
            v = np.array(default if given is None else given, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be an array of numbers of shape {np.shape(default)}, got {given!r:.80}") from None
        if given is not None and v.shape != np.shape(default):
            raise ValueError(f"{name} must have shape {np.shape(default)}, got {v.shape}")
        if not np.all(np.isfinite(v)):
            raise ValueError(f"{name} must be finite")
        out.append(v)
    return out


def has_adjoint(problem, z) -> bool:
    """Whether ``problem.adjoint_norm`` is implemented."""
    try:
        problem.adjoint_norm(np.zeros_like(z))
    except NotImplementedError:
        return False
    return True


def check_requirements(problem, order: str, adjoint: bool, parts) -> None:
    """Refuse a run whose stopping rule or policy reads a quantity the problem cannot give.

    ``parts`` is a sequence of (role, object) with ``object.requires`` a tuple
    of record field names.  The only such quantities today are those built on
    Boyd's dual residual in order "xz", which need ``adjoint_norm``.
    """
    if order != "xz" or adjoint:
        return
    for role, obj in parts:
        missing = [name for name in getattr(obj, "requires", ()) if name in NEEDS_ADJOINT]
        if missing:
            raise ValueError(
                f"{role} {obj!r} needs Boyd's dual residual (it reads {', '.join(missing)}), which in order 'xz' is "
                f"rho ||A^T M (z^(k+1) - z^k)||: implement {type(problem).__name__}.adjoint_norm(y) to return "
                f"||A^T M y|| (a float, in the dual norm of the x space; the Euclidean norm for x in R^n), "
                f"or give A as an admmkit.operators.LinearMap (which derives it), or use order 'zx'"
                + (", or pass stop=admmkit.RelativeChange(...)" if role == "stop" else ""))
