"""Stopping rules that compose: ``RelativeChange(1e-5) | ResidualTolerance(1e-8, 1e-6)``.

A rule is called with the iteration record and returns its name (``rule.name``:
it fired, the run has converged), a :class:`Stop` (the run ends with another
status, such as ``primal_infeasible`` with its certificate), or None (go on).
Anything else (True, 42, another text) is refused at once with a TypeError
naming the rule's class (:func:`verdict`): a rule that fired by mistake would
otherwise end the run as ``converged``.
``a | b`` fires when either fires, ``a & b`` when both do.  The iteration cap
(``max_iter``) is a parameter of :func:`admmkit.solve`.
"""
from __future__ import annotations

import math

from .record import IterationRecord
from .result import Status


class Stop(str):
    """A stopping rule's verdict other than "converged": ``Stop(name, status, certificate)``.

    It is the rule's name (a ``str``, so it reads as one wherever a name is
    expected) with a terminal ``status`` (an :class:`admmkit.Status`, e.g.
    ``Status.PRIMAL_INFEASIBLE``) and an optional ``certificate`` vector that
    :func:`admmkit.solve` puts on the result.
    """

    def __new__(cls, name: str, status: Status | str, certificate=None):
        self = super().__new__(cls, name)
        self.status = Status(status)
        self.certificate = certificate
        return self

    def __repr__(self) -> str:
        return f"Stop({str(self)!r}, {self.status.value!r})"


class StoppingRule:
    """Base class: subclasses implement :meth:`fired`.

    ``requires`` names the record fields the rule reads that a problem may be
    unable to give (``"dual_residual"``, ``"dual_scale"``: order "xz" needs
    ``Problem.adjoint_norm``); :func:`admmkit.solve` refuses to start a run
    that cannot provide them.  ``tolerance`` is the accuracy the rule asks for,
    against which the result's KKT check is made (None: no check).
    """

    name = "rule"
    requires: tuple[str, ...] = ()
    tolerance: float | None = None

    def fired(self, rec: IterationRecord) -> str | None:
        """Return ``self.name`` if the rule fires at this record (or a :class:`Stop`), else None."""
        raise NotImplementedError

    def fired_names(self) -> tuple[str, ...]:
        """The names :meth:`fired` may return besides a :class:`Stop`: the rule's own ``name``."""
        return (self.name,)

    def __or__(self, other: "StoppingRule") -> "AnyOf":
        return AnyOf(self, other)

    def __and__(self, other: "StoppingRule") -> "AllOf":
        return AllOf(self, other)

    def __repr__(self) -> str:
        return self.name


def verdict(rule: StoppingRule, answer):
    """``answer``, what ``rule.fired`` returned, if it is one of the rule's :meth:`~StoppingRule.fired_names`, a
    :class:`Stop` or None; else a TypeError naming the rule's class and the answer."""
    if answer is None or isinstance(answer, Stop) or (isinstance(answer, str) and answer in rule.fired_names()):
        return answer
    raise TypeError(f"stopping rule {type(rule).__name__}.fired() returned {type(answer).__name__} {answer!r:.60}; "
                    f"it must return the rule's name {rule.name!r} when it fires, an admmkit.Stop to end the run "
                    f"with another status, or None")


def _number(name: str, value, low: str) -> float:
    """float(value), or ValueError naming the parameter and its range (``low`` is "> 0" or ">= 0")."""
    try:
        number = float(value) if not isinstance(value, (bool, str, bytes)) else math.nan
    except (TypeError, ValueError):
        number = math.nan
    if not (math.isfinite(number) and (number > 0 if low == "> 0" else number >= 0)):
        raise ValueError(f"{name} must be a finite number {low}, got {value!r}")
    return number


def _positive(name: str, value) -> float:
    return _number(name, value, "> 0")


class RelativeChange(StoppingRule):
    """The paper's rule (section 4): ||x^{k+1} - x^k||_X <= tol ||x^{k+1}||_X."""

    def __init__(self, tol: float = 1e-5):
        self.tol = _positive("tol", tol)
        self.tolerance = self.tol
        self.name = f"relative_change(tol={self.tol:g})"

    def fired(self, rec: IterationRecord) -> str | None:
        """Fire when the relative change of x is at most ``tol``."""
        return self.name if rec.x_change <= self.tol * rec.x_norm else None


class ResidualTolerance(StoppingRule):
    """Boyd et al. (2011) eq. (3.12), in the problem's norms.

    ||r||_M <= eps_pri  = primal_unit eps_abs + eps_rel max(||Ax||_M, ||z||_M, ||c||_M)
    ||s||   <= eps_dual = dual_unit eps_abs + eps_rel dual_scale

    The default rule of :func:`admmkit.solve` is :func:`default_stop`,
    ``ResidualTolerance(1e-6, 1e-5)``.  Its ``tolerance`` (for the KKT check of
    the result) is max(eps_abs, eps_rel).
    """

    requires = ("dual_residual", "dual_scale")

    def __init__(self, eps_abs: float = 1e-6, eps_rel: float = 1e-4):
        self.eps_abs = _number("eps_abs", eps_abs, ">= 0")
        self.eps_rel = _number("eps_rel", eps_rel, ">= 0")
        if self.eps_abs == 0 and self.eps_rel == 0:
            raise ValueError("eps_abs and eps_rel cannot both be 0 (the rule could never fire)")
        self.tolerance = max(self.eps_abs, self.eps_rel)
        self.name = f"residual(eps_abs={self.eps_abs:g}, eps_rel={self.eps_rel:g})"

    def fired(self, rec: IterationRecord) -> str | None:
        """Fire when both residuals are below their tolerances."""
        eps_pri = rec.primal_unit * self.eps_abs + self.eps_rel * rec.primal_scale
        eps_dual = rec.dual_unit * self.eps_abs + self.eps_rel * rec.dual_scale
        ok = rec.primal_residual <= eps_pri and rec.dual_residual <= eps_dual
        return self.name if ok else None


def default_stop() -> "ResidualTolerance":
    """The stopping rule of :func:`admmkit.solve` when none is given: Boyd's residuals, eps_abs 1e-6, eps_rel 1e-5.

    (The paper's ``RelativeChange(1e-5)`` was the default before; the paper's
    contact methods still pass it explicitly.)
    """
    return ResidualTolerance(1e-6, 1e-5)


class AnyOf(StoppingRule):
    """Fires when any of its rules fires (the first one's name is reported)."""

    def __init__(self, *rules: StoppingRule):
        self.rules = _check_rules(rules)
        self.name = " | ".join(r.name for r in self.rules)
        self.requires, self.tolerance = _combined(self.rules)

    def fired(self, rec: IterationRecord) -> str | None:
        """The name (or :class:`Stop`) of the first rule that fires, or None."""
        for rule in self.rules:
            name = verdict(rule, rule.fired(rec))
            if name is not None:
                return name
        return None

    def fired_names(self) -> tuple[str, ...]:
        """The names of its rules (the one that fired is reported)."""
        return tuple(name for rule in self.rules for name in rule.fired_names())


class AllOf(StoppingRule):
    """Fires when all of its rules fire."""

    def __init__(self, *rules: StoppingRule):
        self.rules = _check_rules(rules)
        self.requires, self.tolerance = _combined(self.rules)
        self.name = " & ".join(f"({r.name})" if isinstance(r, AnyOf) else r.name for r in self.rules)

    def fired(self, rec: IterationRecord) -> str | None:
        """This rule's name if every rule fires (the first :class:`Stop` among them if one gave one), else None."""
        verdicts = [verdict(rule, rule.fired(rec)) for rule in self.rules]
        if any(v is None for v in verdicts):
            return None
        return next((v for v in verdicts if isinstance(v, Stop)), self.name)


def _check_rules(rules) -> tuple[StoppingRule, ...]:
    if not rules:
        raise ValueError("a composite stopping rule needs at least one rule")
    for r in rules:
        if not isinstance(r, StoppingRule):
            raise TypeError(f"stop rules must be StoppingRule objects, got {type(r).__name__}")
    return tuple(rules)


def _combined(rules) -> tuple[tuple[str, ...], float | None]:
    """The union of the rules' requirements and the loosest of their tolerances."""
    requires = tuple(dict.fromkeys(name for r in rules for name in r.requires))
    tols = [r.tolerance for r in rules if r.tolerance is not None]
    return requires, (max(tols) if tols else None)
