"""Several parameters at once: the joint parameter box, joint ranges, and adding a request.

A program with several parameters (a proxydural model, a program grown with ``parsel
edit --on``) must give a valid shape at every combination of its sliders, not only with
one slider moving. Requests are solved one at a time on the rest shape and added as
layers (:meth:`Program.plus`): every relation is linear in the corners and holds at
rest, so the sum of displacements that each keep a relation keeps it too, exactly, over
the whole box of ranges (docs/aep.md, "Several parameters"). What a sum does not inherit
is non-degeneracy (two shrinking edits of one part may collapse it together), so a new
layer's range is narrowed until no part degenerates anywhere in the box. Nor does a sum
inherit what a layer keeps only by sliding a contact or laying out a row, so a new layer
that breaks, together with the earlier ones, a relation each of them keeps alone is
refused (:func:`joint_losses`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.hexahedron import corner_jacobians
from parsel_core.ops import GroupOp
from parsel_core.program import NUMPY_MATH, Follow, Parameter, Program, evaluate, op_amounts

#: Box corners are enumerated up to this many parameters (2**10 corners); beyond, random ones.
MAX_CORNER_PARAMETERS = 10
#: A hexahedron whose corner frames shrink below this fraction of their rest volume has collapsed
#: (the AEP solver's automatic tau uses the same criterion).
COLLAPSE = 0.05


def box_corners(parameters: Sequence[Parameter], seed: int = 0) -> dict[str, np.ndarray]:
    """The corners of the box of ranges: all 2**n of them, or 2**MAX_CORNER_PARAMETERS random ones."""
    n = len(parameters)
    if n == 0:
        return {}
    if n <= MAX_CORNER_PARAMETERS:
        bits = np.array(list(itertools.product((0, 1), repeat=n)), dtype=bool)
    else:
        rng = np.random.default_rng(seed)
        bits = rng.integers(0, 2, size=(2 ** MAX_CORNER_PARAMETERS, n)).astype(bool)
    return {p.name: np.where(bits[:, i], p.hi, p.lo) for i, p in enumerate(parameters)}


def joint_samples(program: Program, count: int, seed: int = 0) -> tuple[dict[str, np.ndarray], int]:
    """Joint samples of every parameter and how many of them are box corners.

    One parameter: ``count`` samples with both ends of its range. Several: every corner of
    the box of ranges first, then ``count`` random points (each parameter drawn on its own
    range, both ends among them), so combinations at the extremes are always checked."""
    random = {p.name: p.samples(count, seed=seed + i) for i, p in enumerate(program.parameters)}
    if len(program.parameters) < 2:
        return random, 0
    corners = box_corners(program.parameters, seed)
    n = len(next(iter(corners.values())))
    return {name: np.concatenate([corners[name], random[name]]) for name in random}, n


def sample_at(values: Mapping[str, np.ndarray], index: int) -> dict[str, float]:
    """The parameter values of one joint sample."""
    return {name: float(np.asarray(v)[index]) for name, v in values.items()}


def degenerate(rest: np.ndarray, edited: np.ndarray) -> np.ndarray:
    """Which samples (...,) of an edited hexahedron are flipped or collapsed: the frame at a corner
    turned inside out, or shrunk below COLLAPSE of its rest volume. Removed instances (NaN) are not."""
    removed = np.isnan(edited).all(axis=(-1, -2))
    with np.errstate(invalid="ignore", over="ignore"):
        orientation = corner_jacobians(np.where(removed[..., None, None], rest, edited))
        rest_orientation = corner_jacobians(rest)
        flipped = np.any(~(orientation * np.sign(rest_orientation) > COLLAPSE * np.abs(rest_orientation)), axis=-1)
    return flipped & ~removed


def moved_parts(shape: ShapeGraph, program: Program) -> set[str]:
    """Parts any part op moves (members of an edited virtual parent included)."""
    moved = set()
    for op in program.ops:
        if op.acts_on != "part" or op.name == "keep_fixed":
            continue
        moved.add(op.operand)
        if op.operand in shape.virtual_parents:
            moved.update(shape.relations[op.operand].members)
    return moved & set(shape.parts)


def edge_skew(shape: ShapeGraph, program: Program, values: Mapping[str, Any]) -> dict[str, float]:
    """Per part, the largest |cos| between two of its edges at a corner over the samples
    ``values`` (0 for a box at every sample; a turn summed with a widening shears a part)."""
    out = {}
    for pid, c in evaluate(program, shape, values).parts.items():
        edges = np.stack([c[..., 4, :] - c[..., 0, :], c[..., 2, :] - c[..., 0, :], c[..., 1, :] - c[..., 0, :]], -2)
        with np.errstate(invalid="ignore", divide="ignore"):
            unit = edges / np.linalg.norm(edges, axis=-1, keepdims=True)
        cos = np.abs(np.einsum("...ik,...jk->...ij", unit, unit) - np.eye(3))
        out[pid] = float(np.nanmax(cos)) if np.isfinite(cos).any() else 0.0
    return out


def degenerate_parts(shape: ShapeGraph, program: Program, values: Mapping[str, np.ndarray]) -> list[str]:
    """Parts that degenerate at some of the joint samples ``values``."""
    corners = evaluate(program, shape, values).parts
    rest = shape.rest_corners()
    return sorted(pid for pid in moved_parts(shape, program) if np.any(degenerate(rest[pid], corners[pid])))


def _box_check_values(program: Program, count: int = 64, seed: int = 0) -> dict[str, np.ndarray]:
    values, _ = joint_samples(program, count, seed)
    return values


def _rest_value(parameter: Parameter) -> float:
    return min(max(0.0, parameter.lo), parameter.hi)


def narrowed(parameter: Parameter, factor: float) -> Parameter:
    """The range scaled by ``factor`` about the parameter's rest value (0, or the end nearest it)."""
    rest = _rest_value(parameter)
    lo = math.ceil((rest + factor * (parameter.lo - rest)) * 1000) / 1000 if parameter.lo < rest else parameter.lo
    hi = math.floor((rest + factor * (parameter.hi - rest)) * 1000) / 1000 if parameter.hi > rest else parameter.hi
    lo, hi = min(lo, rest), max(hi, rest)
    return Parameter(parameter.name, lo, hi, min(max(parameter.default, lo), hi))


def fit_joint_range(shape: ShapeGraph, program: Program, name: str, steps: int = 12) -> Program:
    """``program`` with parameter ``name``'s range narrowed (about its rest value) until no part
    degenerates at any corner of the box of ranges or at random joint samples.

    Each layer's range was chosen so that its edit alone keeps every part a proper box;
    two edits that each shrink a part can collapse it when added, so the newest range gives way."""
    if not degenerate_parts(shape, program, _box_check_values(program)):
        return program
    parameter = program.parameter(name)

    def with_factor(factor: float) -> Program:
        return program.with_parameters(narrowed(p, factor) if p.name == name else p for p in program.parameters)

    lo, hi = 0.0, 1.0
    for _ in range(steps):
        mid = (lo + hi) / 2
        if degenerate_parts(shape, with_factor(mid), _box_check_values(with_factor(mid))):
            hi = mid
        else:
            lo = mid
    result = with_factor(lo)
    narrow = result.parameter(name)
    if lo == 0.0 or narrow.hi - narrow.lo <= 1e-3 * max(parameter.hi - parameter.lo, 1e-12) or \
            degenerate_parts(shape, result, _box_check_values(result)):
        bad = degenerate_parts(shape, program, _box_check_values(program))
        raise ParselError(f"parameter {name!r} collapses {', '.join(bad[:3])} together with the other parameters "
                          f"at once; no range of it keeps every part a proper box")
    return result


#: Random joint samples (besides every box corner) at which a new layer must keep, together with
#: the earlier ones, each relation every slider keeps alone; what ``parsel check`` samples too.
JOINT_CHECK_SAMPLES = 200


def joint_losses(shape: ShapeGraph, program: Program, samples: int = JOINT_CHECK_SAMPLES) -> list[Any]:
    """Relations every slider of ``program`` keeps alone that some joint sample breaks: every
    corner of the box of ranges and ``samples`` random points (the relation states of
    :func:`parsel_core.report.check_program`, each with its worst sample)."""
    from parsel_core.report import check_program, kept_alone  # the report samples with this module

    if len(program.parameters) < 2:
        return []
    must = kept_alone(shape, program)
    report = check_program(shape, program, samples=samples)
    return [s for s in report.relations if s.id in must and s.state != "kept"]


def check_joint_relations(shape: ShapeGraph, base: Program, program: Program, name: str, request: str) -> None:
    """Refuse a layer that, added to ``base``, breaks a relation that it and every earlier layer
    keep alone (losses ``base`` already had are not the new layer's).

    Linear residuals add exactly; what does not add is a contact a layer keeps only by sliding,
    or a layout, next to another layer that turns the same parts: the sum is not a valid edit,
    and no range of the new slider short of nothing keeps it."""
    before = {s.id for s in joint_losses(shape, base)}
    lost = [s for s in joint_losses(shape, program) if s.id not in before]
    if not lost:
        return
    worst = max(lost, key=lambda s: s.max_error)
    at = ", ".join(f"{k}={v:.3g}" for k, v in (worst.worst_at or {}).items())
    names = ", ".join(f"{s.id} ({' on '.join(s.members)})" for s in lost)
    raise ParselError(f"request {request!r} ({name}) breaks {names} together with the earlier sliders, though "
                      f"each slider keeps it alone (error {worst.max_error:.3g} at {at}); the edits do not add")


def fresh_name(program: Program, prefix: str = "x") -> str:
    """A parameter name the program does not use: ``x<k>`` with k one past its parameter count."""
    used = set(program.parameter_names)
    k = len(program.parameters) + 1
    while f"{prefix}{k}" in used:
        k += 1
    return f"{prefix}{k}"


def requests_of(program: Program) -> list[dict[str, str]]:
    """What each parameter of a program was asked for: ``metadata["requests"]`` of a stacked
    program, or the request (or seed) of a single edit for each of its parameters."""
    meta = program.metadata
    listed = meta.get("requests")
    if isinstance(listed, list):
        return [{"request": str(item.get("request", "")), "parameter": str(item.get("parameter", ""))}
                for item in listed if isinstance(item, Mapping)]
    text = meta.get("request") or meta.get("seed")
    if not isinstance(text, str) or not text:
        return []
    return [{"request": text, "parameter": p.name} for p in program.parameters]


def check_layouts(base: Program | None, layer: Program, request: str) -> None:
    """Refuse a layer that lays out a group in the other mode than an earlier layer: a top-down
    layout spreads the instances over the parent's span, a bottom-up one extends the row by its
    step, and one row cannot follow both."""
    if base is None:
        return
    modes = {op.operand: op.mode for op in base.ops if isinstance(op, GroupOp)}
    for op in layer.ops:
        if isinstance(op, GroupOp) and modes.get(op.operand, op.mode) != op.mode:
            raise ParselError(f"request {request!r} lays out group {op.operand!r} {op.mode.replace('_', '-')} where "
                              f"an earlier request lays it out {modes[op.operand].replace('_', '-')}; one row cannot "
                              f"follow both")


#: Two parts move alike when their fitted affine maps agree to this (in shape units, per unit of
#: coordinate: the maps are compared on the parts' own corners).
SAME_MOTION = 1e-9


def _affine_maps(rest: np.ndarray, moved: np.ndarray) -> tuple[np.ndarray, float]:
    """The affine maps (samples, 4, 3) taking rest corners (8, 3) to moved ones (samples, 8, 3)
    by least squares, and the largest corner residual (zero for affine edits)."""
    homogeneous = np.hstack([rest, np.ones((8, 1))])
    maps = np.stack([np.linalg.lstsq(homogeneous, m, rcond=None)[0] for m in moved])
    residual = float(np.max(np.abs(homogeneous @ maps - moved))) if len(moved) else 0.0
    return maps, residual


def turns_parts(shape: ShapeGraph, layer: Program, samples: int = 3) -> bool:
    """Whether the layer turns a part: one of its part ops maps the shape's parts by a rotation
    (a linear map that is orthogonal and not the identity) somewhere in its range.

    Shears and scalings are not turns: the solver shears a part between supports that move
    apart, and a sheared part summed with another layer's edit stays the sum of two edits
    that each keep its relations, without a rigid motion to compose."""
    values = {p.name: np.linspace(p.lo, p.hi, samples + 1)[1:] for p in layer.parameters}
    rest = shape.rest_corners()
    for op, amount in zip(layer.ops, op_amounts(layer, values)):
        if op.acts_on != "part" or op.operand not in rest or op.feature is not None:
            continue
        moved = np.broadcast_to(op.apply(rest[op.operand], amount[..., None, None], NUMPY_MATH), (samples, 8, 3))
        affine, residual = _affine_maps(rest[op.operand], moved)
        linear = affine[:, :3, :]
        orthogonal = np.abs(np.einsum("sij,skj->sik", linear, linear) - np.eye(3)).max(axis=(1, 2)) < 1e-9
        turned = np.abs(linear - np.eye(3)).max(axis=(1, 2)) > 1e-9
        if residual < 1e-9 and np.any(orthogonal & turned):
            return True
    return False


def _motions(shape: ShapeGraph, layer: Program, samples: int) -> dict[str, np.ndarray]:
    """Each moved part's affine maps at ``samples`` values of the layer's range (its moved
    corners where the edit is not affine, a taper: such a part moves alike only with itself)."""
    values = {p.name: np.linspace(p.lo, p.hi, samples + 1)[1:] for p in layer.parameters}
    corners = evaluate(layer, shape, values).parts
    rest = shape.rest_corners()
    maps: dict[str, np.ndarray] = {}
    for pid, moved in corners.items():
        moved = np.broadcast_to(moved, (samples, 8, 3))
        if pid not in rest or np.allclose(moved, rest[pid], rtol=0, atol=1e-12):
            continue
        affine, residual = _affine_maps(rest[pid], moved)
        scale = max(float(np.ptp(rest[pid], axis=0).max()), 1e-12)
        maps[pid] = moved if residual > 1e-9 * scale else affine
    return maps


def follows_for(shape: ShapeGraph, layer: Program, samples: int = 3) -> tuple[Follow, ...]:
    """How the ops of a layer that turns parts follow the shape beneath, as an outer layer.

    Parts the layer moves by one and the same map (a door and its handle, turned about one
    hinge) form a rigid set; every op on the set that has an origin follows one point: the
    origin of the first such op on the set's largest part (the hinge), carried by that part.
    Relations inside the set hold after the shape beneath moved them (one map for all); a
    contact on the turning axis stays on it when the parts beneath keep the axis's direction."""
    maps = _motions(shape, layer, samples)
    rest = shape.rest_corners()
    sets: list[list[str]] = []
    for pid in maps:
        for members in sets:
            other = maps[members[0]]
            if other.shape == maps[pid].shape and np.allclose(other, maps[pid], rtol=0, atol=SAME_MOTION):
                members.append(pid)
                break
        else:
            sets.append([pid])
    follows = []
    for members in sets:
        ops = [i for i, op in enumerate(layer.ops) if op.acts_on == "part" and op.operand in members
               and op.point_fields]
        if not ops:
            continue
        volume = {pid: float(np.prod(np.ptp(rest[pid], axis=0))) for pid in members}
        anchor = max(members, key=lambda pid: (pid in shape.parts, volume[pid], pid))
        on_anchor = [i for i in ops if layer.ops[i].operand == anchor] or ops
        point = getattr(layer.ops[on_anchor[0]], layer.ops[on_anchor[0]].point_fields[0])
        follows.append(Follow(anchor, point, tuple(ops)))
    return tuple(follows)


def _compose(shape: ShapeGraph, base: Program, layer: Program, name: str, request: str) -> Program:
    """``layer`` added to ``base``: on top if it turns parts, else beneath the turns on top;
    if the joint check refuses that, with every layer summed (turns too: the relations add,
    a turned and widened part may shear); refused when that fails too."""
    attempts = []
    if turns_parts(shape, layer):
        # A turn summed with a widening shears the part; on top of the others it turns the
        # widened part about its carried hinge (docs/aep.md, "Several parameters").
        attempts.append((base, lambda: base.atop(layer, follows_for(shape, layer))))
    attempts.append((base, lambda: base.plus(layer)))
    if base.outer:
        summed = Program(base.ops, base.parameters, base.metadata, base.layers)
        attempts.append((summed, lambda: summed.plus(layer)))
    for number, (before, build) in enumerate(attempts, start=1):
        try:
            program = fit_joint_range(shape, build(), name)
            check_joint_relations(shape, before, program, name, request)
            return program
        except ParselError:
            if number == len(attempts):
                raise
    raise AssertionError("unreachable")


def add_layer(shape: ShapeGraph, base: Program | None, layer: Program, request: str,
              name: str | None = None) -> tuple[Program, str]:
    """``layer`` (one request's program, solved on the rest shape) added to ``base`` as a new
    layer with its own parameter, the range narrowed where the sum would collapse a part;
    refused (:class:`ParselError`) where the sum breaks a relation each slider keeps alone.

    Returns the program and the new parameter's name. The metadata's ``requests`` list which
    request each parameter came from (the slider page labels its sliders with them)."""
    if len(layer.parameters) != 1:
        raise ParselError(f"a request's program adds one slider; this one has {len(layer.parameters)} parameters")
    check_layouts(base, layer, request)
    base_requests = requests_of(base) if base is not None else []
    if base is None or not base.ops:
        name = name or "x1"
        program = layer.renamed(layer.parameters[0].name, name)
        if turns_parts(shape, program):  # later layers go beneath it
            program = Program((), ()).atop(program, follows_for(shape, program))
    else:
        if not base.layers and turns_parts(shape, base):
            base = Program((), base.parameters, base.metadata).atop(base, follows_for(shape, base))
        name = name or fresh_name(base)
        if name in base.parameter_names:
            raise ParselError(f"parameter {name!r} is already one of the program's ({', '.join(base.parameter_names)})")
        program = _compose(shape, base, layer.renamed(layer.parameters[0].name, name), name, request)
    meta: dict[str, Any] = {key: value for key, value in dict(base.metadata if base is not None else {}).items()
                            if key not in ("request", "seed", "requests")}
    meta.update({"shape": shape.name, "requests": base_requests + [{"request": request, "parameter": name}]})
    return program.with_metadata(meta), name
