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


def test_linear_combination_is_the_shared_loops_expression():
    """The float fast path builds the same object as adding ``number(w) * t`` one at a time,
    including the cases where symengine's representation depends on the order: a constant
    cancelling to exactly 0.0 beside two symbolic terms (kept as a 0.0 coefficient) and
    beside one (dropped), zero products, integral weights, numpy floats and tiny weights."""
    from parsel_core.cas import CASBackend

    backend = get_cas_backend("symengine")
    x = backend.symbol("x")
    a, b = 0.25 + 1.5 * x, -0.75 + 0.5 * x
    cases = [
        ([0.5, 2.5, 3.5, -0.5], [1.0, a, b, 1.0]),          # constant cancels, two terms stay
        ([0.5, 2.5, -0.5, 3.5], [1.0, a, 1.0, b]),          # constant cancels beside one term
        ([0.3, 0.7, 1.1], [0.0, 2.0, -0.0]),                  # zero products
        ([0.3, 0.7], [0.0, -0.0]),
        ([2.5, 3.5, 0.3], [a, b, 0.0]),
        ([1.0, -1.0, 2.0, 0.1], [a, 4.5, b, 3.25]),           # integral weights
        ([1e-16, 0.2, 0.4], [a, np.float64(0.3), 7.0]),       # a tiny weight, a numpy float
        ([0.1] * 40, [0.1 * k if k % 3 else a for k in range(40)]),
        ([], []),
    ]
    rng = np.random.default_rng(3)
    terms = [float(v) if i % 4 else v * x + 1.0 for i, v in enumerate(rng.normal(size=60))]
    cases.append((list(rng.normal(size=60)), terms))
    for weights, terms in cases:
        expected = CASBackend.linear_combination(backend, weights, terms)
        got = backend.linear_combination(weights, terms)
        assert got == expected and str(got) == str(expected) and type(got) is type(expected)
