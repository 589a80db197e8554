"""Fields of an obstacle scene given as text: ``"sin(pi*x)*sin(pi*y)"``.

An expression is read by the contact plug-in's reader
(:func:`admmkit.problems.expressions.expression`, docs/scenes.md): x, y, numbers,
``+ - * / **`` (``^`` read as ``**``) and the functions of its ``FUNCTIONS``; any other name is refused
when the string is read.  The obstacle evaluates a field at many nodes at once, so :func:`field` adds
the same string on numpy arrays (numpy's functions) beside its NGSolve coefficient function.
``Expression.text`` keeps the string (a scene's repr and the JSON output show it).
"""
from __future__ import annotations

import math
from functools import reduce

import ngsolve as ng
import numpy as np

#: an expression's functions on numpy arrays (the names of the contact reader's FUNCTIONS)
NUMPY_FUNCTIONS = {"sqrt": np.sqrt, "sin": np.sin, "cos": np.cos, "tan": np.tan, "exp": np.exp, "log": np.log,
                   "atan": np.arctan, "abs": np.abs, "min": lambda *a: reduce(np.minimum, a),
                   "max": lambda *a: reduce(np.maximum, a), "pi": math.pi}


class Expression:
    """The expression ``text`` in x and y as a field g(x, y): on numpy arrays (and floats) with numpy's
    functions, on NGSolve coefficient functions (``ngsolve.x``, ``ngsolve.y``) with NGSolve's.

    ValueError for a syntax error or a name other than x, y and the allowed functions (the contact
    reader's check); a value that is not finite (``log(x)`` at x = 0) is left to the caller, as nan or inf.
    """

    def __init__(self, text: str):
        from admmkit.problems.expressions import expression     # the reader and its checks
        self.text = text
        self._on_coefficients = expression(text)
        self._code = compile(text.replace("^", "**"), "<expression>", "eval")    # checked by expression()

    def __call__(self, x, y):
        """The field at (x, y): numpy arrays or floats, or NGSolve coefficient functions."""
        if isinstance(x, ng.CoefficientFunction) or isinstance(y, ng.CoefficientFunction):
            return self._on_coefficients(x, y)
        with np.errstate(all="ignore"):             # nan / inf are reported by Scene.evaluate, naming the field
            return eval(self._code, {"__builtins__": {}},
                        NUMPY_FUNCTIONS | {"x": np.asarray(x, dtype=float), "y": np.asarray(y, dtype=float)})

    def __repr__(self) -> str:
        return repr(self.text)

    def __reduce__(self):
        """Pickled as its text (a scene sent to a worker process is read again there)."""
        return Expression, (self.text,)


def field(text: str) -> Expression:
    """An expression string in x and y read into a field g(x, y) (:class:`Expression`)."""
    return Expression(text)


__all__ = ["Expression", "field", "NUMPY_FUNCTIONS"]
