"""A verbal description of a shape for prompts, and its inverse for rule-based readers.

Language models see parts and relations in words (paper 6.2.1): each part's id, label,
where it sits among parts of the same label, its size and centre; each relation as a
sentence. The text follows a fixed line grammar so that :func:`read_description` can
turn it back into a :class:`ShapeSummary`: the offline provider reads exactly what a
hosted model reads, and nothing else.

Conventions (the ones the prompts state): +x is right, +y is up, +z is front, so the
front of a chair faces +z and its left side is at -x as seen from the front.
"""

from __future__ import annotations

import re
from collections import defaultdict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from parsel_core.errors import ParselError
from parsel_core.graph import GROUP_KINDS, ShapeGraph
from parsel_core.labels import AXIS_NAMES, position_words
from parsel_core.relations import Attachment, GroundContact, ReflectionSymmetry, RotationSymmetry, TranslationSymmetry

_NUMBER = r"-?\d+(?:\.\d+)?(?:e-?\d+)?"


def _fmt(value: float) -> str:
    text = f"{float(value):.3f}"
    return "0.000" if text == "-0.000" else text


def _inline(text: object) -> str:
    """A name as it may appear in a prompt: one line, control characters written as escapes.

    Part ids and labels are checked when parts are made (``parsel_core.part.check_name``);
    this keeps any other name (shape, relation ids) from starting a prompt line of its own.
    """
    text = str(text)
    return text if text.isprintable() else "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def _vector_text(vector: Sequence[float]) -> str:
    return "(" + ", ".join(_fmt(v) for v in vector) + ")"


def direction_word(vector: Sequence[float]) -> str:
    """``+x`` / ``-z`` for an axis-aligned direction, else the rounded vector."""
    v = np.asarray(vector, dtype=float)
    norm = float(np.linalg.norm(v))
    if norm < 1e-12:
        return "(0, 0, 0)"
    v = v / norm
    axis = int(np.abs(v).argmax())
    if abs(abs(v[axis]) - 1.0) < 1e-6:
        return ("+" if v[axis] > 0 else "-") + AXIS_NAMES[axis]
    return _vector_text(v)


def relation_sentence(relation) -> str:
    """One relation in words (the grammar :func:`read_description` parses)."""
    members = relation.members
    if isinstance(relation, ReflectionSymmetry):
        normal = np.asarray(relation.normal, dtype=float)
        axis = int(np.abs(normal).argmax())
        if abs(abs(normal[axis]) - 1.0) < 1e-6:
            plane = f"the plane {AXIS_NAMES[axis]} = {_fmt(relation.origin[axis])}"
        else:
            plane = f"the plane through {_vector_text(relation.origin)} with normal {_vector_text(normal)}"
        return f"reflection symmetry: {members[0]} and {members[1]} mirror each other across {plane}"
    if isinstance(relation, TranslationSymmetry):
        step = np.asarray(relation.step, dtype=float)
        return (f"translation symmetry: {', '.join(members)} repeat in a row, {len(members)} copies "
                f"{_fmt(np.linalg.norm(step))} apart along {direction_word(step)}")
    if isinstance(relation, RotationSymmetry):
        return (f"rotation symmetry: {', '.join(members)} repeat around the axis {direction_word(relation.axis)} "
                f"through {_vector_text(relation.center)}, {len(members)} copies "
                f"{np.degrees(relation.angle):.1f} degrees apart")
    if isinstance(relation, Attachment):
        return f"attachment ({relation.contact} contact): {members[0]} is attached to {members[1]}"
    if isinstance(relation, GroundContact):
        return f"ground contact: {members[0]} stands on the ground"
    return f"{relation.kind}: {', '.join(members)} are related"


def describe_shape(shape: ShapeGraph) -> str:
    """The shape in words for a prompt: parts (id, label, position, size, centre), then relations.

    Pure: the same shape always gives the same text, so prompts (and the response cache
    keyed by them) are stable.
    """
    corners = np.concatenate([p.hexahedron.corners for p in shape.parts.values()])
    extent = corners.max(axis=0) - corners.min(axis=0)
    where = position_words(shape)
    lines = [
        f'<shape name="{_inline(shape.name)}" parts="{len(shape.parts)}" relations="{len(shape.relations)}">',
        "Axes: +x is right, +y is up, +z is front (the left side is at -x as seen from the front).",
        f"Overall size: {_fmt(extent[0])} wide (x), {_fmt(extent[1])} tall (y), {_fmt(extent[2])} deep (z).",
        "Parts (id: label, position among parts of the same label; size along x, y, z; centre):",
    ]
    for pid, part in shape.parts.items():
        c = part.hexahedron.corners
        size = c.max(axis=0) - c.min(axis=0)
        lines.append(f"- {_inline(pid)}: {_inline(part.label)}, {where[pid] or 'single'}; size {_fmt(size[0])} x "
                     f"{_fmt(size[1])} x {_fmt(size[2])}; centre {_vector_text(part.hexahedron.center)}")
    groups = [r for r in shape.relations.values() if r.kind in GROUP_KINDS]
    if groups:
        lines.append("Groups (a translation or rotation relation id also names its repeated parts as a whole):")
        for relation in groups:
            label = shape.parts[relation.members[0]].label
            lines.append(f"- {_inline(relation.id)}: the {len(relation.members)} {_inline(label)} parts as one "
                         "group")
    lines.append("Relations:")
    for relation in shape.relations.values():
        lines.append(f"- {_inline(relation.id)}: {_inline(relation_sentence(relation))}")
    if not shape.relations:
        lines.append("- (none)")
    lines.append("</shape>")
    return "\n".join(lines)


def request_block(request: str) -> str:
    """The edit request as it appears in prompts."""
    text = " ".join(str(request).split())
    return f"<request>{text}</request>"


def relation_block(shape: ShapeGraph, relation_id: str) -> str:
    """The relation a validity prompt asks about."""
    relation = shape.relation(relation_id)
    return f'<relation id="{_inline(relation.id)}">{_inline(relation_sentence(relation))}</relation>'


# -- reading the description back -------------------------------------------------------


@dataclass(frozen=True)
class PartSummary:
    """A part as the description gives it: world box extents and centre."""

    id: str
    label: str
    position: str
    size: tuple[float, float, float]
    centre: tuple[float, float, float]

    @property
    def lo(self) -> np.ndarray:
        return np.asarray(self.centre) - np.asarray(self.size) / 2

    @property
    def hi(self) -> np.ndarray:
        return np.asarray(self.centre) + np.asarray(self.size) / 2


@dataclass(frozen=True)
class RelationSummary:
    """A relation as the description gives it: id, kind and members (plus what the words say)."""

    id: str
    kind: str
    members: tuple[str, ...]
    normal_axis: int | None = None
    plane_offset: float | None = None
    contact: str | None = None


@dataclass
class ShapeSummary:
    """What a reader of the prompt knows about the shape."""

    name: str
    parts: dict[str, PartSummary] = field(default_factory=dict)
    relations: dict[str, RelationSummary] = field(default_factory=dict)

    @property
    def lo(self) -> np.ndarray:
        return np.min([p.lo for p in self.parts.values()], axis=0)

    @property
    def hi(self) -> np.ndarray:
        return np.max([p.hi for p in self.parts.values()], axis=0)

    @property
    def centre(self) -> np.ndarray:
        return (self.lo + self.hi) / 2

    @property
    def size(self) -> float:
        return float(np.linalg.norm(self.hi - self.lo))

    def groups(self) -> list[RelationSummary]:
        return [r for r in self.relations.values() if r.kind in GROUP_KINDS]

    def relations_of(self, part_id: str) -> list[RelationSummary]:
        return [r for r in self.relations.values() if part_id in r.members]

    def labels(self) -> dict[str, list[str]]:
        out: dict[str, list[str]] = defaultdict(list)
        for pid, part in self.parts.items():
            out[part.label].append(pid)
        return dict(out)


_SHAPE_BLOCK = re.compile(r'<shape name="(?P<name>[^"]*)"[^>]*>\n(?P<body>.*?)\n</shape>', re.S)
_PART_LINE = re.compile(
    rf"^- (?P<id>.+?): (?P<label>.+), (?P<position>[^,;]+); size (?P<sx>{_NUMBER}) x (?P<sy>{_NUMBER}) x "
    rf"(?P<sz>{_NUMBER}); centre \((?P<cx>{_NUMBER}), (?P<cy>{_NUMBER}), (?P<cz>{_NUMBER})\)$")
_REFLECTION = re.compile(r"^reflection symmetry: (?P<a>.+) and (?P<b>.+) mirror each other across (?P<plane>.+)$")
_AXIS_PLANE = re.compile(rf"^the plane (?P<axis>[xyz]) = (?P<offset>{_NUMBER})$")
_TRANSLATION = re.compile(r"^translation symmetry: (?P<members>.+) repeat in a row, \d+ copies .*$")
_ROTATION = re.compile(r"^rotation symmetry: (?P<members>.+) repeat around the axis .*$")
_ATTACHMENT = re.compile(r"^attachment \((?P<contact>\w+) contact\): (?P<a>.+) is attached to (?P<b>.+)$")
_GROUND = re.compile(r"^ground contact: (?P<a>.+) stands on the ground$")


def _split_members(text: str, parts: Mapping[str, PartSummary]) -> tuple[str, ...]:
    members = tuple(m.strip() for m in text.split(", "))
    unknown = [m for m in members if m not in parts]
    if unknown:
        raise ParselError(f"shape description names unknown part(s) {', '.join(unknown)}")
    return members


def read_description(text: str) -> ShapeSummary:
    """The last ``<shape>`` block of a prompt, read back into a :class:`ShapeSummary`.

    Raises :class:`ParselError` when the text holds no description or a line does not
    follow the grammar of :func:`describe_shape`.
    """
    blocks = list(_SHAPE_BLOCK.finditer(text))
    if not blocks:
        raise ParselError("the prompt holds no <shape> description")
    block = blocks[-1]
    summary = ShapeSummary(block["name"])
    section = ""
    for line in block["body"].splitlines():
        if not line.startswith("- "):
            section = line.split(" ", 1)[0].rstrip(":")
            continue
        if section == "Parts":
            match = _PART_LINE.match(line)
            if not match:
                raise ParselError(f"shape description: cannot read part line {line!r}")
            position = match["position"].strip()
            summary.parts[match["id"]] = PartSummary(
                match["id"], match["label"], "" if position == "single" else position,
                (float(match["sx"]), float(match["sy"]), float(match["sz"])),
                (float(match["cx"]), float(match["cy"]), float(match["cz"])))
        elif section == "Relations":
            if line == "- (none)":
                continue
            rid, _, sentence = line[2:].partition(": ")
            summary.relations[rid] = _read_relation(rid, sentence, summary.parts)
    return summary


def _read_relation(rid: str, sentence: str, parts: Mapping[str, PartSummary]) -> RelationSummary:
    if match := _REFLECTION.match(sentence):
        plane = _AXIS_PLANE.match(match["plane"])
        members = _split_members(f"{match['a']}, {match['b']}", parts)
        if plane:
            return RelationSummary(rid, "reflection", members, AXIS_NAMES.index(plane["axis"]),
                                   float(plane["offset"]))
        return RelationSummary(rid, "reflection", members)
    if match := _TRANSLATION.match(sentence):
        return RelationSummary(rid, "translation", _split_members(match["members"], parts))
    if match := _ROTATION.match(sentence):
        return RelationSummary(rid, "rotation", _split_members(match["members"], parts))
    if match := _ATTACHMENT.match(sentence):
        return RelationSummary(rid, "attachment", _split_members(f"{match['a']}, {match['b']}", parts),
                               contact=match["contact"])
    if match := _GROUND.match(sentence):
        return RelationSummary(rid, "ground", _split_members(match["a"], parts))
    kind, _, rest = sentence.partition(": ")
    return RelationSummary(rid, kind, ())


def read_request(text: str) -> str:
    """The last ``<request>`` of a prompt."""
    found = re.findall(r"<request>(.*?)</request>", text, re.S)
    if not found:
        raise ParselError("the prompt holds no <request>")
    return found[-1].strip()


def read_relation_id(text: str) -> str | None:
    """The id of the last ``<relation id=...>`` of a prompt (validity prompts)."""
    found = re.findall(r'<relation id="([^"]*)">', text)
    return found[-1] if found else None
