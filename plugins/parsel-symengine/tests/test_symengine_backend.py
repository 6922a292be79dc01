"""symengine-specific behaviour: polynomial solving, no trigonometric solver, fast compile."""

import numpy as np

from parsel_core.plugins import get_cas_backend


def test_registered_and_named():
    assert get_cas_backend("symengine").name == "symengine"


def test_polynomial_roots_and_unsolvable_trig():
    backend = get_cas_backend("symengine")
    f, x = backend.symbol("f"), backend.symbol("x")
    roots = backend.solve(f * f - x, "f")
    assert sorted(backend.to_float(backend.subs(r, {"x": 4.0})) for r in roots) == [-2.0, 2.0]
    assert backend.solve(backend.functions()["cos"](f) - x, "f") == []


def test_compile_many_expressions_over_a_batch():
    backend = get_cas_backend("symengine")
    x, y = backend.symbol("x"), backend.symbol("y")
    function = backend.compile(["x", "y"], [x + y, x * y, x - y])
    out = function(np.array([1.0, 2.0]), np.array([3.0, 4.0]))
    assert out.shape == (3, 2) and np.allclose(out, [[4, 6], [3, 8], [-2, -2]])
