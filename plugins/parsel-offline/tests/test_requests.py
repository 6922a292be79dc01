"""The offline interpreter on requests as people write them: each kind of phrasing with a
hand-worked expectation, and the whole request table (both halves) as a regression guard."""

from __future__ import annotations

import importlib

import pytest

from parsel_core.examples import tiny_table
from parsel_core.language import describe_shape, infer
from parsel_core.language.describe import read_description
from parsel_core.loading import load_shape

offline = importlib.import_module("parsel_offline")
scoring = importlib.import_module("parsel_offline.scoring")
NotUnderstood, interpret = offline.NotUnderstood, offline.interpret


@pytest.fixture(scope="module")
def chair():
    return read_description(describe_shape(load_shape("chair")))


@pytest.fixture(scope="module")
def shelf():
    return read_description(describe_shape(load_shape("shelf")))


def ops(summary, request):
    return [(op.op, op.target, dict(op.dirs).get("dir") or dict(op.dirs).get("axis") or dict(op.dirs).get("normal"),
             op.amount) for op in interpret(summary, request).ops]


@pytest.mark.parametrize("request_text, expected", [
    ("the legs are too long", [("scale_1d", "leg.000", "y", "-0.5 * x")]),
    ("a less wide seat", [("scale_1d", "seat", "x", "-0.5 * x")]),
    ("the seat is too narrow for two people", [("scale_1d", "seat", "x", "x")]),
    ("this chair is too low", [("scale_1d", "leg.000", "y", "x")]),
    ("the legs are not long enough", [("scale_1d", "leg.000", "y", "x")]),
])
def test_too_and_less_with_plain_adjectives(chair, request_text, expected):
    assert ops(chair, request_text) == expected


@pytest.mark.parametrize("typo, word", [("cahir", "chair"), ("lgs", "legs"), ("sseat", "seat"), ("longr", "longer"),
                                        ("wdier", "wider")])
def test_typos_are_read_as_the_shapes_words_and_said_so(chair, typo, word):
    request = {"chair": f"make the {typo} wider", "legs": f"make the {typo} longer", "seat": f"make the {typo} deeper",
               "longer": f"make the legs {typo}", "wider": f"make the seat {typo}"}[word]
    reading = interpret(chair, request)
    assert len(reading.ops) == 1
    assert f"I read '{typo}' as '{word}'." in reading.reasons


def test_the_typo_matcher_loads_only_for_a_word_it_does_not_know(parsel_fresh_python):
    """rapidfuzz (about 15 ms of every ``parsel edit``) is imported at the first unknown word."""
    code = ("import sys\nfrom parsel_core.language import describe_shape\nfrom parsel_core.language.describe "
            "import read_description\nfrom parsel_core.loading import load_shape\nimport parsel_offline\n"
            "chair = read_description(describe_shape(load_shape('chair')))\n"
            "parsel_offline.interpret(chair, 'make the chair wider')\nprint('rapidfuzz' in sys.modules)\n"
            "parsel_offline.interpret(chair, 'make the chiar wider')\nprint('rapidfuzz' in sys.modules)")
    assert parsel_fresh_python(code).split() == ["False", "True"]


def test_a_word_too_far_from_any_is_refused_naming_it_with_a_phrasing(chair):
    with pytest.raises(NotUnderstood, match=r"I do not understand 'paint', 'red' in 'paint the legs red'; try a "
                                            r"phrasing such as 'make the back slats longer'"):
        interpret(chair, "paint the legs red")
    with pytest.raises(NotUnderstood, match="'lgx'"):
        interpret(chair, "make the lgx longer")  # two letters off a four-letter word: not a typo of it


@pytest.mark.parametrize("request_text, expected", [
    ("give the legs more height", [("scale_1d", "leg.000", "y", "x")]),
    ("keep the legs as they are and make the seat wider", [("scale_1d", "seat", "x", "x")]),
    ("I'd like the seat wider for my kids plz", [("scale_1d", "seat", "x", "x")]),
    ("hey, ur seat should be deeper i think", [("scale_1d", "seat", "z", "x")]),
    ("make the chair back taller", [("scale_1d", "back_upright.000", "y", "x")]),
    ("make the legs of the chair longer", [("scale_1d", "leg.000", "y", "x")]),
    ("stretch the seat from front to back", [("scale_1d", "seat", "z", "x")]),
    ("stretch the seat left to right", [("scale_1d", "seat", "x", "x")]),
    ("move the seat downward", [("translate", "seat", "-y", "0.225 * x")]),
    ("the seat, make it deeper", [("scale_1d", "seat", "z", "x")]),
    ("the legs - make them shorter", [("scale_1d", "leg.000", "y", "-0.5 * x")]),
    ("raise the chair", [("scale_1d", "leg.000", "y", "x")]),
    ("lower the chair", [("scale_1d", "leg.000", "y", "-0.5 * x")]),
    ("make the legs longer and taller", [("scale_1d", "leg.000", "y", "x")]),
    ("make the seat wider, a wider seat", [("scale_1d", "seat", "x", "x")]),
])
def test_idioms_context_objects_directions_topics_and_repeats(chair, request_text, expected):
    assert ops(chair, request_text) == expected


@pytest.mark.parametrize("request_text", ["make the legs in the back longer", "make the legs at the back longer",
                                          "make the back legs longer"])
def test_positions_as_qualifiers_pick_the_back_legs(chair, request_text):
    [op] = interpret(chair, request_text).ops
    assert op.target == "leg.002" and op.op == "scale_1d"


@pytest.mark.parametrize("request_text, amount", [
    ("make the legs a little longer", "0.25 * x"), ("make the legs slightly shorter", "-0.2 * x"),
    ("make the legs a lot longer", "2 * x"), ("make the legs much shorter", "-0.75 * x"),
    ("make the legs 20% longer", "0.2 * x"), ("make the legs 30 percent shorter", "-0.3 * x"),
    ("make the legs twice as long", "x"), ("make the legs three times as long", "2 * x"),
    ("make the legs half as long", "-0.5 * x"), ("double the length of the legs", "x"),
])
def test_degree_words_set_the_amount(chair, request_text, amount):
    [op] = interpret(chair, request_text).ops
    assert (op.op, op.target, op.amount) == ("scale_1d", "leg.000", amount)


def test_degree_words_on_moves_and_turns(chair):
    [op] = interpret(chair, "move the seat up a bit").ops
    assert op.amount == "0.05625 * x", "a quarter of the default: 0.25 * 0.9 tall * 0.25"
    tilts = interpret(chair, "tilt the legs forward 15 degrees").ops
    assert [op.amount for op in tilts] == ["15 * pi / 180 * x"] * 2, "front and back pairs: tilting breaks their mirror"


def test_idioms_for_counts_and_spacing(shelf):
    assert ops(shelf, "squeeze in another board") == [("change_count", "translation_0", None, "x")]
    assert ops(shelf, "get rid of one of the boards") == [("change_count", "translation_0", None, "-x")]
    assert ops(shelf, "put the boards closer together") == [("change_delta", "translation_0", None, "-0.5 * x")]
    assert ops(shelf, "space the boards further apart") == [("change_delta", "translation_0", None, "x")]


def test_the_height_of_an_object_without_legs_is_its_tallest_part(shelf):
    assert ops(shelf, "lower the shelf") == [("scale_1d", "side_panel.000", "y", "-0.5 * x")]


def test_plugin_words_reach_the_offline_lexicon():
    table = tiny_table()
    result = infer(table, "twist the legs", provider="offline", mode="seed-only", samples=1)
    [op] = result.seed.ops
    assert (op.name, op.operand, op.axis) == ("twist", "leg_bl", (0.0, 1.0, 0.0))
    assert op.origin == tuple(table.parts["leg_bl"].hexahedron.corners.mean(axis=0))


def test_the_must_show_request(chair):
    """'make the legs of the chair a little longer': one scale of the legs along y, once."""
    result = infer(load_shape("chair"), "make the legs of the chair a little longer", provider="offline", samples=1)
    [op] = result.seed.ops
    assert (op.name, op.operand, op.dir, op.amount) == ("scale_1d", "leg.000", (0.0, 1.0, 0.0), "0.25 * x")


@pytest.mark.parametrize("half, floor", [("development", 0.95), ("held-out", 0.90)])
def test_the_request_table(half, floor):
    """Every request of the table: none crashes, every refusal has a reason, and the share of
    requests whose ops are all right stays above the floor."""
    cases = scoring.read_cases(scoring.HALVES[half])
    assert len(cases) >= 100
    outcomes = scoring.run_cases(cases)
    assert [o.crashed for o in outcomes if o.crashed] == []
    assert all("cannot turn this request into an edit: " in o.refused for o in outcomes if o.refused)
    assert scoring.accuracy(outcomes, "all") >= floor
    assert all(o.refused for o in outcomes if not o.case.expected), "requests that should be refused are"


def test_scoring_reads_expectations_and_counts_one_edit_per_symmetric_set(tmp_path):
    from parsel_core.ops import Scale1D

    chair_shape = load_shape("chair")
    [case] = scoring.read_cases(_table(tmp_path, "too\tchair\tthe legs are too long\tscale_1d leg y -"))
    leg = Scale1D("leg.000", "-0.5 * x", origin=(0, 0, 0), dir=(0, 1, 0))
    twin = Scale1D("leg.001", "-0.5 * x", origin=(0, 0, 0), dir=(0, 1, 0))
    assert scoring.score(case, [leg], chair_shape)["all"]
    assert not scoring.score(case, [leg, twin], chair_shape)["all"], "leg.001 mirrors leg.000: the edit twice"
    grow = Scale1D("leg.000", "x", origin=(0, 0, 0), dir=(0, 1, 0))
    assert scoring.score(case, [grow], chair_shape) == {"op": True, "part": True, "axis": True, "sign": False,
                                                        "all": False}
    with pytest.raises(Exception, match=r"bad.tsv:1: expected 4 tab-separated fields"):
        scoring.read_cases(_table(tmp_path, "too\tchair\tno expectation", name="bad.tsv"))


def _table(tmp_path, line, name="t.tsv"):
    path = tmp_path / name
    path.write_text(line + "\n", encoding="utf-8")
    return path


def _networkx_components(summary, parts, broken=()):
    import networkx as nx

    graph = nx.Graph()
    graph.add_nodes_from(parts)
    for relation in summary.relations.values():
        if relation.kind in ("reflection", "translation", "rotation") and set(relation.members) <= set(parts) \
                and relation.id not in broken:
            graph.add_edges_from((relation.members[0], m) for m in relation.members[1:])
    return sorted(tuple(sorted(c)) for c in nx.connected_components(graph))


def test_symmetric_sets_are_the_connected_components_of_the_symmetries(chair, shelf):
    from parsel_offline.interpreter import Interpreter

    reader = Interpreter(chair)
    everything = [p for ids in chair.labels().values() for p in ids]
    assert reader.components(everything) == [
        ("back_rail",), tuple(f"back_slat.00{i}" for i in range(5)), ("back_upright.000", "back_upright.001"),
        ("leg.000", "leg.001", "leg.002", "leg.003"), ("seat",)]
    for summary in (chair, shelf):
        reader = Interpreter(summary)
        labelled = [list(ids) for ids in summary.labels().values()]
        everything = [p for ids in labelled for p in ids]
        symmetries = [r.id for r in summary.relations.values() if r.kind in ("reflection", "translation", "rotation")]
        for parts in [*labelled, everything, everything[::2]]:
            for broken in ((), tuple(symmetries[::2]), tuple(symmetries)):
                reader.broken = set(broken)
                assert reader.components(parts) == _networkx_components(summary, parts, broken), (parts, broken)
