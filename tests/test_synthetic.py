"""Synthetic large assemblies: sizes as documented, relations exact at rest, solvable end to end."""

import numpy as np
import pytest

from parsel_core.graph import GROUP_KINDS
from parsel_core.interfaces import SolveRequest
from parsel_core.plugins import solvers
from parsel_core.program import evaluate
from parsel_core.report import check_program
from parsel_core.synthetic import GENERATORS, SEEDS, assembly, bookcase, long_table, stadium
from parsel_core.textform import seed_from_text


@pytest.mark.parametrize(("generator", "n", "parts", "relations"), [
    (bookcase, 2, 5, 11), (bookcase, 40, 43, 125),
    (stadium, 2, 5, 7), (stadium, 30, 61, 63),
    (long_table, 4, 5, 12), (long_table, 40, 41, 102),
])
def test_sizes_follow_the_documented_formulas(generator, n, parts, relations):
    shape = generator(n)
    assert (len(shape.parts), len(shape.relations)) == (parts, relations)


@pytest.mark.parametrize("name", sorted(GENERATORS))
def test_every_relation_holds_at_rest(name):
    shape = assembly(name, 30)
    corners = shape.rest_corners()
    for relation in shape.relations.values():
        assert np.abs(relation.residual(corners)).max() < 1e-9, relation.id
    groups = [r for r in shape.relations.values() if r.kind in GROUP_KINDS]
    assert groups and all(len(g.members) >= 2 for g in groups)


@pytest.mark.parametrize(("name", "parts"), [("bookcase", 500), ("stadium", 500), ("long_table", 500),
                                             ("bookcase", 100)])
def test_assembly_gives_about_the_parts_asked_for(name, parts):
    assert abs(len(assembly(name, parts).parts) - parts) <= 2


def test_bad_sizes_are_refused():
    with pytest.raises(ValueError, match="n >= 2"):
        bookcase(1)
    with pytest.raises(ValueError, match="even number"):
        long_table(7)
    with pytest.raises(ValueError, match="unknown synthetic assembly"):
        assembly("sofa", 10)


@pytest.mark.parametrize("name", sorted(GENERATORS))
def test_the_seed_edit_propagates_and_keeps_every_relation(name):
    shape = assembly(name, 15)
    result = solvers()["aep"].run(SolveRequest(shape, seed_from_text(SEEDS[name]), {}, (), {}))
    assert check_program(shape, result.program, ()).counts()["broken"] == 0
    rest, edited = shape.rest_corners(), evaluate(result.program, shape, {"x": 0.5}).parts
    moved = [pid for pid in shape.parts if not np.allclose(edited[pid], rest[pid])]
    assert len(moved) > len(shape.parts) // 2  # the seed widens or raises most of the shape
