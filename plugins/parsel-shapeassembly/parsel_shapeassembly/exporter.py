"""Edited shapes back to ShapeAssembly programs (``parsel apply ... -o edited.sa.txt``).

The written program reproduces the edited cuboids when parsel's interpreter (the
paper's) executes it. It is built so that every statement's effect is known:

* Blocks follow the part names: ``Program_1/cube0`` goes into block ``Program_1``, so a
  shape loaded from a program is written in its source's hierarchy (each sub-program
  instance as its own block). A block's bounding box holds its cuboids, in the frame
  most of its leaves share (so a tilted back is one rotated sub-program of aligned
  slats; ``FRAME_POLICIES`` lists the other choices tried when that does not come back
  exactly); the root box is centred at the origin, as the interpreter places it, and
  holds every part, so world positions are kept.
* A cuboid aligned with its block is placed by one ``attach`` (the interpreter's first
  attachment only translates): at a contact point of a kept attachment relation with a
  cuboid placed before it, else on the block's box. Its other kept contacts with
  placed cuboids follow as further ``attach`` statements, which hold already and
  therefore move nothing.
* A rotated cuboid is declared unaligned and attached to the box twice, at two points
  on a line perpendicular to its rotation axis: the second attachment rotates it by the
  minimal rotation, which is then exactly its rotation. The interpreter computes angles
  in float32, so the line is chosen among several to land closest.
* A kept reflection pair mirrored through the block's centre plane is written as its
  first member and ``reflect``; an evenly spaced group along a block axis (including a
  group whose count the edit changed) as its first instance and ``translate``. The
  macros replay the source's attachments, so the source is attached to its block's box,
  or to a cuboid that the macro's motion maps onto itself.

The program is executed before it is returned; a cuboid that does not come back within
``MATCH_TOLERANCE`` of the shape's diagonal has its macros and contacts dropped and is
written again with box attachments only, and the other block frames are tried. A
rotation the interpreter cannot make (it turns an angle below about 2.4e-4 radians into
none and quantises small angles coarsely, from float32 cosines) is then made as two it
can: the part gets a block of its own (``Program_<name>_turn``) turned by ``TURN``, and
the part is turned back within it. Parts that an edit turned into non-cuboids are
written as their best-fitting cuboid (``cuboids.fit_box``) and listed in the result, as
are cuboids that still do not come back.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.interfaces import Exporter
from parsel_core.program import Evaluation
from parsel_core.relations import Attachment, ReflectionSymmetry, TranslationSymmetry, rotation_matrix
from parsel_core.report import tolerance_for
from parsel_shapeassembly.cuboids import Box, fit_box, in_frame, same_frame
from parsel_shapeassembly.interpreter import execute
from parsel_shapeassembly.parser import MIN_DIMENSION, SUBPROGRAM_PREFIX

#: A hexahedron whose corners lie within this fraction of the diagonal of a cuboid is a cuboid.
CUBOID_TOLERANCE = 1e-9
#: Executed corners within this fraction of the diagonal count as reproduced.
MATCH_TOLERANCE = 1e-7
#: Lines tried for each rotated cuboid: directions about its rotation axis, and lengths.
ROTATION_TRIES = 36
ROTATION_LENGTHS = (1.0, 0.8, 0.6)
AXIS_NAMES = ("X", "Y", "Z")
_IDENT = re.compile(r"[^A-Za-z0-9_]")


def _num(value: float) -> str:
    value = float(value)
    for exact in (0.0, 0.5, 1.0):
        if abs(value - exact) < 1e-12:
            value = exact
    text = format(value, ".12g")
    return "0" if text == "-0" else text


def _vec(values: Sequence[float]) -> str:
    return ", ".join(_num(v) for v in values)


@dataclass
class Leaf:
    """One cuboid to write: a part, or an instance of a re-laid-out group."""

    key: str
    path: tuple[str, ...]  # block path elements then the cuboid name
    box: Box
    deviation: float
    group: str | None = None  # laid-out group this instance belongs to
    index: int = 0


@dataclass
class Node:
    """A cuboid of one block: a leaf, or the box of a sub-block."""

    name: str
    box: Box  # in world coordinates
    leaf: Leaf | None = None
    block: Block | None = None


@dataclass
class Block:
    """An ``Assembly`` block: its nodes in order, its frame and box (world)."""

    name: str
    path: tuple[str, ...]
    nodes: dict[str, Node] = field(default_factory=dict)
    frame: np.ndarray = field(default_factory=lambda: np.eye(3))
    box: Box | None = None
    #: A block made to hold one part whose rotation is too small for the interpreter (see TURN).
    turned: bool = False

    def leaves(self) -> list[Leaf]:
        out: list[Leaf] = []
        for node in self.nodes.values():
            out += [node.leaf] if node.leaf is not None else node.block.leaves()
        return out


@dataclass
class ShapeAssemblyExport:
    """A written program and what it says about the shape.

    ``names``: leaf key (part id, or ``group[i]`` for instances) -> leaf name in the
    executed program. ``non_cuboids``: key -> largest corner distance to the written
    cuboid. ``inexact``: key -> largest corner error after execution, for cuboids that do
    not come back within ``MATCH_TOLERANCE``."""

    text: str
    names: dict[str, str]
    expected: dict[str, np.ndarray]
    non_cuboids: dict[str, float]
    inexact: dict[str, float]
    statements: dict[str, int]

    def notes(self) -> list[str]:
        """One line per part written approximately."""
        out = [f"{key}: not a cuboid after the edit (corners up to {dev:.3g} away); written as its best-fitting "
               f"cuboid" for key, dev in self.non_cuboids.items()]
        out += [f"{key}: comes back {err:.3g} away (a rotation below the interpreter's float32 resolution)"
                for key, err in self.inexact.items() if key not in self.non_cuboids]
        return out


def _identifier(name: str, taken: set[str]) -> str:
    """A ShapeAssembly cuboid name for a part name: an identifier, not ``bbox`` nor ``Program_*``."""
    text = _IDENT.sub("_", name) or "part"
    if not (text[0].isalpha() or text[0] == "_"):
        text = "p_" + text
    if text == "bbox" or text.startswith(SUBPROGRAM_PREFIX):
        text = "part_" + text
    base, n = text, 1
    while text in taken:
        n += 1
        text = f"{base}_{n}"
    taken.add(text)
    return text


def collect_leaves(shape: ShapeGraph, evaluation: Evaluation) -> list[Leaf]:
    """Every cuboid of the edited shape, in part order; a re-laid-out group's instances
    stand where its first member stood."""
    replaced = {m: g for g in evaluation.instances for m in shape.relation(g).members}
    thinnest = MIN_DIMENSION  # the interpreter refuses cuboids thinner than this

    def fitted(corners) -> tuple[Box, float]:
        box, deviation = fit_box(np.asarray(corners, dtype=float))
        return Box(box.center, box.axes, np.maximum(box.dims, thinnest)), deviation

    leaves: list[Leaf] = []
    for pid in shape.parts:
        if pid in evaluation.removed:
            continue
        group = replaced.get(pid)
        if group is not None:
            if pid != shape.relation(group).members[0]:
                continue
            for i, corners in enumerate(np.asarray(evaluation.instances[group], dtype=float)):
                leaves.append(Leaf(f"{group}[{i}]", tuple(pid.split("/")), *fitted(corners), group, i))
            continue
        leaves.append(Leaf(pid, tuple(pid.split("/")), *fitted(evaluation.parts[pid])))
    return leaves


def _valid_path(path: tuple[str, ...]) -> bool:
    return all(p.startswith(SUBPROGRAM_PREFIX) and not _IDENT.search(p) for p in path[:-1])


def build_blocks(leaves: Sequence[Leaf], turned: frozenset[str] = frozenset()) -> Block:
    """The block tree from the leaves' paths; names made valid and unique. A leaf in
    ``turned`` gets a block of its own (``Program_<name>_turn``), rotated by ``TURN``."""
    root = Block("Program_0", ())
    block_names = {"Program_0"}
    by_path: dict[tuple[str, ...], Block] = {(): root}
    taken: dict[tuple[str, ...], set[str]] = {(): set()}
    for leaf in leaves:
        path = leaf.path if _valid_path(leaf.path) else ("/".join(leaf.path),)
        if leaf.key in turned:
            path = path[:-1] + (f"{SUBPROGRAM_PREFIX}{_IDENT.sub('_', path[-1])}_turn", path[-1])
        block = root
        for depth in range(len(path) - 1):
            sub = path[: depth + 1]
            if sub not in by_path:
                name = path[depth] if path[depth] not in block_names else None
                if name is None:
                    n = 2
                    while f"{path[depth]}_{n}" in block_names:
                        n += 1
                    name = f"{path[depth]}_{n}"
                block_names.add(name)
                child = Block(name, block.path + (name,), turned=leaf.key in turned and depth == len(path) - 2)
                by_path[sub] = child
                taken[sub] = set()
                block.nodes[name] = Node(name, leaf.box, block=child)
                taken[path[:depth]].add(name)
            block = by_path[sub]
        if leaf.group is not None and leaf.index > 0:
            base = next(n.name for n in block.nodes.values() if n.leaf and n.leaf.group == leaf.group)
            name = _identifier(f"{base}_t{leaf.index}", taken[path[:-1]])
        else:
            name = _identifier(path[-1], taken[path[:-1]])
        block.nodes[name] = Node(name, leaf.box, leaf=leaf)
    return root


#: The frame of a block made for one part (``Block.turned``): ``TURN @ part frame``. A
#: rotation the interpreter cannot make (a few 1e-4 radians: its float32 cosines round it
#: off) becomes two it can, the block's and the part's within it, each of about 0.6 rad.
TURN = rotation_matrix((0.5, 0.65, 0.35), 0.68)

#: How blocks choose their frame, in the order tried (see ``_block_frame``).
FRAME_POLICIES = ("common", "shared", "world")


def _block_frame(boxes: Sequence[Box], policy: str) -> np.ndarray:
    """A block's frame: ``common``: the one most of its parts share; ``shared``: the one all
    share, else the world's; ``world``: the world's. Which reproduces the rotations best
    depends on how the source program made them, so the exporter tries them in turn."""
    if policy == "world":
        return np.eye(3)
    frame = _common_frame(boxes)
    if policy == "shared" and not all(same_frame(in_frame(b, np.eye(3)).axes, frame, 1e-9) for b in boxes):
        return np.eye(3)
    return frame


def _common_frame(boxes: Sequence[Box]) -> np.ndarray:
    """The frame most of the boxes share (up to relabelling); among equals, the least rotated.

    Parts rotated together (a tilted back and its slats) then sit aligned in their block,
    and only the block's box is rotated. The interpreter rotates in float32, so a
    rotation it made itself is reproduced better than the product of two, and the
    least rotated frame is most often the one the block's box had."""
    groups: list[list] = []
    for box in boxes:
        frame = in_frame(box, np.eye(3)).axes
        for group in groups:
            if same_frame(frame, group[0], 1e-9):
                group[1] += 1
                break
        else:
            groups.append([frame, 1])
    best = max(groups, key=lambda g: (g[1], -float(np.abs(g[0] - np.eye(3)).max())))
    return best[0]


def place_blocks(block: Block, is_root: bool = True, policy: str = "common") -> None:
    """Choose each block's frame and box (bottom-up) and the sub-block nodes' boxes."""
    for node in block.nodes.values():
        if node.block is not None:
            place_blocks(node.block, False, policy)
            node.box = node.block.box
    leaves = block.leaves()
    if is_root:
        block.frame = np.eye(3)
        corners = np.concatenate([node.box.corners() for node in block.nodes.values()])
        half = np.abs(corners).max(axis=0)
        block.box = Box(np.zeros(3), np.eye(3), 2 * half)
        return
    if block.turned:
        block.frame = TURN @ in_frame(leaves[0].box, np.eye(3)).axes
    else:
        block.frame = _block_frame([leaf.box for leaf in leaves], policy)
    _fit_block_box(block)


def _fit_block_box(block: Block) -> None:
    """The block's box in its frame: it holds every node (leaves and sub-block boxes)."""
    local = np.concatenate([node.box.corners() for node in block.nodes.values()]) @ block.frame.T
    lo, hi = local.min(axis=0), local.max(axis=0)
    block.box = Box(((lo + hi) / 2) @ block.frame, block.frame, hi - lo)


def relabel_frames(block: Block) -> None:
    """Name each sub-block's axes after its parent's nearest axes (top-down), as the parent
    block states the sub-program's cuboid, so that the block's box and that cuboid agree."""
    for node in block.nodes.values():
        if node.block is not None:
            child = node.block
            child.frame = in_frame(Box(np.zeros(3), child.frame, np.ones(3)), block.frame).axes
            _fit_block_box(child)
            node.box = child.box
            relabel_frames(child)


class _Writer:
    """Writes the statements of every block; ``simple`` nodes get box attachments only."""

    def __init__(self, shape: ShapeGraph, evaluation: Evaluation, root: Block, simple: set[str]) -> None:
        self.shape = shape
        self.evaluation = evaluation
        self.root = root
        self.simple = simple
        self.size = shape.size or 1.0
        self.names: dict[str, str] = {}
        self.counts = {"attach": 0, "reflect": 0, "translate": 0, "rotated": 0}
        corners = {pid: np.asarray(evaluation.parts[pid], dtype=float) for pid in shape.parts
                   if pid not in evaluation.removed}
        self.tolerance = tolerance_for(shape)  # what the relation report calls kept
        self.kept = [r for r in shape.relations.values() if all(m in corners for m in r.members)
                     and r.holds(corners, self.tolerance)]
        self.corners = corners

    # -- geometry of one block ---------------------------------------------

    def local_box(self, block: Block, box: Box) -> Box:
        """A world box in the block's frame (centre relative to the block's centre)."""
        frame = block.frame
        local = Box((box.center - block.box.center) @ frame.T, box.axes @ frame.T, box.dims)
        return in_frame(local, np.eye(3))

    # -- statements ---------------------------------------------------------

    def write(self) -> str:
        blocks: list[Block] = []
        queue = [self.root]
        while queue:
            block = queue.pop(0)
            blocks.append(block)
            queue += [n.block for n in block.nodes.values() if n.block is not None]
        return "".join(self.block_text(b) for b in blocks)

    def block_text(self, block: Block) -> str:
        """Declarations first (a macro's copy takes the key ``cube<n>``, which a later declaration
        of that name would overwrite), then the placing statements in order."""
        header = [f"Assembly {block.name} {{", f"\tbbox = Cuboid({_vec(block.box.dims)}, True)"]
        lines: list[str] = []
        local = {name: self.local_box(block, node.box) for name, node in block.nodes.items()}
        half = block.box.dims / 2
        placed: set[str] = set()
        reflections, translations = self.macros(block, local)
        owner = self.owners(block)
        prefix = "/".join(block.path)
        declared: set[str] = set()
        for name, node in block.nodes.items():
            if name in placed:
                continue
            box = local[name]
            aligned = bool(np.array_equal(box.axes, np.eye(3)))
            header.append(f"\t{name} = Cuboid({_vec(box.dims)}, {aligned})")
            macro_source = name in reflections or name in translations
            if aligned:
                lines += self.attach_aligned(block, name, box, local, declared, owner, half, macro_source)
            else:
                lines += self.attach_rotated(name, box, half)
            placed.add(name)
            declared.add(name)
            self.record(prefix, name, node)
            if name in reflections:
                copy, axis = reflections[name]
                lines.append(f"\treflect({name}, {AXIS_NAMES[axis]})")
                placed.add(copy)
                self.counts["reflect"] += 1
                self.record(prefix, f"{name}_ref", block.nodes[copy])
            if name in translations:
                copies, axis, distance = translations[name]
                lines.append(f"\ttranslate({name}, {AXIS_NAMES[axis]}, {len(copies)}, {_num(distance)})")
                self.counts["translate"] += 1
                for i, copy in enumerate(copies, start=1):
                    placed.add(copy)
                    self.record(prefix, f"{name}_t{i}", block.nodes[copy])
        return "\n".join(header + lines + ["}"]) + "\n"

    def record(self, prefix: str, name: str, node: Node) -> None:
        if node.leaf is not None:
            self.names[node.leaf.key] = f"{prefix}/{name}" if prefix else name

    def owners(self, block: Block) -> dict[str, str]:
        """Part id -> the node of this block that holds it (for contacts)."""
        out: dict[str, str] = {}
        for name, node in block.nodes.items():
            leaves = [node.leaf] if node.leaf is not None else node.block.leaves()
            for leaf in leaves:
                if leaf.group is None:
                    out[leaf.key] = name
        return out

    def contacts(self, name: str, owner: Mapping[str, str]) -> list[tuple[str, np.ndarray]]:
        """Kept attachments between node ``name`` and other nodes: (other node, point on ``name``)."""
        out = []
        for relation in self.kept:
            if not isinstance(relation, Attachment):
                continue
            a, b = relation.members
            if owner.get(a) == name and owner.get(b) not in (None, name):
                point = np.asarray(relation.weights_a) @ self.corners[a]
                out.append((owner[b], point.mean(axis=0)))
            elif owner.get(b) == name and owner.get(a) not in (None, name):
                point = np.asarray(relation.weights_b) @ self.corners[b]
                out.append((owner[a], point.mean(axis=0)))
        return out

    def attach_aligned(self, block: Block, name: str, box: Box, local: Mapping[str, Box], declared: set[str],
                       owner: Mapping[str, str], half: np.ndarray, macro_source: bool) -> list[str]:
        """One placing attach (a contact with a placed cuboid, else the box), then the other contacts."""
        lines: list[str] = []
        contacts = [] if f"{block.name}:{name}" in self.simple else self.contacts(name, owner)
        first = True
        for other, world in contacts:
            if other not in declared:
                continue
            if macro_source and not self.symmetric_target(block, name, other, local):
                continue
            point = (world - block.box.center) @ block.frame.T
            target = _local_point(local[other], point, 1e-9 * self.size if macro_source else self.tolerance)
            if target is None:
                continue
            lines.append(f"\tattach({name}, {other}, {_vec(_local_point(box, point))}, {_vec(target)})")
            self.counts["attach"] += 1
            first = False
            if macro_source:
                break
        if first:
            point = _box_anchor(box, half)
            target = point / (2 * half) + 0.5
            lines.insert(0, f"\tattach({name}, bbox, {_vec(_local_point(box, point))}, {_vec(target)})")
            self.counts["attach"] += 1
        return lines

    def symmetric_target(self, block: Block, name: str, other: str, local: Mapping[str, Box]) -> bool:
        """Whether the macro that copies ``name`` maps cuboid ``other`` onto itself."""
        motions = self._motions.get(name, ())
        box = local[other]
        corners = box.corners()
        for motion in motions:
            moved = motion(corners)
            if _set_distance(moved, corners) > 1e-9 * self.size:
                return False
        return True

    def attach_rotated(self, name: str, box: Box, half: np.ndarray) -> list[str]:
        """Two box attachments along a line perpendicular to the rotation axis (see module doc)."""
        self.counts["rotated"] += 1
        best = None
        for a_local, b_local, a_target, b_target in _rotation_lines(box, half):
            lines = [f"\tattach({name}, bbox, {_vec(a_local)}, {_vec(a_target)})",
                     f"\tattach({name}, bbox, {_vec(b_local)}, {_vec(b_target)})"]
            text = (f"Assembly Program_0 {{\n\tbbox = Cuboid({_vec(2 * half)}, True)\n"
                    f"\tc = Cuboid({_vec(box.dims)}, False)\n"
                    + "\n".join(line.replace(f"({name},", "(c,") for line in lines) + "\n}\n")
            try:
                got = execute(text).cuboids[0].corners()
            except ValueError:
                continue
            error = _set_distance(got, box.corners())
            if best is None or error < best[0]:
                best = (error, lines)
            if error <= 1e-10 * self.size:
                break
        self.counts["attach"] += 2
        if best is None:
            raise ParselError(f"cuboid {name}: no attachment reproduces its rotation")
        return best[1]

    # -- macros -------------------------------------------------------------

    def macros(self, block: Block, local: Mapping[str, Box]):
        """Reflection pairs and translation groups of this block that the macros reproduce."""
        self._motions: dict[str, list] = {}
        reflections: dict[str, tuple[str, int]] = {}
        translations: dict[str, tuple[list[str], int, float]] = {}
        node_of = {node.leaf.key: name for name, node in block.nodes.items() if node.leaf is not None}
        used = {name for name in block.nodes if f"{block.name}:{name}" in self.simple}
        order = list(block.nodes)
        size = self.size
        half = block.box.dims / 2
        for relation in self.kept:
            if not isinstance(relation, ReflectionSymmetry):
                continue
            names = [node_of.get(m) for m in relation.members]
            if None in names or set(names) & used:
                continue
            source, copy = sorted(names, key=order.index)
            if f"{source}_ref" in block.nodes and f"{source}_ref" != copy:
                continue
            for axis in range(3):
                def mirror(points, axis=axis):
                    out = np.array(points, dtype=float)
                    out[..., axis] *= -1
                    return out
                if _set_distance(mirror(local[source].corners()), local[copy].corners()) <= 1e-9 * size:
                    reflections[source] = (copy, axis)
                    self._motions[source] = [mirror]
                    used.update(names)
                    break
        groups: dict[str, list[str]] = {}
        for name, node in block.nodes.items():
            if node.leaf is not None and node.leaf.group is not None:
                groups.setdefault(node.leaf.group, []).append(name)
        for relation in self.kept:
            if isinstance(relation, TranslationSymmetry) and relation.id not in groups:
                names = [node_of.get(m) for m in relation.members]
                if None not in names:
                    groups[relation.id] = names
        for names in groups.values():
            if len(names) < 2 or set(names) & used or min(names, key=order.index) != names[0]:
                continue
            if any(f"{names[0]}_t{i}" in block.nodes and f"{names[0]}_t{i}" != n
                   for i, n in enumerate(names[1:], start=1)):
                continue
            boxes = [local[n] for n in names]
            step = boxes[1].center - boxes[0].center
            axis = int(np.argmax(np.abs(step)))
            off_axis = np.delete(step, axis)
            if np.abs(off_axis).max() > 1e-12 * size or abs(step[axis]) < 1e-9 * size:
                continue
            exact = all(np.abs(b.dims - boxes[0].dims).max() <= 1e-12 * size
                        and np.array_equal(b.axes, boxes[0].axes)
                        and np.abs(b.center - boxes[0].center - i * step).max() <= 1e-12 * size
                        for i, b in enumerate(boxes))
            if not exact:
                continue
            count = len(names) - 1
            translations[names[0]] = (names[1:], axis, float(step[axis]) * count / float(2 * half[axis]))
            offsets = [np.eye(3)[axis] * step[axis] * i for i in range(1, count + 1)]
            self._motions[names[0]] = [lambda p, o=o: p + o for o in offsets]
            used.update(names)
        return reflections, translations


def _set_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Largest distance from a corner of ``b`` to the nearest corner of ``a`` (and back)."""
    d = np.linalg.norm(np.asarray(a)[:, None, :] - np.asarray(b)[None, :, :], axis=-1)
    return float(max(d.min(axis=0).max(), d.min(axis=1).max()))


def _local_point(box: Box, point: np.ndarray, outside: float | None = None) -> np.ndarray | None:
    """Coordinates of ``point`` in ``box``'s [0, 1]^3. With ``outside``: ``None`` when the point
    lies farther than that outside the box; a point on the box's surface up to rounding is
    clipped into [0, 1], one a little farther keeps its coordinates (so it is met exactly)."""
    local = ((point - box.center) @ box.axes.T) / box.dims + 0.5
    if outside is None:
        return local
    clipped = np.clip(local, 0.0, 1.0)
    gap = float(np.abs((clipped - local) * box.dims).max())
    if gap > outside:
        return None
    return clipped if gap <= 1e-12 * float(box.dims.max()) else local


def _box_anchor(box: Box, half: np.ndarray) -> np.ndarray:
    """Where an aligned cuboid meets the block's box: the centre of the face on the box's
    bottom, top or a side when it touches one, else its centre."""
    lo, hi = box.center - box.dims / 2, box.center + box.dims / 2
    point = box.center.copy()
    for axis in (1, 0, 2):
        scale = max(float(half[axis]), 1e-12)
        if abs(lo[axis] + half[axis]) <= 1e-9 * scale:
            point[axis] = lo[axis]
            break
        if abs(hi[axis] - half[axis]) <= 1e-9 * scale:
            point[axis] = hi[axis]
            break
    return point


def _rotation_lines(box: Box, half: np.ndarray):
    """Candidate (moved A, moved B, target A, target B) local points for a rotated cuboid.

    The cuboid starts aligned (axes = identity), so its rotation is ``R = axes.T``; a line
    through the centre along ``d``, perpendicular to R's axis, turns onto ``R d`` by the
    minimal rotation, which is R."""
    from scipy.spatial.transform import Rotation

    rotation = box.axes.T
    rotvec = Rotation.from_matrix(rotation).as_rotvec()
    angle = float(np.linalg.norm(rotvec))
    axis = rotvec / angle if angle > 0 else np.array([1.0, 0.0, 0.0])
    helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
    e1 = np.cross(axis, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    for length in ROTATION_LENGTHS:
        for k in range(ROTATION_TRIES):
            yield _rotation_line(box, half, rotation, math.cos(math.pi * k / ROTATION_TRIES) * e1
                                 + math.sin(math.pi * k / ROTATION_TRIES) * e2, length)


def _rotation_line(box: Box, half: np.ndarray, rotation: np.ndarray, d: np.ndarray, length: float):
    """The two points of one line along ``d`` (``length`` of the longest that fits in the cuboid)."""
    s = length * 0.5 / float(np.max(np.abs(d) / box.dims))
    a_local = 0.5 - s * d / box.dims
    b_local = 0.5 + s * d / box.dims
    xa = box.center - s * (rotation @ d)
    xb = box.center + s * (rotation @ d)
    return a_local, b_local, xa / (2 * half) + 0.5, xb / (2 * half) + 0.5


def _executed_corners(text: str) -> dict[str, np.ndarray]:
    return {c.name: c.corners() for c in execute(text).cuboids}


def export_program(shape: ShapeGraph, evaluation: Evaluation) -> ShapeAssemblyExport:
    """The ShapeAssembly program of ``shape`` as edited (see the module docstring)."""
    leaves = collect_leaves(shape, evaluation)
    if not leaves:
        raise ParselError(f"shape {shape.name!r}: nothing to write (every part was removed)")
    best = None
    for policy in FRAME_POLICIES:
        attempt = _attempt(shape, evaluation, leaves, policy, frozenset())
        if best is None or attempt[0] < best[0]:
            best = attempt
        if not best[1].inexact:
            return best[1]
    # parts that still do not come back: rotations too small for the interpreter; give each a turned block
    retry = _attempt(shape, evaluation, leaves, best[2], frozenset(best[1].inexact))
    return (retry if retry[0] < best[0] else best)[1]


def _attempt(shape: ShapeGraph, evaluation: Evaluation, leaves: Sequence[Leaf], policy: str,
             turned: frozenset[str], rounds: int = 3) -> tuple[tuple[float, float], ShapeAssemblyExport, str]:
    """Write, execute and compare; cuboids that do not come back lose their macros and
    contacts for the next round. Returns (score, export, policy), lower scores better."""
    size = shape.size or 1.0
    expected = {leaf.key: leaf.box.corners() for leaf in leaves}
    non_cuboids = {leaf.key: leaf.deviation for leaf in leaves if leaf.deviation > CUBOID_TOLERANCE * size}
    simple: set[str] = set()
    for _ in range(rounds):
        root = build_blocks(leaves, turned)
        place_blocks(root, policy=policy)
        relabel_frames(root)
        writer = _Writer(shape, evaluation, root, simple)
        text = writer.write()
        got = _executed_corners(text)
        errors = {key: (_set_distance(got[name], expected[key]) if name in got else math.inf)
                  for key, name in writer.names.items()}
        bad = {key for key, err in errors.items() if err > MATCH_TOLERANCE * size}
        more = _nodes_of(root, bad) - simple
        if not bad or not more:
            break
        simple |= more
    inexact = {key: err for key, err in errors.items() if err > MATCH_TOLERANCE * size}
    score = (len(inexact), max(inexact.values(), default=0.0))
    return score, ShapeAssemblyExport(text, dict(writer.names), expected, non_cuboids, inexact,
                                      dict(writer.counts)), policy


def _nodes_of(block: Block, keys: set[str]) -> set[str]:
    """Names of the nodes (leaves and sub-blocks) on the way to the given leaves."""
    out: set[str] = set()
    for name, node in block.nodes.items():
        if node.leaf is not None and node.leaf.key in keys:
            out.add(f"{block.name}:{name}")
        elif node.block is not None:
            inner = _nodes_of(node.block, keys)
            if inner:
                out |= inner | {f"{block.name}:{name}"}
    return out


class ShapeAssemblyExporter(Exporter):
    """``.sa.txt`` / ``.sa``: the edited shape as a ShapeAssembly program."""

    name = "shapeassembly"
    extensions = (".sa.txt", ".sa")

    def export(self, shape: ShapeGraph, evaluation: Evaluation, path: Path) -> None:
        import sys

        from parsel_core.io import atomic_write_text

        result = export_program(shape, evaluation)
        atomic_write_text(Path(path), result.text)
        for note in result.notes():
            print(f"parsel: note: {Path(path).name}: {note}", file=sys.stderr)
