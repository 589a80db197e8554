"""Coefficient functions of a scene given as text: ``"0.003*(x - 1.5)**2 + 0.001"``.

A gap, a traction component, a body force, a slip bound or a friction
coefficient may be a number, a Python callable f(x, y) (in 3D: of the
point (x, y) of the contact face z = 0) or an expression string.  An
expression may use x, y, numbers, + - * / ** and the functions in
:data:`FUNCTIONS`; ``^`` is read as ``**`` (FreeFEM's power, the paper's
tool: ``0.003*(x-1.5)^2`` is ``0.003*(x-1.5)**2``); it evaluates on floats (math) and on NGSolve
coefficient functions (ngsolve), so one string serves both the nodal values
(the gap at the contact nodes) and the assembled load (a traction integrated
by NGSolve).
"""
from __future__ import annotations

import builtins
import math
from typing import Callable

#: the functions (and the constant pi) an expression may use; the docs list them (docs/scenes.md)
FUNCTIONS = ("sqrt", "sin", "cos", "tan", "exp", "log", "atan", "abs", "min", "max", "pi")
_MATH = ("sqrt", "sin", "cos", "tan", "exp", "log", "atan")


def _cf_abs(a):
    import ngsolve
    return ngsolve.IfPos(a, a, -a) if isinstance(a, ngsolve.CoefficientFunction) else abs(a)


def _cf_min(*args):
    import ngsolve
    out = args[0]
    for b in args[1:]:
        out = ngsolve.IfPos(out - b, b, out) if isinstance(out - b, ngsolve.CoefficientFunction) else min(out, b)
    return out


def _cf_max(*args):
    import ngsolve
    out = args[0]
    for b in args[1:]:
        out = ngsolve.IfPos(out - b, out, b) if isinstance(out - b, ngsolve.CoefficientFunction) else max(out, b)
    return out


def expression(text: str) -> Callable:
    """Turn a string in x and y (e.g. ``"-10*exp(-x)"``, ``"0.003*(x-1.5)^2"``) into f(x, y).

    f works on floats (math's functions) and on NGSolve coefficient functions
    (ngsolve.x, ngsolve.y: ngsolve's functions; abs, min and max via IfPos).
    Names other than x, y and :data:`FUNCTIONS` are refused when the string is
    read, so attribute access and imports cannot be spelled.
    """
    if not isinstance(text, str):
        raise TypeError(f"expression must be a string, got {type(text).__name__}")
    try:
        code = compile(text.replace("^", "**"), "<expression>", "eval")   # FreeFEM's power, with its precedence
    except SyntaxError as err:
        raise ValueError(f"expression {text!r} is not valid Python syntax: {err.msg}") from None
    unknown = set(code.co_names) - set(FUNCTIONS) - {"x", "y"}
    if unknown:
        raise ValueError(f"expression {text!r} uses unknown names {sorted(unknown)}; "
                         f"allowed: x, y, {', '.join(FUNCTIONS)}")

    # every name the code may look up is checked above; __import__ is needed by pybind11 (ngsolve's
    # functions import numpy's type casters through the caller's builtins), and nothing in the
    # expression can reach it
    safe_builtins = {"__import__": builtins.__import__}

    def f(x, y):
        if isinstance(x, (int, float)) and isinstance(y, (int, float)):
            ns = {n: getattr(math, n) for n in _MATH} | {"abs": abs, "min": min, "max": max}
        else:
            import ngsolve
            ns = {n: getattr(ngsolve, n) for n in _MATH} | {"abs": _cf_abs, "min": _cf_min, "max": _cf_max}
        return eval(code, {"__builtins__": safe_builtins}, ns | {"pi": math.pi, "x": x, "y": y})

    f.expression = text
    return f


def as_function(value, name: str):
    """A number, a callable or an expression string -> a float or a callable f(x, y).

    Raises ValueError naming ``name`` for anything else (a bool, a list, None).
    """
    if isinstance(value, str):
        return expression(value)
    if callable(value):
        return value
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value)
    raise ValueError(f"{name} must be a number, a callable f(x, y) or an expression string, got {value!r}")


def finite_positive(value, name: str, accepted: str) -> None:
    """Raise ValueError unless value is a finite number > 0 (``accepted`` states the range)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise ValueError(f"{name} = {value!r} is outside the accepted range {accepted}")
