"""Elementwise ``sin``, ``cos`` and ``sqrt`` for operator authors.

An operator's ``transform(points, amount, math)`` runs on three kinds of values: floats
and float arrays (numeric evaluation, batched over slider samples), numpy object arrays
of CAS expressions (the symbolic path edit propagation solves on), and single CAS
expressions. numpy's ufuncs handle the first kind but not object arrays of sympy or
symengine expressions, and a CAS's ``sin`` takes one expression, not an array. The
functions here take any of them, entry by entry, so one ``transform`` serves every path.

The engine passes this module as ``math`` on the symbolic path (numeric callers pass
numpy, whose ``sin``/``cos``/``sqrt`` agree), so ``math.sin(angle)`` works everywhere;
authors may also import the functions directly::

    from parsel_core.opmath import cos, sin

A CAS expression's function is looked up on the top-level module of its type
(``sympy.sin`` for sympy expressions, ``symengine.sin`` for symengine ones), so any CAS
whose package exposes these names works without the core importing it.
"""

from __future__ import annotations

import importlib
import math as _math
from functools import cache
from typing import Any

import numpy as np

__all__ = ["FUNCTIONS", "cos", "sin", "sqrt"]

#: The functions an operator may use, by name.
FUNCTIONS = ("sin", "cos", "sqrt")


@cache
def _cas_function(module_name: str, name: str) -> Any:
    try:
        function = getattr(importlib.import_module(module_name), name)
    except (ImportError, AttributeError):
        raise TypeError(f"{name}: values of package {module_name!r} are neither numbers nor CAS expressions "
                        f"with a {module_name}.{name}") from None
    return function


def _scalar(name: str, value: Any) -> Any:
    if isinstance(value, (bool, int, float, np.number)):
        return getattr(np, name)(value) if isinstance(value, np.number) else getattr(_math, name)(value)
    module_name = type(value).__module__.partition(".")[0]
    return _cas_function(module_name, name)(value)


def _apply(name: str, values: Any) -> Any:
    if isinstance(values, np.ndarray):
        if values.dtype == object:
            return np.frompyfunc(lambda v: _scalar(name, v), 1, 1)(values)
        return getattr(np, name)(values)
    return _scalar(name, values)


def sin(values: Any) -> Any:
    """Sine of a float, a numpy array (float or object) or a CAS expression, entry by entry."""
    return _apply("sin", values)


def cos(values: Any) -> Any:
    """Cosine of a float, a numpy array (float or object) or a CAS expression, entry by entry."""
    return _apply("cos", values)


def sqrt(values: Any) -> Any:
    """Square root of a float, a numpy array (float or object) or a CAS expression, entry by entry."""
    return _apply("sqrt", values)
