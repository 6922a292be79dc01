"""The solver's fast paths give the same numbers, to the last bit, as the plain ones.

Candidates are applied in batches (screening._apply_all), broken relations are looked up
per pattern, per-relation maxima are taken by segments, candidate lists are cached and
the joint pass remembers the systems it has solved; none of these may change a program
(benchmarks/bench_aep_speed.py checks whole programs against a baseline revision).
"""

import dataclasses
import itertools

import numpy as np
import pytest

from parsel_aep import candidates, cluster, screening
from parsel_core.hexahedron import EDGE_NAMES, FACE_NAMES, Hexahedron
from parsel_core.ops import Rotate, Scale1D, Scale2D, Scale3D, Shear, Translate


def skewed_box(rng) -> Hexahedron:
    """A box turned about a random axis, with its corners jittered (not quite a box)."""
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    unit = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    corners = (unit * rng.uniform(0.05, 0.5, 3)) @ q + rng.normal(size=3)
    return Hexahedron(corners + rng.normal(scale=1e-3, size=(8, 3)))


def random_ops(rng, count: int) -> list:
    out = []
    for _ in range(count):
        kind = int(rng.integers(6))
        o = tuple(float(v) for v in rng.normal(size=3))
        d = tuple(float(v) for v in rng.normal(size=3))
        e = tuple(float(v) for v in np.cross(d, rng.normal(size=3)))
        feature = [None, None, FACE_NAMES[int(rng.integers(6))], EDGE_NAMES[int(rng.integers(12))]][
            int(rng.integers(4))]
        if kind == 0:
            out.append(Translate("p", "f", dir=d, feature=feature))
        elif kind == 1:
            out.append(Rotate("p", "f", origin=o, axis=d))
        elif kind == 2:
            out.append(Scale1D("p", "f", origin=o, dir=d, feature=feature if feature in FACE_NAMES else None))
        elif kind == 3:
            out.append(Scale2D("p", "f", origin=o, normal=d))
        elif kind == 4:
            out.append(Scale3D("p", "f", origin=o))
        else:
            out.append(Shear("p", "f", origin=o, normal=d, dir=e))
    return out


class Anchor:
    """An op the batches do not know (like propagate.AnchorScale): applied on its own."""

    name, feature, acts_on = "scale_1d", None, "part"

    def apply(self, corners, amount, math):
        return corners * (1 + amount)


@pytest.mark.parametrize("amount", [1.0, 0.0, np.pi / 2, np.pi])
@pytest.mark.parametrize("seed", range(4))
def test_batched_application_is_bitwise_the_ops_own(seed, amount):
    rng = np.random.default_rng(seed)
    rest = skewed_box(rng).corners
    ops = random_ops(rng, 60)
    ops.insert(7, Anchor())
    batched = screening._apply_all(ops, rest, amount)
    plain = np.stack([op.apply(rest, amount, screening.NUMPY_MATH) for op in ops])
    assert batched.shape == plain.shape
    assert batched.tobytes() == plain.tobytes()


@pytest.mark.parametrize("seed", range(4))
def test_ops_applied_each_at_its_own_amount_are_bitwise_the_ops_own(seed):
    rng = np.random.default_rng(seed)
    rest = skewed_box(rng).corners
    ops = random_ops(rng, 60)
    ops.insert(7, Anchor())
    amounts = rng.normal(size=len(ops)) * rng.choice([1e-6, 1.0, 100.0], size=len(ops))
    each = screening.apply_each(ops, rest, amounts)
    plain = np.stack([op.apply(rest, float(a), np) for op, a in zip(ops, amounts)])
    assert each.tobytes() == plain.tobytes()


def test_rotations_applied_each_at_its_own_angle_are_bitwise_the_ops_own():
    """apply_each batches rotations too, each angle's sine and cosine taken on its own:
    hundreds of angles, small and large, about faces, edges and whole parts."""
    rng = np.random.default_rng(11)
    rest = skewed_box(rng).corners
    features = [None, *FACE_NAMES, *EDGE_NAMES]
    ops = [Rotate("p", "f", origin=tuple(float(v) for v in rng.normal(size=3)),
                  axis=tuple(float(v) for v in rng.normal(size=3)), feature=features[i % len(features)])
           for i in range(400)]
    amounts = rng.normal(size=len(ops)) * rng.choice([1e-9, 1e-3, 1.0, 50.0, 1e6], size=len(ops))
    each = screening.apply_each(ops, rest, amounts)
    plain = np.stack([op.apply(rest, float(a), np) for op, a in zip(ops, amounts)])
    assert each.tobytes() == plain.tobytes()


@pytest.mark.parametrize("seed", range(3))
def test_candidate_lists_are_the_same_built_lazily_and_cached(seed):
    rng = np.random.default_rng(seed)
    box = skewed_box(rng)
    for hint in (None, "translate", "scale", "rotate"):
        first = candidates.own_candidates("p", box, hint)
        again = candidates.own_candidates("p", box, hint)
        assert first == again and first is not again
        # the merge of the original generator: every op built, the first of each key kept
        assert first == reference_own_candidates("p", box, hint)


def flat_and_aligned_boxes(rng) -> list[Hexahedron]:
    """Boxes whose feature points share heights, planes and positions: an axis-aligned box
    (three directions), a board thinner than the keys round (coincident points) and one turned about
    a single axis."""
    board = Hexahedron.from_bounds((0.1, 0.4, -0.3), (0.9, 0.4 + 1e-9, 0.3))
    turn = np.array([[np.cos(0.3), 0.0, -np.sin(0.3)], [0.0, 1.0, 0.0], [np.sin(0.3), 0.0, np.cos(0.3)]])
    return [Hexahedron.from_bounds(rng.normal(size=3), rng.normal(size=3) + 2.0), board,
            Hexahedron(Hexahedron.from_bounds((-0.2, 0.0, -0.1), (0.2, 0.7, 0.1)).corners @ turn.T)]


@pytest.mark.parametrize("seed", range(2))
def test_candidates_of_boxes_with_shared_features_merge_as_before(seed):
    rng = np.random.default_rng(seed)
    boxes = flat_and_aligned_boxes(rng)
    for box in boxes:
        for hint in (None, "scale"):
            got = candidates._own_candidates("p", box, hint)
            assert got == reference_own_candidates("p", box, hint)
            assert [vars(op) for op in got] == [vars(op) for op in reference_own_candidates("p", box, hint)]
    about = list(candidates._about_neighbours("p", boxes).values())
    assert about == reference_neighbour_candidates("p", boxes[0], [], boxes)
    assert [vars(op) for op in about] == [vars(op) for op in reference_neighbour_candidates("p", boxes[0], [], boxes)]


def test_candidates_of_a_class_built_by_its_constructor_are_the_same(monkeypatch):
    """A class whose ops the fast path cannot build as its constructor does (here: marked
    so) is built by the constructor; the lists stay the same."""
    rng = np.random.default_rng(7)
    box, neighbours = skewed_box(rng), [skewed_box(rng), flat_and_aligned_boxes(rng)[1]]
    want_own = reference_own_candidates("p", box, None)
    want_about = reference_neighbour_candidates("p", box, [], neighbours)
    monkeypatch.setattr(candidates, "_ABOUT", {})
    built = []
    for cls in (Scale1D, Rotate):
        candidates._own_fields(cls)  # (the layout is known first)
        monkeypatch.setitem(candidates._LAYOUT, cls, (candidates._LAYOUT[cls][0], False))
        monkeypatch.setattr(cls, "__post_init__", lambda op, check=cls.__post_init__: built.append(op) or check(op))
    assert candidates._own_candidates("p", box, None) == want_own
    assert len(built) == sum(type(op) in (Scale1D, Rotate) for op in want_own)  # each by its constructor
    built.clear()
    assert list(candidates._about_neighbours("p", neighbours).values()) == want_about
    assert len(built) >= sum(type(op) in (Scale1D, Rotate) for op in want_about)


def test_points_that_are_not_finite_are_refused_as_the_constructor_refuses_them():
    from parsel_core.errors import ProgramFormatError

    assert candidates._points([[0.5, -0.0, 1e-13]]) == [(0.5, 0.0, 0.0)]
    with pytest.raises(ProgramFormatError, match="finite"):
        candidates._points([[0.5, np.nan, 0.0]])


def reference_own_candidates(part, hexahedron, hint):
    """own_candidates as first written (every op constructed, then merged)."""
    import itertools  # noqa: F401

    from parsel_core.hexahedron import feature_corners

    _key, _vec = candidates._key, candidates._vec
    points = hexahedron.feature_points
    dirs = candidates.directions(hexahedron)
    out = {}

    def add(key, op):
        out.setdefault(key, op)

    for d in dirs:
        add(("translate", _key(d)), Translate(part, "f", dir=_vec(d)))
    for n in dirs:
        for p in points:
            add(("scale_1d", _key(n), round(float(p @ n), 7)), Scale1D(part, "f", origin=_vec(p), dir=_vec(n)))
            in_plane = p - (p @ n) * n
            add(("scale_2d", _key(n), _key(in_plane)), Scale2D(part, "f", origin=_vec(p), normal=_vec(n)))
            add(("rotate", _key(n), _key(in_plane)), Rotate(part, "f", origin=_vec(p), axis=_vec(n)))
        for d in dirs:
            if abs(float(n @ d)) > 1e-6:
                continue
            for p in points:
                add(("shear", _key(n), _key(d), round(float(p @ n), 7)),
                    Shear(part, "f", origin=_vec(p), normal=_vec(n), dir=_vec(d)))
    for p in points:
        add(("scale_3d", _key(p)), Scale3D(part, "f", origin=_vec(p)))
    corners = hexahedron.corners
    for face in FACE_NAMES:
        face_points = corners[list(feature_corners(face))]
        normal = hexahedron.face_normal(face)
        for d in dirs:
            add(("face_translate", face, _key(d)), Translate(part, "f", feature=face, dir=_vec(d)))
            if abs(float(d @ normal)) > 0.9:
                continue
            for p in np.concatenate([face_points, face_points.mean(axis=0, keepdims=True)]):
                add(("face_scale", face, _key(d), round(float(p @ d), 7)),
                    Scale1D(part, "f", feature=face, origin=_vec(p), dir=_vec(d)))
    for edge in EDGE_NAMES:
        for d in dirs:
            add(("edge_translate", edge, _key(d)), Translate(part, "f", feature=edge, dir=_vec(d)))
    ops = list(out.values())
    if hint in candidates.HINT_TYPES:
        ops = [op for op in ops if candidates.candidate_family(op) in candidates.HINT_TYPES[hint]]
    return ops


def test_neighbour_candidates_merge_as_before():
    rng = np.random.default_rng(5)
    box, neighbours = skewed_box(rng), [skewed_box(rng), skewed_box(rng)]
    got = candidates.neighbour_candidates("p", box, [], neighbours)
    want = reference_neighbour_candidates("p", box, [], neighbours)
    assert got == want and [vars(op) for op in got] == [vars(op) for op in want]


def reference_screen(candidates, moving, others, constraints, tolerance, per_constraint=False):
    """Screening as it was: a Screened object for every row, broken ids and error totals
    row by row."""
    system = screening._system(candidates, moving, others, constraints)
    allowed = np.maximum(tolerance, system.rest_errors)

    def ids(errors):
        return tuple(system.ids[i] for i in np.flatnonzero(~(errors < allowed)))

    def made(op, index, f, errors, kind, a, offset):
        broken = ids(errors)
        finite = errors[np.isfinite(errors)]
        cost = 0.0 if not broken else float(finite.sum()) if len(finite) == len(errors) else float("inf")
        return screening.Screened(op, index, f, broken, kind, a, offset, errors, cost)

    results = []
    for columns in system.slices if per_constraint else [slice(None)]:
        if system.affine:
            f, usable = screening._affine_amounts(system.r0, system.slope, columns)
            errors = screening.relation_max_errors(f[:, :, None] * system.slope[:, None, :] + system.r0,
                                                   system.slices)
            for n in np.flatnonzero(usable):
                index, op = system.affine[n]
                results.append(made(op, index, f[n], errors[n], "affine", system.slope[n], system.r0))
        if system.rotations:
            f, usable = screening._rotation_amounts_batch(system, columns)
            residual = (system.matrix @ np.stack([np.cos(f), np.sin(f)], axis=1)).transpose(0, 2, 1)
            residual += system.r0
            residual -= system.offset[:, None, :]
            errors = screening.relation_max_errors(residual, system.slices)
            for n in np.flatnonzero(usable):
                index, op = system.rotations[n]
                results.append(made(op, index, f[n], errors[n], "rotation", system.matrix[n], system.offset[n]))
        for index, compound, slopes in system.compounds or ():
            f = compound_amounts_alone(system.r0, slopes, columns)
            errors = screening.relation_max_errors((system.r0 + f @ slopes)[None], system.slices)[0]
            if np.all(np.isfinite(errors)):
                results.append(made(compound, index, f, errors, "compound", slopes, system.r0))
    results.sort(key=(lambda s: (s.index, len(s.broken))) if per_constraint else (lambda s: s.index))
    return results


def compound_amounts_alone(r0: np.ndarray, slopes: np.ndarray, columns) -> np.ndarray:
    """One compound's basis amounts (S, B) from its own solve: the reference for the
    stacked solves of screening._compound_amounts_each."""
    return -(screening.compound_solver(slopes, columns) @ r0[:, columns].T).T


def same_screened(a, b) -> bool:
    return (a.op is b.op and a.index == b.index and a.kind == b.kind and a.broken == b.broken
            and a.f.tobytes() == b.f.tobytes() and a.a.tobytes() == b.a.tobytes()
            and a.offset.tobytes() == b.offset.tobytes() and a.errors.tobytes() == b.errors.tobytes()
            and (a.cost == b.cost or (np.isnan(a.cost) and np.isnan(b.cost))))


FIXTURE_REQUESTS = [
    ("chair_1746.txt", "scale_1d('Program_1/cube0', origin=(0.0, -0.7, 0.0), dir=(0, 1, 0), amount=0.5*x)"),
    ("chair_2436.txt", "translate(cube1, dir=(0, 1, 0), amount=0.2*x)"),
    ("chair_42394.txt", "scale_1d(cube1, origin=(0.3, 0.0, 0.0), dir=(0, 0, 1), amount=x)"),
    ("table_23034.txt", "scale_1d(cube1, origin=(0.0, 0.3575, 0.0), dir=(1, 0, 0), amount=x)"),
]


def solve_fixtures():
    from pathlib import Path

    from parsel_aep.propagate import propagate
    from parsel_core import Program
    from parsel_core.interfaces import SolveRequest
    from parsel_core.loading import load_shape

    fixtures = Path(__file__).parent / "fixtures"
    for name, seed in FIXTURE_REQUESTS:
        propagate(SolveRequest(load_shape(str(fixtures / name)), Program.from_text(seed)))


def test_screen_tables_hold_every_row_of_plain_screening(monkeypatch):
    """Screening keeps its results as arrays and makes Screened objects only for the rows a
    search reads, takes the rows of candidates a search screened before from its memo, and
    (searches for valid candidates) stops checking a candidate at its first broken
    constraint; every valid row, their order, broken ids and error totals must be those of
    screening every candidate afresh and making them all, and every other row must still
    count as broken. (Breaking-edits: breaking.py, tested below.)"""
    from parsel_aep import propagate as propagate_module

    table_of = screening.screen_table
    seen = {"plain": 0, "rows": 0, "reused": 0, "cut short": 0}

    def both(candidates, moving, others, constraints, tolerance, memo=None, valid_only=False):
        known = {key for rows in (memo or {}).values() for key in rows if key is not None}
        reused = any(id(op) in known for op in candidates)
        table = table_of(candidates, moving, others, constraints, tolerance, memo, valid_only)
        want = reference_screen(candidates, moving, others, constraints, tolerance)
        got = [table.screened(i) for i in table.order]
        assert len(got) == len(want)
        for i, g, w in zip(table.order, got, want):
            if valid_only and w.broken:  # checked only until its first broken constraint
                assert g.op is w.op and table.nbroken[i] >= 1 and g.broken and set(g.broken) <= set(w.broken)
                continue
            assert same_screened(g, w)
            assert table.nbroken[i] == len(g.broken) and table.index[i] == g.index
            assert table.cost[i] == g.cost and table.finite[i] == bool(np.all(np.isfinite(g.f)))
        seen["plain"] += 1
        seen["rows"] += len(got)
        seen["reused"] += reused
        seen["cut short"] += sum(len(g.broken) < len(w.broken) for g, w in zip(got, want))
        return table

    monkeypatch.setattr(propagate_module, "screen_table", both)
    solve_fixtures()
    assert seen["plain"] > 20 and seen["rows"] > 1000
    assert seen["reused"] > 2  # rows a search had screened before, taken from its memo
    assert seen["cut short"] > 100  # candidates no longer checked after a broken constraint


@pytest.mark.parametrize("sizes", [(3, 0, 5, 1, 0), (0, 0, 2), (4,), ()])
def test_segment_maxima_are_the_slice_maxima(sizes):
    rng = np.random.default_rng(len(sizes))
    slices, start = [], 0
    for size in sizes:
        slices.append(slice(start, start + size))
        start += size
    values = rng.uniform(0, 1, start)
    if start > 2:
        values[1] = np.nan
    got = screening.slice_maxima(values, slices)
    want = np.array([values[s].max(initial=0.0) for s in slices])
    assert got.tobytes() == want.tobytes()


@pytest.mark.parametrize("seed", range(6))
def test_compounds_solved_together_are_bitwise_each_solved_alone(seed):
    """Compounds of mixed basis sizes (and a zero one, and rank-deficient ones) solved in
    stacked calls give each compound's amounts as its own solve does, in its place."""
    rng = np.random.default_rng(seed)
    k, samples = 30, 5
    r0 = rng.normal(size=(samples, k))
    slopes = []
    for size in rng.integers(1, 7, size=7):
        s = rng.normal(size=(size, k)) * 10.0 ** rng.uniform(-3, 3)
        if size > 2 and rng.uniform() < 0.5:
            s[-1] = s[0] * 2.0  # a dependent basis op
        slopes.append(s)
    slopes.append(np.zeros((3, k)))
    for columns in (slice(None), slice(4, 10), slice(7, 7)):
        got = screening._compound_amounts_each(r0, slopes, columns)
        want = [compound_amounts_alone(r0, s, columns) for s in slopes]
        assert [f.shape for f in got] == [f.shape for f in want]
        assert all(a.tobytes() == b.tobytes() for a, b in zip(got, want))


def test_solver_reuses_a_system_it_has_solved():
    rng = np.random.default_rng(0)
    b, k = 12, 30
    system = cluster.ClusterSystem(("p",), (), (slice(0, b),), (), (slice(0, k),), rng.normal(size=(5, k)),
                                   rng.normal(size=(b, k)), rng.uniform(0.1, 1, b), np.ones(b), np.ones(1))
    columns = np.arange(k)
    rows = rng.uniform(0.5, 2, k)
    first = cluster.solver(system, columns, rows)
    again = cluster.solver(system, columns, rows.copy())
    assert again is first and not first.flags.writeable
    assert cluster.solver(fresh_copy(system), columns, rows).tobytes() == first.tobytes()
    other = cluster.solver(system, columns, rows * 2)
    assert other is not first


# -- the joint pass decides with fast numerics and solves exactly --------------------------

def random_system(rng, parts: int = 4, constraints: int = 14, samples: int = 5, rank_loss: int = 0,
                  conflict: float = 0.0) -> "cluster.ClusterSystem":
    """A joint system of ``parts`` boxes (6 basis amounts each) and ``constraints`` relations
    of 1-3 residual columns; ``rank_loss`` basis amounts repeat others (a rank-deficient
    system); ``conflict`` adds residuals no amount can meet (relations to give up)."""
    b = 6 * parts
    sizes = rng.integers(1, 4, constraints)
    slices, start = [], 0
    for size in sizes:
        slices.append(slice(start, start + int(size)))
        start += int(size)
    k = start
    slopes = rng.normal(size=(b, k)) * (rng.random((b, k)) < 0.4)
    for i in range(rank_loss):
        slopes[b - 1 - i] = slopes[i] * 0.5
    x = np.linspace(0, 1, samples)[:, None]
    f_true = rng.normal(size=(1, b)) * 0.1
    r0 = -(x * f_true) @ slopes + conflict * x * rng.normal(size=(1, k)) * (rng.random(k) < 0.2)
    allowances = np.full(constraints, 1e-3)
    return cluster.ClusterSystem(tuple(f"p{i}" for i in range(parts)), (), tuple(slice(6 * i, 6 * i + 6)
                                 for i in range(parts)), tuple(range(constraints)), tuple(slices), r0, slopes,
                                 rng.uniform(0.01, 1, b), np.tile([2.0, 2.0, 2.0, 1.0, 1.0, 1.0], parts),
                                 allowances)


def exact_solve(system):
    """solve() as first written: every decision on the exact solver."""
    everything = list(range(len(system.constraints)))
    best = None
    for start in (everything, None):
        if start is None:
            start = cluster._sparse_breaks(system)
        f, matrix, kept = cluster._drop_until_kept(system, start)
        errors = cluster.relation_errors(system, f) / system.allowances
        score = (-len(kept), float(np.sum(errors[errors >= 1.0])))
        if best is None or score < best[0]:
            best = (score, f, matrix, kept)
        if len(kept) == len(everything):
            break
    _, f, matrix, kept = best
    sparse = cluster.sparsify(system, kept, f)
    if sparse is not None:
        f, matrix = sparse
    return f, matrix, kept


def fresh_copy(system):
    """The same system without the matrices it has solved."""
    return cluster.ClusterSystem(*(getattr(system, f) for f in ("parts", "compounds", "blocks", "constraints",
                                                                 "slices", "r0", "slopes", "weights", "costs",
                                                                 "allowances")))


def assert_solve_is_the_exact_solve(system):
    f, matrix, kept = cluster.solve(system)
    f0, matrix0, kept0 = exact_solve(fresh_copy(system))
    assert kept == kept0
    assert matrix.tobytes() == matrix0.tobytes() and f.tobytes() == f0.tobytes()


@pytest.mark.parametrize("seed", range(12))
def test_solve_with_fast_decisions_is_bitwise_the_exact_solve(seed):
    rng = np.random.default_rng(seed)
    system = random_system(rng, rank_loss=seed % 3, conflict=[0.0, 0.05, 1.0][seed % 3])
    assert_solve_is_the_exact_solve(system)


def test_fast_decisions_too_close_to_call_are_refused():
    system = random_system(np.random.default_rng(3))
    fast, exact = cluster._Numerics(system, fast=True), cluster._Numerics(system, fast=False)
    values, limits = np.array([0.5, 1.0 - 1e-9]), np.array([1.0, 1.0])
    assert list(exact.below(values, limits)) == [True, True]
    with pytest.raises(cluster._Borderline):
        fast.below(values, limits)
    with pytest.raises(cluster._Borderline):
        fast.below(np.array([np.nan]), 1.0)
    assert fast.worst([(3.0, 0), (2.0, 1)]) == (3.0, 0)
    with pytest.raises(cluster._Borderline):
        fast.worst([(3.0, 0), (3.0 * (1 - 1e-9), 1)])
    assert exact.worst([(3.0, 0), (3.0, 1)]) == (3.0, 1)
    with pytest.raises(cluster._Borderline):
        fast.less(1.0, 1.0 + 1e-12)


@pytest.mark.parametrize("shape", [(40, 12), (12, 40), (30, 30), (1, 5), (5, 1)])
@pytest.mark.parametrize("rank", [None, 1, 3])
def test_guarded_lstsq_agrees_with_numpy_pinv(shape, rank):
    rng = np.random.default_rng(sum(shape) * 10 + (rank or 0))
    a = rng.normal(size=shape)
    if rank is not None and rank < min(shape):  # rank-deficient: the minimum-norm solution
        a = rng.normal(size=(shape[0], rank)) @ rng.normal(size=(rank, shape[1]))
    b = rng.normal(size=(shape[0], 7))
    got = cluster._guarded_lstsq(a, b, 1e-9, 1e-4)
    want = np.linalg.pinv(a, rcond=1e-9) @ b
    assert np.allclose(got, want, rtol=1e-9, atol=1e-11 * np.abs(want).max())
    zero = cluster._guarded_lstsq(np.zeros(shape), b, 1e-9, 1e-4)
    assert zero.shape == (shape[1], 7) and not zero.any()
    assert cluster._guarded_lstsq(np.zeros((0, 3)), np.zeros((0, 7)), 1e-9, 1e-4).shape == (3, 7)


def test_guarded_lstsq_refuses_a_singular_value_at_the_cutoff():
    rng = np.random.default_rng(1)
    u, _ = np.linalg.qr(rng.normal(size=(8, 4)))
    v, _ = np.linalg.qr(rng.normal(size=(4, 4)))
    b = rng.normal(size=(8, 3))
    a = u @ np.diag([1.0, 0.5, 1e-3, 1e-9 * (1 + 1e-6)]) @ v.T
    with pytest.raises(cluster._Borderline):
        cluster._guarded_lstsq(a, b, 1e-9, 1e-4)
    a = u @ np.diag([1.0, 0.5, 1e-3, 1e-7]) @ v.T
    assert np.allclose(cluster._guarded_lstsq(a, b, 1e-9, 1e-4), np.linalg.pinv(a, rcond=1e-9) @ b, rtol=1e-6)


@pytest.mark.parametrize("shape", [(40, 12), (300, 60), (12, 12)])
def test_conditioned_lstsq_is_the_least_squares_solution(shape):
    rng = np.random.default_rng(shape[0])
    a = rng.normal(size=shape) * (rng.random(shape) < 0.3) + np.eye(*shape)  # sparse, full column rank
    b = rng.normal(size=(shape[0], 17))
    got = cluster._conditioned_lstsq(a, b)
    want = np.linalg.lstsq(a, b, rcond=1e-9)[0]
    assert got is not None and np.allclose(got, want, rtol=1e-10, atol=1e-12 * np.abs(want).max())


@pytest.mark.parametrize("wrappers", [True, False])
def test_conditioned_lstsq_declines_what_it_cannot_prove(wrappers, monkeypatch):
    """With scipy's LAPACK wrappers (potrf, posv, potrs) and with numpy's Cholesky and LU
    solves where they cannot be loaded: the same proofs, the same solutions."""
    if not wrappers:
        monkeypatch.setattr(cluster, "lapack_wrappers", lambda: None)
    elif cluster.lapack_wrappers() is None:
        pytest.skip("scipy's LAPACK wrappers are not available")
    rng = np.random.default_rng(2)
    u, _ = np.linalg.qr(rng.normal(size=(30, 6)))
    v, _ = np.linalg.qr(rng.normal(size=(6, 6)))
    b = rng.normal(size=(30, 3))
    a = u @ np.diag([1, 1, 1, 1, 1, 1e-3]) @ v.T
    got = cluster._conditioned_lstsq(a, b)
    assert got is not None and np.allclose(got, np.linalg.pinv(a, rcond=1e-9) @ b, rtol=1e-11, atol=1e-13)
    for smallest in (1e-7, 1e-12, 0.0):  # near or at pinv's cutoff: left to the SVD
        assert cluster._conditioned_lstsq(u @ np.diag([1, 1, 1, 1, 1, smallest]) @ v.T, b) is None
    assert cluster._conditioned_lstsq(rng.normal(size=(4, 6)), rng.normal(size=(4, 3))) is None  # wide
    assert cluster._conditioned_lstsq(np.zeros((30, 6)), b) is None
    assert cluster._conditioned_lstsq(np.full((30, 6), np.nan), b) is None


def test_positive_definite_is_choleskys_verdict():
    rng = np.random.default_rng(5)
    q, _ = np.linalg.qr(rng.normal(size=(8, 8)))
    for smallest in (1.0, 1e-8, 0.0, -1e-8, -1.0):
        m = q @ np.diag([3.0, 2, 2, 1, 1, 1, 0.5, smallest]) @ q.T
        m = (m + m.T) / 2
        try:
            np.linalg.cholesky(m)
            want = True
        except np.linalg.LinAlgError:
            want = False
        copy = m.copy()
        assert cluster._positive_definite(m) is want
        assert np.array_equal(m, copy)  # (the caller's matrix is left as it was)


@pytest.mark.parametrize("seed", range(6))
def test_determined_amounts_give_the_reweighted_sparse_prior(seed):
    """FOCUSS's reweighting is skipped when the kept constraints determine every amount
    (fast numerics proved full column rank); its prior is then the one reweighting gives."""
    rng = np.random.default_rng(seed)
    system = random_system(rng, parts=2, constraints=40, rank_loss=seed % 2)
    f_true = rng.normal(size=len(system.weights)) * (rng.random(len(system.weights)) < 0.5)  # few amounts needed
    system = dataclasses.replace(system, r0=-np.linspace(0, 1, 5)[:, None] * f_true @ system.slopes, solved={})
    kept = list(range(len(system.constraints)))
    columns, rows = cluster._columns(system, kept), cluster._row_weights(system, kept)
    fast = cluster._Numerics(system, fast=True)
    f = fast.amounts(columns, rows)
    assert fast.determined(columns, rows) == (seed % 2 == 0)  # a repeated amount: not determined
    exact = cluster._Numerics(fresh_copy(system), fast=False)
    want = cluster._focuss(system, kept, exact.amounts(columns, rows), 12, exact)
    got = cluster._sparse_prior(system, kept, f, 12, fast)
    assert (got is None) == (want is None)
    assert want is not None and 0 < np.count_nonzero(want) < len(want)
    assert got.tobytes() == want.tobytes()


def test_fast_amounts_agree_with_the_exact_solver():
    rng = np.random.default_rng(4)
    system = random_system(rng, rank_loss=2)
    fast, exact = cluster._Numerics(system, fast=True), cluster._Numerics(system, fast=False)
    columns = np.arange(system.r0.shape[1])
    rows = rng.uniform(0.5, 2.0, len(columns))
    prior = system.prior * (rng.random(len(system.weights)) < 0.7)  # some amounts left out
    for args in ((columns,), (columns, rows), (columns, rows, prior), (columns[:9], rows[:9], prior)):
        got, want = fast.amounts(*args), exact.amounts(*args)
        assert np.allclose(got, want, rtol=1e-8, atol=1e-10 * np.abs(want).max())


@pytest.mark.parametrize("seed", range(6))
def test_tall_systems_decide_on_their_qr_and_solve_as_the_exact_solver(seed):
    """Many more residual columns than amounts: fast solves that differ only in the prior
    share one QR of the weighted system; the amounts agree with the exact solver's and the
    whole solve is still bitwise the exact one."""
    rng = np.random.default_rng(seed)
    system = random_system(rng, parts=2, constraints=40, rank_loss=seed % 3, conflict=[0.0, 0.05, 1.0][seed % 3])
    fast, exact = cluster._Numerics(system, fast=True), cluster._Numerics(system, fast=False)
    columns = np.arange(system.r0.shape[1])
    rows = rng.uniform(0.5, 2.0, len(columns))
    for _ in range(4):
        prior = system.prior * (rng.random(len(system.weights)) < 0.7)
        got, want = fast.amounts(columns, rows, prior), exact.amounts(columns, rows, prior)
        assert np.allclose(got, want, rtol=1e-8, atol=1e-10 * np.abs(want).max())
    assert [v is not None for v in fast.factored.values()] == [True]  # one QR for the last three
    assert_solve_is_the_exact_solve(system)


def reference_slopes(parts, hexahedra, rest, constraints, frame, shears, members):
    """build_system's slopes as first written: every constraint evaluated for every part."""
    def residuals(view):
        blocks = [np.asarray(r.residual(view), dtype=float) for r in constraints]
        lead = np.broadcast_shapes(*(b.shape[:-1] for b in blocks))
        return np.concatenate([np.broadcast_to(b, lead + b.shape[-1:]) for b in blocks], axis=-1)

    involved = {m for r in constraints for m in r.members}
    still = {m: rest[m][None] for m in involved}
    base = residuals(still)[0]
    out = []
    for part in parts:
        compound = cluster.box_compound(part, hexahedra[part], frame, shears)
        targets = members.get(part, (part,))
        moved = {m: np.stack([op.apply(rest[m], 1.0, np) for op in compound.basis]) for m in targets}
        out.append(np.broadcast_to(residuals({**still, **moved}) - base, (compound.size, len(base))))
    return np.concatenate(out)


@pytest.mark.parametrize("frame, shears", [("local", False), ("local", True), ("world", True)])
def test_box_bases_are_built_once_per_part_box_and_variant(frame, shears):
    rng = np.random.default_rng(9)
    box, other = skewed_box(rng), skewed_box(rng)
    first = cluster.box_compound("p", box, frame, shears)
    assert cluster.box_compound("p", box, frame, shears) is first
    assert first == cluster._box_compound("p", box, frame, shears)  # what it remembers is what it builds
    assert cluster.box_compound("p", other, frame, shears) != first
    assert cluster.box_compound("q", box, frame, shears).basis[0].operand == "q"
    assert cluster.box_compound("p", box, frame, not shears) != first


@pytest.mark.parametrize("frame, shears", [("local", False), ("world", True)])
def test_joint_slopes_evaluate_only_the_constraints_a_part_moves(frame, shears):
    from parsel_core.loading import load_shape

    shape = load_shape("chair")
    rest = shape.rest_corners()
    parts = sorted(shape.parts)[:4]
    constraints = [r for r in shape.relations.values() if set(r.members) & set(parts)]
    corners = {m: np.broadcast_to(c, (3, 8, 3)) for m, c in rest.items()}
    hexahedra = {p: shape.part(p).hexahedron for p in parts}
    system = cluster.build_system(parts, hexahedra, rest, corners, constraints, 1e-4, frame, shears)
    want = reference_slopes(parts, hexahedra, rest, constraints, frame, shears, {})
    assert system.slopes.tobytes() == np.ascontiguousarray(want).tobytes()


def reference_neighbour_candidates(part, hexahedron, neighbour_ops, neighbour_hexahedra):
    """neighbour_candidates as first written (every op built, then merged)."""
    _vec = candidates._vec
    out = {}
    centre = hexahedron.center

    def add(op):
        out.setdefault((op.name, tuple(sorted(op.params().items()))), op)

    for op in neighbour_ops:
        params = dict(op.params())
        add(type(op)(part, "f", **params))
        origin = params.get("origin")
        if origin is not None and op.name.startswith("scale"):
            line = centre - np.asarray(origin)
            if np.linalg.norm(line) > 1e-9:
                add(Translate(part, "f", dir=_vec(line / np.linalg.norm(line))))
    for neighbour in neighbour_hexahedra:
        for n in candidates.directions(neighbour):
            for p in neighbour.feature_points:
                add(Rotate(part, "f", origin=_vec(p), axis=_vec(n)))
                add(Scale1D(part, "f", origin=_vec(p), dir=_vec(n)))
            add(Translate(part, "f", dir=_vec(n)))
        for p in neighbour.feature_points:
            add(Scale3D(part, "f", origin=_vec(p)))
    return list(out.values())


def test_neighbour_candidates_keep_the_borrowed_ops_first():
    rng = np.random.default_rng(6)
    box, neighbours = skewed_box(rng), [skewed_box(rng), skewed_box(rng)]
    p = candidates._vec(neighbours[0].feature_points[3])
    n = candidates._vec(candidates.directions(neighbours[0])[1])
    borrowed = [Scale1D("n0", "x", origin=p, dir=n), Rotate("n0", "x", origin=p, axis=n)]
    for ops in (borrowed, [], borrowed):  # computed, then cached
        got = candidates.neighbour_candidates("p", box, ops, neighbours)
        want = reference_neighbour_candidates("p", box, ops, neighbours)
        assert got == want and [type(op) for op in got] == [type(op) for op in want]


def eager_least_breaking(self, screened, constraints, rest):
    """The choice of a breaking-edit as first written: every row screened and ranked, the
    best ranked within 1% of the least error among the edits not too distorting."""
    rows = [s for s in screened if len(s.broken) < constraints and np.isfinite(s.cost)]
    ranked = self.rank(rows, rest)
    if not ranked:
        return None
    least = min(s.cost for s in ranked)
    return next(s for s in ranked if s.cost <= least * 1.01 + self.tolerance)


def test_breaking_edits_screened_lazily_are_those_of_screening_every_row(monkeypatch):
    """Breaking-edit searches bound every row's errors and evaluate only the rows the choice
    reads (breaking.py). Every bound must be at most the row's cost, every evaluated row
    must be bitwise the one of screening every candidate from each constraint afresh, in
    its order, and the choice must be the one ranking every screened row gives; most rows
    are never evaluated."""
    from parsel_aep import breaking
    from parsel_aep import propagate as propagate_module
    from parsel_aep.propagate import Propagation

    made = []
    table_of = breaking.breaking_table

    def recorded(candidates, moving, others, constraints, tolerance, memo=None):
        table = table_of(candidates, moving, others, constraints, tolerance, memo)
        made.append((table, reference_screen(candidates, moving, others, constraints, tolerance, True)))
        return table

    lazy = Propagation.least_breaking
    seen = {"searches": 0, "rows": 0, "evaluated": 0}

    def both(self, table, constraints, rest):
        eager = made[-1][1]
        want = eager_least_breaking(self, eager, constraints, rest)
        got = lazy(self, table, constraints, rest)
        assert (got is None) == (want is None)
        if want is not None:
            assert same_screened(got, want)
        seen["searches"] += 1
        seen["rows"] += len(table.index)
        seen["evaluated"] += int(table.known.sum())
        # every row, evaluated now, is the one screened afresh, in the same order
        assert table.bound.shape == table.cost.shape
        table.evaluate(np.arange(len(table.index)))
        assert np.all(table.bound[table.finite] <= table.cost[table.finite])
        order = np.lexsort((table.generated, table.nbroken, table.index))
        assert len(order) == len(eager)
        for i, w in zip(order, eager):
            assert same_screened(table.screened(i), w)
            assert table.nbroken[i] == len(w.broken) and table.cost[i] == w.cost
            assert table.finite[i] == bool(np.all(np.isfinite(w.f)))
        return got

    monkeypatch.setattr(propagate_module, "breaking_table", recorded)
    monkeypatch.setattr(Propagation, "least_breaking", both)
    solve_fixtures()
    assert seen["searches"] >= 3 and seen["rows"] > 1000
    assert seen["evaluated"] < 0.5 * seen["rows"]


def test_best_breaking_row_is_the_first_of_ranking_every_row(monkeypatch):
    """A breaking-edit search ranks the hundreds of rows within 1% of the least error as
    arrays and makes a Screened only of the best (Propagation.best_row); it must be the
    first of ranking them all as Screened objects (Propagation.rank), ties included: the
    rows are also ranked reversed and in a random order, and without the best."""
    from parsel_aep.propagate import Propagation

    fast = Propagation.best_row
    rng = np.random.default_rng(8)
    seen = {"calls": 0, "rows": 0}

    def first_ranked(self, table, rows, rest):
        ranked = self.rank([table.screened(i) for i in rows], rest)
        return ranked[0] if ranked else None

    def both(self, table, rows, rest):
        got = fast(self, table, rows, rest)
        orders = [rows, rows[::-1], rng.permutation(rows)]
        for order in orders:
            want = first_ranked(self, table, order, rest)
            found = fast(self, table, order, rest)
            assert (found is None) == (want is None)
            if want is not None:
                assert table.screened(found) is want
        if got is not None and len(rows) > 1:
            rest_rows = rows[rows != got]
            want = first_ranked(self, table, rest_rows, rest)
            found = fast(self, table, rest_rows, rest)
            assert (found is None) == (want is None) and (want is None or table.screened(found) is want)
        seen["calls"] += 1
        seen["rows"] += len(rows)
        return got

    monkeypatch.setattr(Propagation, "best_row", both)
    solve_fixtures()
    assert seen["calls"] >= 3 and seen["rows"] > 100


def test_joint_variants_come_in_the_order_solving_them_all_gives(monkeypatch):
    """The joint pass solves its variants lazily (propagate.best_clusters); they must come
    in the order of solving every variant and sorting them by score."""
    from parsel_aep.propagate import Propagation

    lazy = Propagation.best_clusters
    seen = {"rings": 0, "variants": 0, "solved for the first": 0}

    def both(self, state, variants):
        solved = [self.cluster_solve(state, *v) for v in variants]
        want = [(f.parts, f.score) for f in sorted((f for f in solved if f is not None), key=lambda f: f.score)]
        calls = []
        real = self.cluster_solve

        def counted(*args):
            calls.append(args)
            return real(*args)

        monkeypatch.setattr(self, "cluster_solve", counted, raising=False)
        ranked = lazy(self, state, variants)
        got = list(itertools.islice(ranked, 1))
        seen["solved for the first"] += len(calls)
        got += list(ranked)
        monkeypatch.delattr(self, "cluster_solve")
        assert [(f.parts, f.score) for f in got] == want
        seen["rings"] += 1
        seen["variants"] += len(variants)
        yield from got

    monkeypatch.setattr(Propagation, "best_clusters", both)
    solve_fixtures()
    assert seen["rings"] >= 2 and seen["variants"] > seen["rings"]
    assert seen["solved for the first"] < seen["variants"]  # the first came before all were solved


def test_remembered_corners_and_errors_are_those_evaluated_afresh(monkeypatch):
    """A run remembers programs' corners (whole, and each part's by the ops moving it) and
    relation errors by what they read; every answer, remembered or not, must be the fresh
    evaluation's, to the bit."""
    from parsel_aep import propagate as propagate_module
    from parsel_aep.propagate import Propagation
    from parsel_core.program import evaluate

    corners_of, error_of, parts_of = Propagation.corners, Propagation.error, Propagation.parts_of
    seen = {"corners": 0, "corners remembered": 0, "errors": 0, "errors remembered": 0, "parts": 0,
            "parts reused": 0}

    def parts(self, program):
        before = len(self._part_corners)
        got = parts_of(self, program)
        seen["parts"] += len(got)
        seen["parts reused"] += len(got) - (len(self._part_corners) - before)
        return got

    def corners(self, ops):
        remembered = tuple(map(id, ops)) in self._corners
        got = corners_of(self, ops)
        fresh = evaluate(self.program(ops), self.shape, {self.parameter.name: self.xs}).parts
        assert got.keys() == fresh.keys()
        assert all(got[p].tobytes() == fresh[p].tobytes() and not got[p].flags.writeable for p in got)
        seen["corners"] += 1
        seen["corners remembered"] += remembered
        return got

    def error(self, relation, corners, sliding=()):
        before = len(self._errors)
        got = error_of(self, relation, corners, sliding)
        allowance = relation.allowance(self.tolerance)
        full = propagate_module.relation_error(relation, corners, sliding)
        assert got == propagate_module.relation_error(relation, corners, sliding, below=allowance)
        assert (got < allowance) == (full < allowance) and (got == full or got < allowance)
        seen["errors"] += 1
        seen["errors remembered"] += len(self._errors) == before
        return got

    monkeypatch.setattr(Propagation, "corners", corners)
    monkeypatch.setattr(Propagation, "error", error)
    monkeypatch.setattr(Propagation, "parts_of", parts)
    solve_fixtures()
    assert seen["corners remembered"] > 5 and seen["errors remembered"] > seen["errors"] / 2
    assert seen["parts reused"] > seen["parts"] / 2  # (programs part by part, mostly reused)


def test_remembered_symbolic_corners_are_those_derived_afresh(monkeypatch):
    """The derivations read decided parts' symbolic corners, remembered part by part by the
    ops moving them: every answer must print as the whole program's symbolic corners."""
    from parsel_aep.propagate import Propagation
    from parsel_core.program import symbolic_corners

    symbolic_of = Propagation.symbolic_parts
    seen = {"parts": 0, "reused": 0, "whole": 0}

    def symbolic(self, ops, only):
        before = len(self._symbolic)
        got = symbolic_of(self, ops, only)
        fresh = symbolic_corners(self.program(ops), self.shape, self.backend, only=only)
        assert got.keys() == fresh.keys()
        for pid in got:
            assert np.asarray(got[pid]).dtype == np.asarray(fresh[pid]).dtype
            assert [str(e) for e in np.ravel(got[pid])] == [str(e) for e in np.ravel(fresh[pid])], pid
        moved = [pid for pid in got if np.asarray(got[pid]).dtype == object]
        seen["parts"] += len(moved)
        seen["reused"] += len(moved) - (len(self._symbolic) - before)
        seen["whole"] += any(op.acts_on != "part" for op in ops)
        return got

    monkeypatch.setattr(Propagation, "symbolic_parts", symbolic)
    solve_fixtures()
    assert seen["parts"] > 20 and seen["reused"] > seen["parts"] / 3


def test_symbolic_corners_of_a_part_follow_its_ops():
    """Remembered by the ops moving each part: another op on a part (the same count), an op
    on its group and a program with a group layout each give the whole program's corners."""
    from parsel_aep.propagate import Propagation
    from parsel_core import Program
    from parsel_core.interfaces import SolveRequest
    from parsel_core.loading import load_shape
    from parsel_core.ops import ChangeCount
    from parsel_core.program import symbolic_corners

    shape = load_shape("shelf")
    group = next(g for g, r in shape.relations.items() if r.kind == "translation")
    board, other = shape.relations[group].members[0], next(p for p in sorted(shape.parts)
                                                         if p not in shape.relations[group].members)
    run = Propagation(SolveRequest(shape, Program.from_text(f"translate({other!r}, dir=(0, 1, 0), amount=x)")))
    run.params = run.parameter
    first = [Translate(other, "0.5*x", dir=(0, 1, 0)), Scale1D(board, "x", origin=(0, 0, 0), dir=(1, 0, 0))]
    programs = [first, [first[0], Scale1D(board, "2*x", origin=(0, 0, 0), dir=(1, 0, 0))],
                [first[0], Translate(group, "x", dir=(1, 0, 0))],
                [first[0], Scale1D(group, "x", origin=(0, 0, 0), dir=(0, 1, 0)), ChangeCount(group, "x")], first]
    only = [board, other, group]
    for ops in programs:
        got = run.symbolic_parts(ops, only)
        fresh = symbolic_corners(run.program(ops), shape, run.backend, only=only)
        assert got.keys() == fresh.keys()
        assert all([str(e) for e in np.ravel(got[p])] == [str(e) for e in np.ravel(fresh[p])] for p in got)
    assert run.symbolic_parts(first, only)[board] is got[board]  # (the first program's, remembered)


class Variant:
    """A stand-in for a solved joint-pass cluster: a score, and sparse amounts that may fail
    (its score then fails too when it drops constraints, as the error needs them)."""

    def __init__(self, score, fails=False):
        self._score, self.fails = score, fails
        self.dropped = tuple(range(score[0]))
        self.reads = 0

    @property
    def solution(self):
        if self.fails:
            raise np.linalg.LinAlgError("SVD did not converge")
        return None

    @property
    def score(self):
        self.reads += 1
        if self.dropped:
            _ = self.solution
        return self._score


@pytest.mark.parametrize("seed", range(20))
def test_lazy_variants_come_as_sorting_all_the_solvable_ones(seed):
    """best_clusters against the eager rule on crafted scores: ties (with each other and with
    an unsolved variant's bound), unsolvable variants (None), dropped constraints, and
    clusters whose sparse amounts fail (left out, as if unsolved)."""
    from parsel_aep.propagate import Propagation

    rng = np.random.default_rng(seed)
    variants = [([f"p{i}"], ["local", "world"][int(rng.integers(2))], bool(rng.integers(2))) for i in range(8)]
    made = {}
    for parts, frame, shears in variants:
        kind = int(rng.integers(5))
        dropped = int(rng.integers(1, 3))
        score = (0, 0.0, shears, frame != "local") if kind < 2 else (dropped, float(rng.choice([0.5, 1.0])),
                                                                      shears, frame != "local")
        made[parts[0]] = None if kind == 2 else Variant(score, fails=kind == 3 and rng.random() < 0.5)

    class Stub:
        def __init__(self):
            self.solves = []

        def cluster_solve(self, state, parts, frame, shears):
            self.solves.append(parts[0])
            return made[parts[0]]

    state = type("State", (), {"stats": {"time_s": {"screen": 0.0}}})()
    stub = Stub()
    ranked = Propagation.best_clusters(stub, state, variants)
    got = list(itertools.islice(ranked, 1))
    solved_for_first = len(stub.solves)
    got += list(ranked)
    want = sorted((v for v in made.values() if v is not None and not v.fails), key=lambda v: v.score)
    assert [id(v) for v in got] == [id(v) for v in want]
    assert len(stub.solves) == len(variants)
    bound, index = min(((0, 0.0, s, f != "local"), i) for i, (_, f, s) in enumerate(variants))
    lead = made[variants[index][0][0]]
    if lead is not None and not lead.fails and lead.score == bound:  # it comes first, the rest unsolved
        assert got[0] is lead and solved_for_first == 1


def test_aep_solves_with_fewer_garbage_collections(monkeypatch):
    """The solve runs inside parsel_core.collector.fewer_collections, which is left on return."""
    import gc

    from parsel_aep import propagate
    from parsel_core.collector import SOLVE_THRESHOLD
    from parsel_core.examples import tiny_table
    from parsel_core.interfaces import SolveRequest
    from parsel_core.plugins import solvers
    from parsel_core.program import Program

    seen = []

    class Recording(propagate.Propagation):
        def run(self):
            seen.append(gc.get_threshold()[0])
            return super().run()

    monkeypatch.setattr(propagate, "Propagation", Recording)
    previous = gc.get_threshold()
    gc.set_threshold(700, *previous[1:])
    try:
        result = solvers()["aep"].run(SolveRequest(tiny_table(), Program.from_text(
            "scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)")))
        assert seen == [SOLVE_THRESHOLD] and result.program.ops
        assert gc.get_threshold()[0] == 700
    finally:
        gc.set_threshold(*previous)


def test_joint_slopes_remembered_across_variants_and_rings_are_the_fresh_ones():
    """One memo for every system of a shape (variants, rings of more parts and more
    constraints, a group's members): each system's arrays are those built without it."""
    from parsel_core.loading import load_shape

    shape = load_shape("shelf")
    rest = shape.rest_corners()
    corners = {m: np.broadcast_to(c, (3, 8, 3)) for m, c in rest.items()}
    hexahedra = {p: shape.part(p).hexahedron for p in shape.parts}
    group = next(g for g, r in shape.relations.items() if r.kind == "translation")
    hexahedra[group] = shape.part(group).hexahedron
    members = {group: tuple(shape.relations[group].members)}
    single = sorted(p for p in shape.parts if p not in members[group])
    memo: dict = {}
    rings = [single[:1], single[:2], single[:2] + [group], single]
    for parts in rings:
        moved = {m for p in parts for m in members.get(p, (p,))}
        constraints = [r for r in shape.relations.values() if set(r.members) & moved and r.id != group]
        for frame, shears in [("local", False), ("local", True), ("world", True)]:
            args = (parts, hexahedra, rest, corners, constraints, 1e-4, frame, shears, frozenset(), members)
            fresh, kept = cluster.build_system(*args), cluster.build_system(*args, memo=memo)
            for name in ("slopes", "weights", "r0", "costs"):
                assert getattr(kept, name).tobytes() == getattr(fresh, name).tobytes(), name
    assert len(memo) > 3 * len(rings)


@pytest.mark.parametrize("seed", range(6))
def test_a_solve_proved_deficient_from_an_earlier_spectrum_would_fail_the_conditioning_proof(seed):
    """The fast solves skip the Cholesky proof of a system whose smallest singular value an
    earlier solve bounds (same prior, rows removed and reweighted): only where the proof
    fails; and a well-conditioned system is never skipped."""
    from types import SimpleNamespace

    rng = np.random.default_rng(seed)
    k, n = 240, 40
    a = rng.normal(size=(k, n)) * (rng.random((k, n)) < 0.2)
    u, s, vt = np.linalg.svd(a, full_matrices=False)
    s[-1] *= [0.0, 1e-14, 1e-9, 1e-6, 1e-3, 1.0][seed]  # from exactly deficient to well conditioned
    a = (u * s) @ vt
    numerics = cluster._Numerics(SimpleNamespace(slopes=np.zeros((n, k))), fast=True)
    prior = np.ones(n)
    rows = rng.uniform(0.5, 2.0, k)
    s = np.linalg.svd(a * rows[:, None], compute_uv=False)
    numerics.remember(np.arange(k), rows, prior, s.min(), s.max(), len(s))
    skipped = 0
    for trial in range(20):
        columns = np.sort(rng.choice(k, size=int(rng.integers(n + 5, k + 1)), replace=False))
        new_rows = rng.uniform(0.5, 2.0, len(columns)) * (1.0 if trial % 2 else rng.uniform(1, 1e3))
        weighted = a[columns] * new_rows[:, None]
        if numerics.deficient(columns, new_rows, prior, weighted):
            skipped += 1
            norm = np.abs(weighted).max()
            assert cluster._conditioned_lstsq(weighted / norm, np.ones((len(columns), 2))) is None
    if seed <= 2:  # (deficient to the last bits or far below the proof's 1e-5: proved)
        assert numerics.deficient(np.arange(k), rows, prior, a * rows[:, None]) and skipped > 0
    if seed >= 4:  # (within a few decades of the proof's bound: never skipped)
        assert skipped == 0 and not numerics.deficient(np.arange(k), rows, prior, a * rows[:, None])
    assert not numerics.deficient(np.arange(k), rows, 2 * prior, a * rows[:, None])  # (another prior)


def test_only_the_clusters_dropping_the_fewest_constraints_are_scored():
    """The error of the dropped constraints needs the sparse amounts: clusters dropping more
    than the next one are not scored (nor their amounts solved) until they may come next."""
    from parsel_aep.propagate import Propagation

    variants = [([f"p{i}"], "local", False) for i in range(5)]
    made = {"p0": Variant((2, 0.5, False, False)), "p1": Variant((3, 0.1, False, False)),
            "p2": Variant((2, 0.2, False, False)), "p3": Variant((1, 0.9, False, False), fails=True),
            "p4": Variant((4, 0.0, False, False))}

    class Stub:
        def cluster_solve(self, state, parts, frame, shears):
            return made[parts[0]]

    state = type("State", (), {"stats": {"time_s": {"screen": 0.0}}})()
    ranked = Propagation.best_clusters(Stub(), state, variants)
    assert next(ranked) is made["p2"]  # (p3, dropping one, cannot be solved: left out)
    assert [made[p].reads > 0 for p in sorted(made)] == [True, False, True, True, False]
    assert list(ranked) == [made["p0"], made["p1"], made["p4"]]


def test_an_l1_start_keeping_fewer_constraints_than_the_first_pass_is_not_solved(monkeypatch):
    """Dropping constraints from the L1 fit's start keeps at most as many as it starts from:
    when that is fewer than the first pass kept, it cannot score better and is not solved."""
    rng = np.random.default_rng(1)
    system = random_system(rng, rank_loss=1, conflict=0.05)
    starts = []
    drop = cluster._drop_until_kept
    monkeypatch.setattr(cluster, "_drop_until_kept",
                        lambda s, kept, n=None: starts.append(list(kept)) or drop(s, kept, n))
    kept = cluster.plan(system).kept
    everything = list(range(len(system.constraints)))
    assert len(cluster._sparse_breaks(fresh_copy(system))) < len(kept) < len(everything)
    assert starts == [everything]
    assert_solve_is_the_exact_solve(system)


@pytest.mark.parametrize("seed", range(8))
def test_a_column_too_short_for_the_conditioning_proof_fails_it_without_a_factorisation(seed, monkeypatch):
    """A column whose squared norm is below CONDITIONED^2 times the longest one's leaves
    G - d I indefinite: the proof is declined without forming G, where the Cholesky
    factorisation would have failed; longer columns are still proved by it."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(60, 12)) * (rng.random((60, 12)) < 0.4) + np.eye(60, 12)
    b = rng.normal(size=(60, 3))
    column = int(rng.integers(12))
    short = a.copy()
    short[:, column] *= [1e-6, 3e-6, 6e-6, 1e-7, 1e-9, 1e-12, 0.0, 5e-6][seed]
    g = short.T @ short
    top = min(float(np.trace(g)), float(np.abs(g).sum(axis=1).max()))
    with pytest.raises(np.linalg.LinAlgError):  # what the proof itself would find
        np.linalg.cholesky(g - cluster.CONDITIONED ** 2 * top * np.eye(12))
    factorised = []
    proof = cluster._positive_definite
    monkeypatch.setattr(cluster, "_positive_definite", lambda m: factorised.append(m) or proof(m))
    assert cluster._conditioned_lstsq(short, b) is None and not factorised
    kept = a.copy()
    kept[:, column] *= 1e-3  # (short, but well above the bound: still proved)
    got = cluster._conditioned_lstsq(kept, b)
    assert factorised and got is not None
    assert np.allclose(got, np.linalg.lstsq(kept, b, rcond=1e-9)[0], rtol=1e-9)


@pytest.mark.parametrize("seed", range(6))
def test_systems_little_taller_than_wide_also_decide_on_their_qr(seed):
    """Between B and 2B residual columns the fast solves that differ only in the prior
    also share one QR; the amounts agree with the exact solver's and the solve is still
    bitwise the exact one."""
    rng = np.random.default_rng(seed)
    system = random_system(rng, parts=4, constraints=18, rank_loss=seed % 3, conflict=[0.0, 0.05, 1.0][seed % 3])
    columns = np.arange(system.r0.shape[1])
    assert len(system.weights) <= len(columns) < 2 * len(system.weights)
    fast, exact = cluster._Numerics(system, fast=True), cluster._Numerics(system, fast=False)
    rows = rng.uniform(0.5, 2.0, len(columns))
    for _ in range(4):
        prior = system.prior * (rng.random(len(system.weights)) < 0.7)
        got, want = fast.amounts(columns, rows, prior), exact.amounts(columns, rows, prior)
        assert np.allclose(got, want, rtol=1e-8, atol=1e-10 * np.abs(want).max())
    assert [v is not None for v in fast.factored.values()] == [True]
    assert_solve_is_the_exact_solve(system)


def test_candidates_moving_no_constraint_leave_an_empty_table():
    """No translation or scaling of the moving part moves a constraint (none reads it): no
    amount is usable, and screening returns a table with no rows instead of failing."""
    from parsel_core.relations import Attachment

    rng = np.random.default_rng(3)
    box = skewed_box(rng)
    corner = tuple(float(v) for v in np.eye(8)[0])
    contact = Attachment("a-b", ("a", "b"), weights_a=(corner,), weights_b=(corner,))
    others = {m: np.broadcast_to(skewed_box(rng).corners, (5, 8, 3)) for m in ("a", "b")}
    candidates = [Translate("p", "f", dir=(1.0, 0.0, 0.0)), Scale1D("p", "f", origin=(0.0, 0.0, 0.0),
                                                                     dir=(0.0, 1.0, 0.0))]
    table = screening.screen_table(candidates, {"p": box.corners}, others, [contact], 1e-3)
    assert len(table.index) == len(table.finite) == len(table.order) == 0
    assert screening.screen(candidates, {"p": box.corners}, others, [contact], 1e-3) == []


def spectrum_matrix(rng, shape, values):
    """A (m, n) matrix with the given singular values (the rest of them zero)."""
    u, _ = np.linalg.qr(rng.normal(size=(shape[0], shape[1])))
    v, _ = np.linalg.qr(rng.normal(size=(shape[1], shape[1])))
    s = np.zeros(shape[1])
    s[:len(values)] = values
    return (u * s) @ v.T


@pytest.mark.parametrize("null", [0, 1, 4])
def test_orthogonal_lstsq_is_pinvs_solution_where_it_proves_the_rank(null):
    """A tall system with an exact null space and the rest well conditioned (the drop
    steps' and the L1 fit's): gelsy's rank is proved to be pinv's and its solution is
    pinv's; the bounds it reports hold the smallest and largest singular values."""
    rng = np.random.default_rng(null)
    n = 12
    a = spectrum_matrix(rng, (40, n), rng.uniform(1e-4, 1.0, n - null))
    b = rng.normal(size=(40, 5))
    spectrum = []
    got = cluster._orthogonal_lstsq(a, b, 1e-9, 1e-4, spectrum)
    want = np.linalg.pinv(a, rcond=1e-9) @ b
    assert got is not None and np.allclose(got, want, rtol=1e-8, atol=1e-10 * np.abs(want).max())
    s = np.linalg.svd(a, compute_uv=False)
    (smallest, largest, count), = spectrum
    assert s.min() <= smallest and s.max() <= largest and count == n


@pytest.mark.parametrize("smallest", [1e-9 * (1 + 1e-6), 1e-9 * (1 - 1e-6), 1.5e-9, 3e-9, 1e-11, 1e-7])
def test_orthogonal_lstsq_is_pinvs_or_leaves_the_rank_to_the_svd(smallest):
    """A singular value near pinv's cutoff: where gelsy's rank is proved its solution is
    pinv's: the residuals to rounding, the amounts to ``~cond u`` (here 1e-7 of the
    largest, along the direction of the singular value near the cutoff); at the cutoff
    itself it is not proved and the SVD refuses to decide; a wide system is always left
    to the SVD."""
    rng = np.random.default_rng(5)
    a = spectrum_matrix(rng, (40, 8), [1.0, 0.5, 0.3, 0.2, 0.1, 0.05, 0.01, smallest])
    b = rng.normal(size=(40, 3))
    want = np.linalg.pinv(a, rcond=1e-9) @ b
    got = cluster._orthogonal_lstsq(a, b, 1e-9, 1e-4)
    if got is not None:  # (relative to |b| + |a| |y|: ORTHOGONAL_DRIFT and rounding)
        scale = np.abs(b).max() + np.abs(a).max() * np.abs(want).max()
        assert np.abs(a @ got - a @ want).max() <= cluster.ORTHOGONAL_DRIFT * scale
        assert np.abs(got - want).max() <= 1e-6 * np.abs(want).max()
    if abs(smallest - 1e-9) <= 1e-4 * 1e-9:
        assert got is None
        with pytest.raises(cluster._Borderline):
            cluster._guarded_lstsq(a, b, 1e-9, 1e-4)
    assert cluster._orthogonal_lstsq(rng.normal(size=(5, 8)), rng.normal(size=(5, 3)), 1e-9, 1e-4) is None


def test_a_solve_with_a_null_space_decides_through_gelsy_and_is_the_exact_solve(monkeypatch):
    """Repeated basis amounts (an exact null space): the drop steps and the L1 fit solve
    by gelsy, proved, and the whole solve is still bitwise the exact one."""
    rng = np.random.default_rng(2)
    system = random_system(rng, parts=3, constraints=40, rank_loss=2, conflict=0.05)
    proved = []
    orthogonal = cluster._orthogonal_lstsq
    monkeypatch.setattr(cluster, "_orthogonal_lstsq",
                        lambda *a, **k: (lambda y: proved.append(y is not None) or y)(orthogonal(*a, **k)))
    assert_solve_is_the_exact_solve(system)
    assert sum(proved) > 3


def test_the_amounts_focuss_starts_from_are_gelsds_not_gelsys(monkeypatch):
    """gelsy's amounts agree with pinv's only to ``~cond u`` along directions near the
    cutoff; the plan's least-costed amounts, where FOCUSS starts, are those of a plan
    without gelsy, to the bit."""
    rng = np.random.default_rng(2)
    system = random_system(rng, parts=3, constraints=40, rank_loss=2, conflict=0.05)
    found = cluster.plan(fresh_copy(system))
    assert found.numerics.orthogonal  # (the drop steps did go through gelsy)
    monkeypatch.setattr(cluster, "_orthogonal_lstsq", lambda *a, **k: None)
    plain = cluster.plan(fresh_copy(system))
    assert found.kept == plain.kept and found.f.tobytes() == plain.f.tobytes()


def test_the_fast_solvers_leave_their_system_as_it_was():
    """A fast solve tries the Cholesky proof, then gelsy, then gelsd on one scaled system
    (:meth:`cluster._Numerics.amounts`): none of them may write into it."""
    rng = np.random.default_rng(11)
    u, _ = np.linalg.qr(rng.normal(size=(40, 8)))
    v, _ = np.linalg.qr(rng.normal(size=(8, 8)))
    for smallest in (0.5, 1e-14):  # proved by Cholesky; a null space gelsy proves
        a = np.asfortranarray(u @ np.diag([1, 1, 1, 1, 1, 1, 1, smallest]) @ v.T)
        b = np.asfortranarray(rng.normal(size=(40, 3)))
        before = a.copy(), b.copy()
        cluster._conditioned_lstsq(a, b)
        cluster._orthogonal_lstsq(a, b, 1e-9, 1e-4)
        cluster._guarded_lstsq(a, b, 1e-9, 1e-4)
        assert np.array_equal(a, before[0]) and np.array_equal(b, before[1])


@pytest.mark.parametrize("seed", range(4))
def test_kept_columns_and_row_weights_are_each_constraints_run(seed):
    """``_columns`` and ``_row_weights`` are made by array operations from the system's
    runs; they must be, byte for byte, each kept constraint's columns in order and its
    ``1 / allowance`` repeated over them (the solves are remembered by these bytes)."""
    rng = np.random.default_rng(seed)
    for _ in range(50):
        count = int(rng.integers(1, 12))
        sizes = rng.integers(1, 25, count)
        starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        slices = tuple(slice(int(a), int(a + b)) for a, b in zip(starts, sizes))
        allowances = rng.random(count) * 1e-2 + 1e-4
        system = cluster.ClusterSystem((), (), (), (), slices, np.zeros((1, 1)), np.zeros((1, 1)), np.zeros(1),
                                       np.zeros(1), allowances)
        kept = sorted(rng.choice(count, int(rng.integers(0, count + 1)), replace=False).tolist())
        columns = np.array([c for i in kept for c in range(slices[i].start, slices[i].stop)], dtype=int)
        weights = np.array([1.0 / allowances[i] for i in kept for _ in range(sizes[i])], dtype=float)
        assert cluster._columns(system, kept).tobytes() == columns.tobytes()
        assert cluster._row_weights(system, kept).tobytes() == weights.tobytes()
        assert cluster._columns(system, tuple(kept)).tobytes() == columns.tobytes()


def test_joint_edits_derived_unit_by_unit_are_those_derived_whole(monkeypatch):
    """The joint pass derives a cluster's closed forms unit by unit, the most distorting
    unit first, and gives up at the first member distorted at the end of the range or the
    first closed form that disagrees with its numbers (Propagation.cluster_ops). Its answer
    must be the one deriving every unit in order and checking the whole program gives, and
    its check of one unit's members must be the whole evaluation's, to the bit."""
    import dataclasses

    from parsel_aep.propagate import HIGH_DISTORTION, Propagation, _part_by_part
    from parsel_aep.selection import arap_energies
    from parsel_core.program import evaluate

    def whole(self, found):
        residual = self.cluster_residual(found)
        units = self.cluster_units(found)
        if units is None:
            return None, None
        new_ops = []
        for unit in units:
            for _, terms in unit:
                for op, expr, expected in terms(residual):
                    text = self.closed_amount(op, expr, expected)
                    if text is None:
                        return None, None
                    if text != "0":
                        new_ops.append(dataclasses.replace(op, amount=text))
        ops = found.others_ops + new_ops
        edited = evaluate(self.program(ops), self.shape, {self.parameter.name: self.xs[-1:]}).parts
        distorted = [m for m in found.members if arap_energies(self.rest[m], edited[m][-1:])[0] > HIGH_DISTORTION]
        return (None if distorted else ops), (ops, distorted)

    unit_by_unit, check = Propagation.cluster_ops, Propagation.distorted
    seen = {"derived": 0, "given up": 0, "distorted early": 0, "checked": 0}

    def counted(self, ops, members):
        out = check(self, ops, members)
        seen["distorted early"] += out
        return out

    def both(self, state, found):
        got = unit_by_unit(self, state, found)
        want, derived = whole(self, found)
        assert (got is None) == (want is None)
        if got is not None:
            assert [repr(op) for op in got] == [repr(op) for op in want]
        if derived is not None and _part_by_part(self.program(derived[0])):
            for m in found.members:  # one member at a time, as a unit's members are checked
                assert check(self, derived[0], [m]) == (m in derived[1])
                seen["checked"] += 1
        seen["derived"] += 1
        seen["given up"] += got is None
        return got

    monkeypatch.setattr(Propagation, "cluster_ops", both)
    monkeypatch.setattr(Propagation, "distorted", counted)
    solve_fixtures()
    assert seen["derived"] >= 3 and seen["checked"] > 0
    assert seen["given up"] > 0 and seen["distorted early"] > 0  # (the early exit is exercised)
