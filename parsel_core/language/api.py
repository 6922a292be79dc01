"""The seed-edit reply API: Python-like code a model writes, read with :mod:`ast`, never run.

A model answers the seed-edit prompt with a short snippet such as::

    seat = part("seat")
    scale_1d(seat, origin=seat.center(), dir="x", amount=x)

The snippet is parsed into a tree and walked by a small interpreter that knows only the
calls, methods, names and literals listed in docs/language.md: ``part``, ``group``,
``cannot_edit``, one call per registered edit operator, and the methods ``center``,
``face``, ``edge``, ``corner`` and ``axis`` of part references. Anything else (imports,
attribute access to dunders, loops, unknown calls, arithmetic outside ``amount=``) is a
:class:`ReplyError` naming the culprit. Walking the tree only builds values of the
types below and :class:`parsel_core.ops.EditOp` instances; no model text reaches
``eval``, ``exec`` or ``compile``.

Directional words name world directions (+x right, +y up, +z front); a face named by a
word is the hexahedron face whose outward normal is closest to that direction.
"""

from __future__ import annotations

import ast
import dataclasses
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from parsel_core.errors import ParselError, ProgramFormatError
from parsel_core.expressions import parse_expression
from parsel_core.graph import GROUP_KINDS, ShapeGraph
from parsel_core.hexahedron import AXES, FACE_NAMES, canonical_feature_name, feature_corners
from parsel_core.ops import EditOp

#: World directions by word. Left/right are as seen from the front (+z looks at the viewer).
DIRECTION_WORDS: dict[str, tuple[float, float, float]] = {
    "x": (1.0, 0.0, 0.0), "+x": (1.0, 0.0, 0.0), "-x": (-1.0, 0.0, 0.0),
    "y": (0.0, 1.0, 0.0), "+y": (0.0, 1.0, 0.0), "-y": (0.0, -1.0, 0.0),
    "z": (0.0, 0.0, 1.0), "+z": (0.0, 0.0, 1.0), "-z": (0.0, 0.0, -1.0),
    "right": (1.0, 0.0, 0.0), "left": (-1.0, 0.0, 0.0),
    "up": (0.0, 1.0, 0.0), "top": (0.0, 1.0, 0.0), "upward": (0.0, 1.0, 0.0), "upwards": (0.0, 1.0, 0.0),
    "down": (0.0, -1.0, 0.0), "bottom": (0.0, -1.0, 0.0), "downward": (0.0, -1.0, 0.0),
    "downwards": (0.0, -1.0, 0.0),
    "front": (0.0, 0.0, 1.0), "forward": (0.0, 0.0, 1.0), "forwards": (0.0, 0.0, 1.0),
    "back": (0.0, 0.0, -1.0), "backward": (0.0, 0.0, -1.0), "backwards": (0.0, 0.0, -1.0),
    "rear": (0.0, 0.0, -1.0),
}
#: Words that name a face of a hexahedron by the world direction of its outward normal.
FACE_WORDS = ("top", "bottom", "left", "right", "front", "back", "up", "down", "rear", "upper", "lower")
_FACE_ALIASES = {"upper": "top", "lower": "bottom", "up": "top", "down": "bottom", "rear": "back"}
_IDENTIFIER = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
PART_METHODS = ("center", "centre", "face", "edge", "corner", "axis")
API_CALLS = ("part", "group", "cannot_edit")
MAX_CODE = 20_000
MAX_STATEMENTS = 60
MAX_OPS = 12


class ReplyError(ParselError):
    """A reply that cannot be used: the message is the reason reported for that sample."""


@dataclass(frozen=True)
class PartRef:
    """A part (or a group's virtual parent) of the shape, by id."""

    id: str


@dataclass(frozen=True)
class FeatureRef:
    """A face, edge or corner of a part, by canonical feature name (``v+``, ``u-v+``)."""

    part: str
    feature: str


@dataclass(frozen=True)
class GroupRef:
    """A translation or rotation symmetry group, by relation id."""

    id: str


@dataclass(frozen=True)
class Point:
    xyz: tuple[float, float, float]


@dataclass(frozen=True)
class Direction:
    xyz: tuple[float, float, float]


@dataclass(frozen=True)
class Cannot:
    """The model's statement that the request cannot be expressed as an edit."""

    reason: str


@dataclass(frozen=True)
class SeedReply:
    """What a seed-edit reply says: edit ops, or that it cannot edit (``cannot``)."""

    ops: tuple[EditOp, ...] = ()
    cannot: str | None = None


def code_blocks(reply: str) -> list[str]:
    """Every fenced code block of a reply, in order; the whole reply when it has no fence.

    A reply whose last fence is opened but never closed was cut off: that is an error,
    not something to guess around.
    """
    if not isinstance(reply, str) or not reply.strip():
        raise ReplyError("empty reply")
    if len(reply) > 4 * MAX_CODE:
        raise ReplyError(f"reply of {len(reply)} characters is too long")
    fences = [m.start() for m in re.finditer(r"^[ \t]*```", reply, re.M)]
    if not fences:
        return [reply.strip()]
    if len(fences) % 2:
        raise ReplyError("partial reply: a ``` code block is opened but never closed")
    blocks = []
    for start, end in zip(fences[0::2], fences[1::2]):
        block = reply[start:end]
        newline = block.find("\n")
        code = block[newline + 1:] if newline >= 0 else ""
        blocks.append(code)
    if not any(code.strip() for code in blocks):
        raise ReplyError("empty code block")
    return blocks


def extract_code(reply: str) -> str:
    """The last non-empty fenced code block of a reply; the whole reply when it has no fence."""
    return [code for code in code_blocks(reply) if code.strip()][-1]


def read_blocks(reply: str, reader):
    """Read a reply whose answer may be any of its code blocks: the first block ``reader``
    accepts wins. Returns (value, index of that block, number of blocks); when no block is
    accepted, the first block's error is raised (naming the block when there are several).
    """
    blocks = [code for code in code_blocks(reply) if code.strip()]
    errors: list[ReplyError] = []
    for index, code in enumerate(blocks):
        try:
            return reader(code), index, len(blocks)
        except ReplyError as exc:
            errors.append(exc)
    if len(blocks) == 1:
        raise errors[0]
    raise ReplyError(f"none of the {len(blocks)} code blocks is an answer; block 1: {errors[0]}")


def parse_code(code: str) -> list[ast.stmt]:
    """The statements of a code snippet, with a clear reason when it does not parse."""
    if len(code) > MAX_CODE:
        raise ReplyError(f"code of {len(code)} characters is too long (limit {MAX_CODE})")
    try:
        tree = ast.parse(code, mode="exec")
    except SyntaxError as exc:
        raise ReplyError(f"malformed code: {exc.msg} (line {exc.lineno})") from None
    except (ValueError, RecursionError, MemoryError) as exc:
        raise ReplyError(f"malformed code: {exc}") from None
    if len(tree.body) > MAX_STATEMENTS:
        raise ReplyError(f"too many statements ({len(tree.body)}, limit {MAX_STATEMENTS})")
    _prescan(tree)
    return tree.body


def _prescan(tree: ast.AST) -> None:
    """Refuse the smuggling forms anywhere in the tree, naming the first in reading order:
    imports, and attributes or names that start with an underscore (dunders)."""
    found: list[tuple[int, int, str]] = []
    for node in ast.walk(tree):
        where = (getattr(node, "lineno", 0), getattr(node, "col_offset", 0))
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            found.append((*where, f"line {where[0]}: imports are not allowed"))
        elif isinstance(node, ast.Attribute) and node.attr.startswith("_"):
            end = (getattr(node, "end_lineno", where[0]), getattr(node, "end_col_offset", where[1]))
            found.append((*end, f"line {where[0]}: attribute access to {node.attr!r} is not allowed"))
        elif isinstance(node, ast.Name) and node.id.startswith("__"):
            found.append((*where, f"line {where[0]}: name {node.id!r} is not allowed"))
    if found:
        raise ReplyError(min(found)[2])


def _statement_error(node: ast.stmt) -> ReplyError:
    if isinstance(node, (ast.Import, ast.ImportFrom)):
        return ReplyError(f"line {node.lineno}: imports are not allowed")
    kind = type(node).__name__
    return ReplyError(f"line {node.lineno}: {kind} statements are not allowed (only assignments and API calls)")


def face_for_word(hexahedron, word: str) -> str:
    """The face (``u+`` ...) named by a direction word or given by its canonical name."""
    if word in FACE_NAMES:
        return word
    key = _FACE_ALIASES.get(word, word)
    if key not in DIRECTION_WORDS or key in ("x", "y", "z", "+x", "+y", "+z", "-x", "-y", "-z"):
        raise ReplyError(f"unknown face {word!r} (use top, bottom, left, right, front, back or u+, v-, ...)")
    target = np.asarray(DIRECTION_WORDS[key])
    scores = [float(hexahedron.face_normal(name) @ target) for name in FACE_NAMES]
    return FACE_NAMES[int(np.argmax(scores))]


def resolve_direction(value: Any, where: str) -> tuple[float, float, float]:
    """A direction from a word, a tuple of three numbers or a :class:`Direction`."""
    if isinstance(value, Direction):
        return value.xyz
    if isinstance(value, str):
        key = value.strip().lower()
        if key not in DIRECTION_WORDS:
            raise ReplyError(f"{where}: unknown direction {value!r} (use x, y, z, -x, up, down, left, right, "
                             "front, back or three numbers)")
        return DIRECTION_WORDS[key]
    if isinstance(value, tuple) and len(value) == 3 and all(isinstance(v, (int, float)) for v in value):
        vector = np.asarray(value, dtype=float)
        if not np.all(np.isfinite(vector)) or np.linalg.norm(vector) < 1e-12:
            raise ReplyError(f"{where}: direction {value!r} must be finite and non-zero")
        return tuple(float(v) for v in vector)
    raise ReplyError(f"{where}: expected a direction (a word like 'x' or 'up', or three numbers), got "
                     f"{_show(value)}")


def _show(value: Any) -> str:
    if isinstance(value, PartRef):
        return f"part {value.id!r}"
    if isinstance(value, FeatureRef):
        return f"a feature of {value.part!r}"
    if isinstance(value, GroupRef):
        return f"group {value.id!r}"
    return repr(value)


class SeedInterpreter:
    """Reads one seed-edit snippet against a shape and the registered operators."""

    def __init__(self, shape: ShapeGraph, registry: Mapping[str, type[EditOp]], parameter: str = "x") -> None:
        self.shape = shape
        self.registry = dict(registry)
        self.parameter = parameter
        self.names: dict[str, Any] = {}
        self.ops: list[EditOp] = []
        self.cannot: list[str] = []

    # -- statements ----------------------------------------------------------------

    def run(self, code: str) -> SeedReply:
        for node in parse_code(code):
            self.statement(node)
        if self.cannot and self.ops:
            raise ReplyError("the reply both edits and calls cannot_edit()")
        if self.cannot:
            return SeedReply(cannot=self.cannot[0])
        if not self.ops:
            raise ReplyError("no edit: the code calls no edit operator")
        if len(self.ops) > MAX_OPS:
            raise ReplyError(f"too many edits ({len(self.ops)}, limit {MAX_OPS})")
        return SeedReply(tuple(self.ops))

    def statement(self, node: ast.stmt) -> None:
        if isinstance(node, ast.Pass):
            return
        if isinstance(node, ast.Expr):
            if isinstance(node.value, ast.Constant) and isinstance(node.value.value, str):
                return  # a docstring-like note
            self.expression(node.value)
            if not isinstance(node.value, ast.Call):
                raise ReplyError(f"line {node.lineno}: a bare expression does nothing; call an edit operator")
            return
        if isinstance(node, ast.Assign):
            if len(node.targets) != 1 or not isinstance(node.targets[0], ast.Name):
                raise ReplyError(f"line {node.lineno}: only simple assignments like 'seat = part(\"seat\")'")
            name = node.targets[0].id
            self._check_binding(name, node.lineno)
            self.names[name] = self.expression(node.value)
            return
        raise _statement_error(node)

    def _check_binding(self, name: str, line: int) -> None:
        if name.startswith("_"):
            raise ReplyError(f"line {line}: names starting with '_' are not allowed ({name!r})")
        if name in API_CALLS or name in self.registry or name in (self.parameter, "pi", "e"):
            raise ReplyError(f"line {line}: cannot assign to the reserved name {name!r}")

    # -- expressions ---------------------------------------------------------------

    def expression(self, node: ast.expr) -> Any:
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float, str)):
                raise ReplyError(f"line {node.lineno}: literal {node.value!r} is not allowed here")
            return node.value
        if isinstance(node, ast.Name):
            if node.id.startswith("_"):
                raise ReplyError(f"line {node.lineno}: name {node.id!r} is not allowed")
            if node.id in self.names:
                return self.names[node.id]
            if node.id == self.parameter:
                raise ReplyError(f"line {node.lineno}: the parameter {node.id!r} belongs in amount=")
            raise ReplyError(f"line {node.lineno}: unknown name {node.id!r}")
        if isinstance(node, (ast.Tuple, ast.List)):
            values = tuple(self.expression(e) for e in node.elts)
            if len(values) != 3 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
                raise ReplyError(f"line {node.lineno}: a tuple must be three numbers (a point or direction)")
            return tuple(float(v) for v in values)
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            value = self.expression(node.operand)
            sign = -1.0 if isinstance(node.op, ast.USub) else 1.0
            if isinstance(value, (int, float)):
                return sign * value
            if isinstance(value, Direction):
                return Direction(tuple(sign * c for c in value.xyz))
            raise ReplyError(f"line {node.lineno}: cannot negate {_show(value)}")
        if isinstance(node, ast.Attribute):
            if node.attr.startswith("_"):
                raise ReplyError(f"line {node.lineno}: attribute access to {node.attr!r} is not allowed")
            raise ReplyError(f"line {node.lineno}: .{node.attr} must be called as a method "
                             f"({', '.join(PART_METHODS)})")
        if isinstance(node, ast.Call):
            return self.call(node)
        if isinstance(node, ast.BinOp):
            raise ReplyError(f"line {node.lineno}: arithmetic is only allowed in amount=")
        raise ReplyError(f"line {getattr(node, 'lineno', '?')}: {type(node).__name__} is not allowed")

    def call(self, node: ast.Call) -> Any:
        if any(isinstance(a, ast.Starred) for a in node.args) or any(k.arg is None for k in node.keywords):
            raise ReplyError(f"line {node.lineno}: * and ** arguments are not allowed")
        func = node.func
        if isinstance(func, ast.Attribute):
            if func.attr.startswith("_"):
                raise ReplyError(f"line {node.lineno}: attribute access to {func.attr!r} is not allowed")
            target = self.expression(func.value)
            return self.method(target, func.attr, node)
        if not isinstance(func, ast.Name):
            raise ReplyError(f"line {node.lineno}: only API functions may be called")
        name = func.id
        if name.startswith("_"):
            raise ReplyError(f"line {node.lineno}: call to {name!r} is not allowed")
        if name == "part":
            return self.part(self._one_string(node, "part"), node.lineno)
        if name == "group":
            return self.group(self._one_string(node, "group"), node.lineno)
        if name == "cannot_edit":
            reason = self._one_string(node, "cannot_edit")
            self.cannot.append(" ".join(reason.split())[:500])
            return None
        if name in self.registry:
            op = self.edit(self.registry[name], node)
            self.ops.append(op)
            return op
        allowed = ", ".join(sorted([*API_CALLS, *self.registry]))
        raise ReplyError(f"line {node.lineno}: call to {name!r} is outside the API (allowed: {allowed})")

    def _one_string(self, node: ast.Call, name: str) -> str:
        if len(node.args) != 1 or node.keywords:
            raise ReplyError(f"line {node.lineno}: {name}() takes one string")
        value = self.expression(node.args[0])
        if not isinstance(value, str):
            raise ReplyError(f"line {node.lineno}: {name}() takes a string, got {_show(value)}")
        return value

    def part(self, pid: str, line: int) -> PartRef:
        if pid not in self.shape.parts and pid not in self.shape.virtual_parents:
            raise ReplyError(f"line {line}: unknown part {pid!r}")
        return PartRef(pid)

    def group(self, gid: str, line: int) -> GroupRef:
        relation = self.shape.relations.get(gid)
        if relation is None or relation.kind not in GROUP_KINDS:
            groups = ", ".join(r.id for r in self.shape.relations.values() if r.kind in GROUP_KINDS) or "none"
            raise ReplyError(f"line {line}: unknown group {gid!r} (groups: {groups})")
        return GroupRef(gid)

    def method(self, target: Any, name: str, node: ast.Call) -> Any:
        line = node.lineno
        if name not in PART_METHODS:
            raise ReplyError(f"line {line}: unknown method .{name}() (allowed: {', '.join(PART_METHODS)})")
        if isinstance(target, GroupRef):
            target = PartRef(target.id)
        if not isinstance(target, PartRef):
            raise ReplyError(f"line {line}: .{name}() needs a part, got {_show(target)}")
        if node.keywords:
            raise ReplyError(f"line {line}: .{name}() takes positional arguments only")
        args = [self.expression(a) for a in node.args]
        if not all(isinstance(a, str) for a in args):
            raise ReplyError(f"line {line}: .{name}() takes face words like 'top' or names like 'u+'")
        hexahedron = self.shape.part(target.id).hexahedron
        if name in ("center", "centre"):
            if args:
                raise ReplyError(f"line {line}: .{name}() takes no arguments")
            return Point(tuple(float(v) for v in hexahedron.center))
        if name == "axis":
            if len(args) != 1:
                raise ReplyError(f"line {line}: .axis() takes one name: u, v, w or a face word")
            word = args[0]
            if word in AXES:
                return Direction(tuple(float(v) for v in hexahedron.local_axes[AXES.index(word)]))
            return Direction(tuple(float(v) for v in hexahedron.face_normal(self._face(hexahedron, word, line))))
        expected = {"face": 1, "edge": 2, "corner": 3}[name]
        if len(args) == 1 and re.fullmatch(rf"([uvw][+-]){{{expected}}}", args[0]):
            feature = args[0]
        else:
            if len(args) != expected:
                raise ReplyError(f"line {line}: .{name}() takes {expected} face word(s), got {len(args)}")
            feature = "".join(self._face(hexahedron, word, line) for word in args)
        try:
            feature_corners(feature)
        except ValueError:
            raise ReplyError(f"line {line}: {', '.join(args)} do not name one {name} (two of them lie on the same "
                             "axis)") from None
        if target.id in self.shape.virtual_parents:
            raise ReplyError(f"line {line}: features of the group {target.id!r} cannot be edited; "
                             "edit one of its parts")
        return FeatureRef(target.id, canonical_feature_name(feature))

    @staticmethod
    def _face(hexahedron, word: str, line: int) -> str:
        try:
            return face_for_word(hexahedron, word if word in FACE_NAMES else word.strip().lower())
        except ReplyError as exc:
            raise ReplyError(f"line {line}: {exc}") from None

    # -- edit operators --------------------------------------------------------------

    def point(self, value: Any, where: str) -> tuple[float, float, float]:
        if isinstance(value, Point):
            return value.xyz
        if isinstance(value, PartRef):
            return tuple(float(v) for v in self.shape.part(value.id).hexahedron.center)
        if isinstance(value, GroupRef):
            return tuple(float(v) for v in self.shape.part(value.id).hexahedron.center)
        if isinstance(value, FeatureRef):
            corners = self.shape.part(value.part).hexahedron.corners[list(feature_corners(value.feature))]
            return tuple(float(v) for v in corners.mean(axis=0))
        if isinstance(value, tuple) and len(value) == 3:
            return value
        raise ReplyError(f"{where}: expected a point (a part, a feature, part.center() or three numbers), "
                         f"got {_show(value)}")

    def amount(self, node: ast.expr, where: str) -> str:
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            text = node.value
        elif isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not isinstance(
                node.value, bool):
            text = repr(node.value)
        else:
            text = ast.unparse(node)
        text = radians_to_pi(text)
        try:
            expression = parse_expression(text)
        except ProgramFormatError as exc:
            raise ReplyError(f"{where}: {exc}") from None
        unknown = sorted(expression.names - {self.parameter})
        if unknown:
            raise ReplyError(f"{where}: amount {text!r} uses unknown name(s) {', '.join(unknown)} "
                             f"(only {self.parameter!r})")
        if self.parameter not in expression.names:
            raise ReplyError(f"{where}: amount {text!r} must depend on {self.parameter!r}")
        return expression.text

    def edit(self, cls: type[EditOp], node: ast.Call) -> EditOp:
        where = f"line {node.lineno}: {cls.name}()"
        if len(node.args) != 1:
            raise ReplyError(f"{where} takes the part (or group) first, then keyword arguments")
        target = self.expression(node.args[0])
        data: dict[str, Any] = {}
        if cls.acts_on == "group":
            if isinstance(target, PartRef) and target.id in self.shape.virtual_parents:
                target = GroupRef(target.id)
            if not isinstance(target, GroupRef):
                raise ReplyError(f"{where} edits a symmetry group: pass group(\"...\"), got {_show(target)}")
            data["operand"] = target.id
        elif isinstance(target, FeatureRef):
            data["operand"], data["feature"] = target.part, target.feature
        elif isinstance(target, (PartRef, GroupRef)):
            data["operand"] = target.id
        else:
            raise ReplyError(f"{where} needs a part or a feature first, got {_show(target)}")
        fields = {f.name for f in dataclasses.fields(cls)} - {"operand", "feature"}
        for keyword in node.keywords:
            key = keyword.arg
            if key not in fields:
                raise ReplyError(f"{where} has no argument {key!r} (arguments: {', '.join(sorted(fields))})")
            if key in data:
                raise ReplyError(f"{where}: argument {key!r} given twice")
            if key == "amount":
                data[key] = self.amount(keyword.value, where)
                continue
            value = self.expression(keyword.value)
            if key in cls.unit_fields:
                data[key] = resolve_direction(value, f"{where} {key}=")
            elif key in cls.point_fields:
                data[key] = self.point(value, f"{where} {key}=")
            elif isinstance(value, (str, int, float)):
                data[key] = value
            else:
                raise ReplyError(f"{where} {key}= must be a number or a string, got {_show(value)}")
        if cls.name != "keep_fixed" and "amount" not in data:
            raise ReplyError(f"{where} needs amount= (an expression of {self.parameter})")
        missing = [name for name in cls.unit_fields if name not in data]
        if missing:
            raise ReplyError(f"{where} needs {', '.join(f'{m}=' for m in missing)} (a direction)")
        for name in cls.point_fields:
            if name not in data:  # documented default: the target's own centre
                data[name] = self.point(target if not isinstance(target, FeatureRef) else PartRef(target.part),
                                        where)
        try:
            return cls(**data)
        except (ProgramFormatError, TypeError, ValueError) as exc:
            raise ReplyError(f"{where}: {exc}") from None


class _Radians(ast.NodeTransformer):
    def visit_Call(self, node: ast.Call) -> ast.AST:  # noqa: N802 (ast's naming)
        self.generic_visit(node)
        if isinstance(node.func, ast.Name) and node.func.id == "radians" and len(node.args) == 1 \
                and not node.keywords:
            degrees = ast.BinOp(node.args[0], ast.Mult(), ast.Name("pi", ast.Load()))
            return ast.BinOp(degrees, ast.Div(), ast.Constant(180))
        return node


def radians_to_pi(text: str) -> str:
    """``radians(15) * x`` -> ``15 * pi / 180 * x``: models often write angles this way, and the
    amount language (docs/dsl.md) knows ``pi`` but not ``radians``."""
    if "radians" not in text:
        return text
    try:
        tree = ast.parse(text, mode="eval")
    except (SyntaxError, ValueError, RecursionError):
        return text
    return ast.unparse(_Radians().visit(tree))


def parse_seed_code(code: str, shape: ShapeGraph, registry: Mapping[str, type[EditOp]] | None = None,
                    parameter: str = "x") -> SeedReply:
    """Read a seed-edit snippet into ops (or a ``cannot_edit`` reason); raises :class:`ReplyError`."""
    if registry is None:
        from parsel_core.plugins import edit_operators

        registry = edit_operators()
    return SeedInterpreter(shape, registry, parameter).run(code)


def parse_seed_reply(reply: str, shape: ShapeGraph, registry: Mapping[str, type[EditOp]] | None = None,
                     parameter: str = "x") -> SeedReply:
    """A whole reply (reasoning, then code blocks) read into a :class:`SeedReply`: the first
    block that reads as a seed edit is the answer."""
    return read_blocks(reply, lambda code: parse_seed_code(code, shape, registry, parameter))[0]


def is_identifier(text: str) -> bool:
    return bool(_IDENTIFIER.match(text))
