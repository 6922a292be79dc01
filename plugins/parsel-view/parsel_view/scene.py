"""What the slider page needs, computed once in Python: the program as data, the meshes as cage coordinates.

The browser re-implements the built-in ops' point maps and the group layouts
(``static/parsel_eval.js``); other part ops (plugins') get a point map generated from
their ``transform`` (:mod:`parsel_view.opjs`). Here every op is reduced to plain numbers: its name,
the parts it moves (a virtual parent's members included, as
``parsel_core.program._apply_part_ops`` does), the corners a feature op moves, and its
own origin / direction fields. Group layouts get the constants that only depend on
the rest shape (the anchors' cage coordinates in the virtual parent, the rest step).
Each part's mesh is sent as the cube coordinates ``(u, v, w)`` of its vertices in the
part's rest hexahedron; the page turns them into the 8 trilinear weights once, and a
slider step is then one ``(m, 8) @ (8, 3)`` product per edited part.

So that the page can say when the current slider values break a relation, each relation
goes as its linear map from the members' corner displacements to its residual (every
relation is linear in the corners), with its allowance and, for attachments, the cage
weights the sliding-contact check needs. The camera is fitted to the bounds of the
shape over the whole box of parameter ranges, so the shape stays in view as it grows.
"""

from __future__ import annotations

import base64
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from parsel_core.cage import inverse_trilinear, point_weights
from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.layout import translation_deviations
from parsel_core.ops import (
    ChangeCount,
    ChangeDelta,
    EditOp,
    GroupOp,
    KeepFixed,
    Rotate,
    Scale1D,
    Scale2D,
    Scale3D,
    Shear,
    Translate,
)
from parsel_core.program import Program, anchor_groups, follow_weights
from parsel_core.relations import RotationSymmetry, TranslationSymmetry
from parsel_core.textform import display_text
from parsel_view.jsexpr import amounts_script

SCENE_FORMAT = "parsel.view"
SCENE_VERSION = 1

#: Part ops the page implements, by class (not by name: a plugin may reuse a name).
JS_PART_OPS: tuple[type[EditOp], ...] = (Translate, Rotate, Scale1D, Scale2D, Scale3D, Shear, KeepFixed)
JS_GROUP_OPS: tuple[type[EditOp], ...] = (ChangeCount, ChangeDelta)


def b64(array: np.ndarray, dtype: str) -> str:
    """Little-endian bytes of ``array`` as base64: 4/3 the binary size, instead of ~2.5x for JSON numbers."""
    return base64.b64encode(np.ascontiguousarray(array, dtype=dtype).tobytes()).decode("ascii")


def label_colours(labels: Sequence[str]) -> dict[str, list[float]]:
    """The colours ``parsel inspect --png`` uses (``parsel_core.drawing.label_colours``), as RGB."""
    from parsel_core.drawing import label_colours as core_colours

    return {label: [round(float(c), 4) for c in rgba[:3]] for label, rgba in core_colours(labels).items()}


def js_class(op: EditOp) -> type[EditOp] | None:
    """The built-in op class whose point map the page re-implements for ``op``, if any.

    A subclass that overrides ``transform`` (or registers another name) is a different
    map: its JavaScript is generated from its ``transform`` (:mod:`parsel_view.opjs`)."""
    for cls in JS_PART_OPS + JS_GROUP_OPS:
        if isinstance(op, cls) and type(op).transform is cls.transform and op.name == cls.name:
            return cls
    return None


def _op_data(index: int, op: EditOp, shape: ShapeGraph, anchors_only: set[str]) -> dict[str, Any]:
    cls = js_class(op)
    if op.acts_on != "part" and cls is None:
        raise ParselError(f"op {index} ({op.name} on {op.operand!r}) re-lays out a group in a way the slider page "
                          f"does not implement (it implements: {', '.join(c.name for c in JS_GROUP_OPS)})")
    if cls in JS_GROUP_OPS:
        return {"index": index, "op": op.name, "kind": "group", "group": op.operand, "mode": op.mode}
    targets = [op.operand]
    if op.operand in shape.virtual_parents and op.operand not in anchors_only:
        targets += list(shape.relations[op.operand].members)
    params = {key: list(value) if isinstance(value, tuple) else value for key, value in op.params().items()}
    return {"index": index, "op": op.name, "kind": "part", "targets": targets,
            "corners": list(op.corner_indices) if op.feature is not None else None, "params": params,
            "generated": cls is None}


def generated_point_maps(program: Program) -> dict[int, str]:
    """JavaScript point maps, by op index, of the part ops the page has no hand-written map for."""
    from parsel_view.opjs import point_map_js

    maps = {}
    for index, op in enumerate(program.ops):
        if op.acts_on == "part" and js_class(op) is None:
            try:
                maps[index] = point_map_js(op)
            except ParselError as exc:
                raise ParselError(f"op {index} ({op.name} on {op.operand!r}): {exc}; the slider page cannot show "
                                  f"it") from None
    return maps


def _group_data(group_id: str, ops: list[tuple[int, GroupOp]], shape: ShapeGraph) -> dict[str, Any]:
    relation = shape.relations[group_id]
    rest = shape.rest_corners()
    members = list(relation.members)
    data: dict[str, Any] = {"id": group_id, "members": members, "mode": ops[0][1].mode,
                            "ops": [{"index": i, "op": op.name} for i, op in ops]}
    if isinstance(relation, TranslationSymmetry):
        centres = [rest[m].mean(axis=0) for m in members]
        rest_step = centres[1] - centres[0] if len(members) > 1 else np.zeros(3)
        anchors = np.array([centres[0], centres[-1]])
        data.update(kind="translation", rest_step=rest_step.tolist(),
                    anchor_weights=point_weights(rest[group_id], anchors).tolist(),
                    deviations=translation_deviations([rest[m] for m in members]).reshape(len(members), 24).tolist())
    elif isinstance(relation, RotationSymmetry):
        center = np.asarray(relation.center, dtype=float)
        axis = np.asarray(relation.axis, dtype=float)
        data.update(kind="rotation", angle=float(relation.angle), closed=bool(relation.closed),
                    center=center.tolist(), axis=(axis / np.linalg.norm(axis)).tolist(),
                    center_weights=point_weights(rest[group_id], center[None])[0].tolist())
    else:  # pragma: no cover - Program.validate refuses group ops on other relations
        raise ParselError(f"group {group_id!r} is a {relation.kind}, not a translation or rotation group")
    return data


def rest_values(program: Program) -> dict[str, float]:
    """The slider values the page opens at: those where every amount is zero (the shape at
    rest, usually 0), if they lie in the ranges; otherwise the parameters' defaults."""
    from parsel_core.expressions import numpy_functions, parse_expression

    zero = {p.name: min(max(0.0, p.lo), p.hi) for p in program.parameters}
    with np.errstate(all="ignore"):
        amounts = [float(parse_expression(op.amount).build(zero, numpy_functions())) for op in program.ops]
    if all(abs(a) <= 1e-12 for a in amounts):
        return zero
    return {p.name: p.default for p in program.parameters}


def program_data(program: Program, shape: ShapeGraph) -> dict[str, Any]:
    """The program reduced to numbers for ``parsel_eval.js`` (amounts go to :func:`amounts_script`)."""
    program.validate(shape)
    rest = rest_values(program)
    anchors = anchor_groups(program)
    ops = [_op_data(i, op, shape, anchors[i]) for i, op in enumerate(program.ops)]
    for number, follow in enumerate(program.follows):
        for i in follow.ops:
            ops[i]["follow"] = number
    per_group: dict[str, list[tuple[int, GroupOp]]] = {}
    for i, op in enumerate(program.ops):
        if isinstance(op, GroupOp):
            per_group.setdefault(op.operand, []).append((i, op))
    return {
        "parameters": [{"name": p.name, "lo": p.lo, "hi": p.hi, "default": p.default, "rest": rest[p.name]}
                       for p in program.parameters],
        "ops": ops,
        "layers": [[part.start, part.stop] for part in program.layer_slices],
        "outer": list(program.outer),
        "follows": [{"part": f.part, "point": list(f.point), "weights": follow_weights(shape, f).tolist()}
                    for f in program.follows],
        "groups": [_group_data(g, group_ops, shape) for g, group_ops in per_group.items()],
        "rest": {pid: np.asarray(c, dtype=float).ravel().tolist() for pid, c in shape.rest_corners().items()},
    }


def slider_labels(program: Program) -> dict[str, str]:
    """Each parameter's request text (``metadata["requests"]``, or the one request or seed of
    a single edit), which the page shows above its slider."""
    from parsel_core.joint import requests_of

    names = set(program.parameter_names)
    return {item["parameter"]: item["request"] for item in requests_of(program)
            if item["parameter"] in names and item["request"]}


def relation_data(shape: ShapeGraph, program: Program) -> dict[str, Any]:
    """Every relation as numbers the page checks at each slider step: ``residual = r0 + M d``
    with ``d`` the members' corner displacements from rest (M sparse: rows, columns, values),
    its allowance, whether it may break (the program's ``breaks``), the members' part names,
    and for attachments the weights of the sliding-contact check (``parsel_core.report``)."""
    from parsel_core.relations import Attachment
    from parsel_core.report import sliding_members, tolerance_for

    rest = shape.rest_corners()
    tolerance = tolerance_for(shape)
    breaks = set(program.metadata.get("breaks") or ()) if isinstance(program.metadata.get("breaks"), list) else set()
    sliding = sliding_members(shape, program)
    out = []
    for rid, relation in shape.relations.items():
        members = list(relation.members)
        base = {m: np.asarray(rest[m], dtype=float) for m in members}
        r0 = np.asarray(relation.residual(base), dtype=float).reshape(-1)
        raw0 = np.asarray(relation.constraint(base), dtype=float).reshape(-1)
        rows, cols, vals = [], [], []
        for j, m in enumerate(members):
            for k in range(24):
                moved = dict(base)
                bumped = base[m].copy().reshape(-1)
                bumped[k] += 1.0
                moved[m] = bumped.reshape(8, 3)
                column = np.asarray(relation.constraint(moved), dtype=float).reshape(-1) - raw0
                for row in np.nonzero(np.abs(column) > 1e-14)[0]:
                    rows.append(int(row))
                    cols.append(j * 24 + k)
                    vals.append(float(column[row]))
        item: dict[str, Any] = {
            "id": rid, "kind": relation.kind, "members": members,
            "names": [shape.parts[m].name if m in shape.parts else m for m in members],
            "size": int(r0.size), "r0": r0.tolist(), "rows": rows, "cols": cols, "vals": vals,
            "allowance": float(relation.allowance(tolerance)), "may_break": rid in breaks,
        }
        if isinstance(relation, Attachment):
            item["weights"] = [np.asarray(relation.weights_a).tolist(), np.asarray(relation.weights_b).tolist()]
            item["face"] = relation.contact == "face"
            item["sliding"] = [m for m in members if m in sliding]
        out.append(item)
    return {"relations": out, "tolerance": tolerance}


def view_bounds(shape: ShapeGraph, program: Program, count: int = 48) -> list[list[float]]:
    """Bounds of every part (and group instance) over the box of parameter ranges: its corners
    and ``count`` random joint samples. The page fits its camera to them."""
    from parsel_core.joint import joint_samples, sample_at
    from parsel_core.program import evaluate, laid_out_groups

    rest = np.concatenate([np.asarray(c, dtype=float) for c in shape.rest_corners().values()])
    lo, hi = rest.min(axis=0), rest.max(axis=0)
    if not program.parameters:
        return [lo.tolist(), hi.tolist()]
    values, box = joint_samples(program, count)
    parts = evaluate(program, shape, values).parts
    every = np.concatenate([np.asarray(c, dtype=float).reshape(-1, 3) for c in parts.values()])
    if laid_out_groups(program):  # instances past the old count exist only in scalar evaluations
        n = len(next(iter(values.values())))
        for index in range(min(n, max(box, 2) + 16)):
            for instances in evaluate(program, shape, sample_at(values, index)).instances.values():
                every = np.concatenate([every, np.asarray(instances, dtype=float).reshape(-1, 3)])
    every = every[np.all(np.isfinite(every), axis=1)]
    if len(every):
        lo, hi = np.minimum(lo, every.min(axis=0)), np.maximum(hi, every.max(axis=0))
    return [lo.tolist(), hi.tolist()]


def _part_mesh(shape: ShapeGraph, pid: str) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and triangle faces of a part: its mesh, or its hexahedron's 12 triangles."""
    part = shape.parts[pid]
    mesh = part.mesh
    if mesh is not None and getattr(mesh, "vertices", None) is not None and getattr(mesh, "faces", None) is not None:
        vertices = np.asarray(mesh.vertices, dtype=float)
        faces = np.asarray(mesh.faces, dtype=np.int64)
        if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
            raise ParselError(f"shape {shape.name!r}: part {pid!r}: mesh has no triangle faces")
        return vertices, faces
    return np.asarray(part.hexahedron.corners, dtype=float), part.hexahedron.triangles().astype(np.int64)


def is_closed_volume(vertices: np.ndarray, faces: np.ndarray) -> bool:
    """Whether a mesh is watertight with consistent, outward winding: its back faces are never seen."""
    import trimesh

    return bool(trimesh.Trimesh(vertices, faces, process=False).is_volume)


def mesh_data(shape: ShapeGraph) -> list[dict[str, Any]]:
    """Per part: label, colour, cube coordinates of the vertices (float64), faces (uint32), and
    whether the mesh is a closed volume (the page culls back faces of those)."""
    colours = label_colours([p.label for p in shape.parts.values()])
    out = []
    for pid, part in shape.parts.items():
        vertices, faces = _part_mesh(shape, pid)
        uvw = inverse_trilinear(part.hexahedron.corners, vertices)
        if not np.all(np.isfinite(uvw)):
            raise ParselError(f"shape {shape.name!r}: part {pid!r}: its mesh has no cage coordinates in its "
                              f"hexahedron (a degenerate box?)")
        out.append({"id": pid, "label": part.label, "colour": colours[part.label],
                    "vertices": len(vertices), "faces": len(faces), "closed": is_closed_volume(vertices, faces),
                    "uvw": b64(uvw, "<f8"), "index": b64(faces, "<u4")})
    return out


@dataclass
class PageData:
    """Everything one page shows: the scene (JSON data) and the amounts (a script)."""

    scene: dict[str, Any]
    amounts_js: str
    program: Program
    shape: ShapeGraph
    meta: dict[str, Any] = field(default_factory=dict)

    def scene_json(self) -> str:
        """Compact JSON; ``<`` escaped so the text can sit inside a ``<script>`` element."""
        return json.dumps(self.scene, separators=(",", ":"), allow_nan=False).replace("<", "\\u003c")


def build_page_data(program: Program, shape: ShapeGraph, title: str | None = None,
                    meta: Mapping[str, Any] | None = None) -> PageData:
    """The page's scene for ``program`` on ``shape``; raises ``ParselError`` naming a mismatch."""
    data = program_data(program, shape)
    script = amounts_script([op.amount for op in program.ops], program.parameter_names,
                            generated_point_maps(program))  # first: it refuses ops the page cannot draw
    corners = np.concatenate([np.asarray(c, dtype=float) for c in shape.rest_corners().values()])
    info = {key: value for key, value in dict(program.metadata).items() if isinstance(value, (str, int, float))}
    scene = {
        "format": SCENE_FORMAT,
        "version": SCENE_VERSION,
        "shape": shape.name,
        "title": title or f"{shape.name}: {len(program.ops)} ops, {len(program.parameters)} parameter(s)",
        "metadata": info,
        "program_text": display_text(program.to_text()),
        "bounds": [corners.min(axis=0).tolist(), corners.max(axis=0).tolist()],
        "view_bounds": view_bounds(shape, program),
        "sliders": slider_labels(program),
        "meshes": mesh_data(shape),
        **relation_data(shape, program),
        **data,
    }
    return PageData(scene, script, program, shape, dict(meta or {}))
