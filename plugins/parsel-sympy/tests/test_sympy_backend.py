"""sympy-specific behaviour: the general solver handles trigonometric constraints."""

import math

import pytest

from parsel_core.errors import ProgramFormatError
from parsel_core.plugins import get_cas_backend


def test_registered_and_named():
    assert get_cas_backend("sympy").name == "sympy"


def test_solves_a_rotation_constraint():
    # a handle point at distance 1 from a hinge rotated by f must reach height sin(x): sin(f) - sin(x) = 0
    backend = get_cas_backend("sympy")
    f, x = backend.symbol("f"), backend.symbol("x")
    solutions = backend.solve(backend.functions()["sin"](f) - backend.functions()["sin"](x), "f")
    values = {round(backend.to_float(backend.subs(s, {"x": 0.3})), 9) for s in solutions}
    assert 0.3 in values and round(math.pi - 0.3, 9) in values


def test_integers_stay_exact():
    backend = get_cas_backend("sympy")
    assert str(backend.parse("1/3 + x") - backend.symbol("x")) == "1/3"
    with pytest.raises(ProgramFormatError):
        backend.parse("import os")
