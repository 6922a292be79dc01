"""Parser for ShapeAssembly program text.

The text is tokenised line by line with regular expressions and turned into
frozen dataclasses; program text is never handed to ``eval``/``exec``.  The
parser performs every check that can be made without executing geometry
(argument counts and types, faces/axes, cuboids used before they are
declared, balanced braces, sub-program blocks that exist and do not form a
cycle), so that the executor only has to deal with well-formed programs and
every malformed input is reported with the file and line it comes from.

Grammar accepted (one statement per line, blank lines and ``#`` comments
ignored)::

    Assembly NAME {
        bbox = Cuboid(l, h, w, aligned)          # first statement of a block
        NAME = Cuboid(l, h, w[, True|False])
        attach(c1, c2, x1, y1, z1, x2, y2, z2)
        squeeze(c1, c2, c3, face, u, v)
        reflect(c, X|Y|Z)
        translate(c, X|Y|Z, n, d)
    }

A cuboid whose name starts with ``Program_`` stands for the bounding box of
the ``Assembly`` block of the same name.  The first block is the root.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

__all__ = [
    "AXES",
    "FACES",
    "AttachStmt",
    "Block",
    "CuboidStmt",
    "ProgramAST",
    "ReflectStmt",
    "ShapeAssemblyError",
    "SqueezeStmt",
    "Statement",
    "TranslateStmt",
    "parse_program",
]

FACES: tuple[str, ...] = ("right", "left", "top", "bot", "front", "back")
AXES: tuple[str, ...] = ("X", "Y", "Z")
SUBPROGRAM_PREFIX = "Program_"
# Far above the corpus maximum (36); guards against runaway input.
MAX_TRANSLATE_COUNT = 1000
#: Thinner cuboids have no usable cage (their corner Jacobians vanish in float64).
MIN_DIMENSION = 1e-6

_NAME = r"[A-Za-z_][A-Za-z0-9_]*"
_NAME_RE = re.compile(rf"^{_NAME}$")
_NUMBER_RE = re.compile(r"^[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?$")
_INT_RE = re.compile(r"^\+?\d+$")
_BLOCK_OPEN_RE = re.compile(rf"^Assembly\s+({_NAME})\s*\{{$")
_ASSIGN_RE = re.compile(rf"^({_NAME})\s*=\s*(.*)$")
_CALL_RE = re.compile(rf"^({_NAME})\s*\((.*)\)\s*;?$")


class ShapeAssemblyError(ValueError):
    """Malformed or non-executable ShapeAssembly input.

    The message is a single line ``<source>:<line>: <what is wrong>`` so that
    a failing corpus file can be located without a traceback.
    """

    def __init__(self, message: str, source: str | None = None, line: int | None = None) -> None:
        self.source = source
        self.line = line
        self.detail = message
        if source is None and line is None:
            super().__init__(message)
        else:
            where = f"{source or '<string>'}:{line}" if line is not None else f"{source}"
            super().__init__(f"{where}: {message}")


Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class CuboidStmt:
    """``name = Cuboid(l, h, w, aligned)``: declare a cuboid at the origin."""

    name: str
    dims: Vec3
    aligned: bool
    line: int


@dataclass(frozen=True)
class AttachStmt:
    """``attach(moved, target, x1, y1, z1, x2, y2, z2)``: move ``moved`` so that
    its local point 1 meets the local point 2 of ``target``."""

    moved: str
    target: str
    moved_point: Vec3
    target_point: Vec3
    line: int


@dataclass(frozen=True)
class SqueezeStmt:
    """``squeeze(moved, first, second, face, u, v)``: place ``moved`` between two
    cuboids; expands into two attachments."""

    moved: str
    first: str
    second: str
    face: str
    u: float
    v: float
    line: int


@dataclass(frozen=True)
class ReflectStmt:
    """``reflect(cuboid, axis)``: add a mirrored copy across the block's bbox."""

    cuboid: str
    axis: str
    line: int


@dataclass(frozen=True)
class TranslateStmt:
    """``translate(cuboid, axis, count, distance)``: add ``count`` copies spaced
    evenly over ``distance`` (a fraction of the bbox size along ``axis``)."""

    cuboid: str
    axis: str
    count: int
    distance: float
    line: int


Statement = CuboidStmt | AttachStmt | SqueezeStmt | ReflectStmt | TranslateStmt


@dataclass(frozen=True)
class Block:
    """One ``Assembly NAME { ... }`` block; ``statements[0]`` declares ``bbox``."""

    name: str
    statements: tuple[Statement, ...]
    line: int

    @property
    def bbox(self) -> CuboidStmt:
        """The block's bounding-box declaration (validated to exist)."""
        first = self.statements[0]
        assert isinstance(first, CuboidStmt)
        return first


@dataclass(frozen=True)
class ProgramAST:
    """A parsed hierarchical program: blocks by name, the first one is the root."""

    blocks: dict[str, Block]
    root: str
    source: str


def _split_args(text: str) -> list[str]:
    """Comma-separated argument list; an empty list for ``()``."""
    stripped = text.strip()
    if not stripped:
        return []
    return [a.strip() for a in stripped.split(",")]


@dataclass(frozen=True)
class _LineCtx:
    """Where a statement comes from, for error messages."""

    source: str
    line: int
    #: The ``max_magnitude`` limit, read once per program (``None``: read when needed).
    max_magnitude: float | None = None

    def error(self, message: str) -> ShapeAssemblyError:
        return ShapeAssemblyError(message, self.source, self.line)


def _number(ctx: _LineCtx, token: str, what: str) -> float:
    """Parse a finite decimal literal (no ``nan``/``inf``/underscores)."""
    if not _NUMBER_RE.match(token):
        raise ctx.error(f"{what}: expected a number, got {token!r}")
    value = float(token)
    if not math.isfinite(value):  # a literal too large for a double, 1e400
        raise ctx.error(f"{what}: {token[:40]} is too large")
    bound = ctx.max_magnitude
    if bound is None:  # (a context made without the limit: read it here)
        from parsel_core.config import limit

        bound = limit("max_magnitude")
    if abs(value) > bound:
        raise ctx.error(f"{what}: {token[:40]} is over the limit max_magnitude = {bound:g} "
                        "(raise it with PARSEL_MAX_MAGNITUDE)")
    return value


def _name(ctx: _LineCtx, token: str, what: str) -> str:
    if not _NAME_RE.match(token):
        raise ctx.error(f"{what}: expected a cuboid name, got {token!r}")
    return token


def _expect_count(ctx: _LineCtx, command: str, args: list[str], counts: tuple[int, ...]) -> None:
    if len(args) not in counts:
        want = " or ".join(str(c) for c in counts)
        raise ctx.error(f"{command}() expects {want} arguments, got {len(args)}")


def _parse_cuboid(ctx: _LineCtx, name: str, args: list[str]) -> CuboidStmt:
    _expect_count(ctx, "Cuboid", args, (3, 4))
    dims = tuple(_number(ctx, a, f"Cuboid() dimension {i + 1}") for i, a in enumerate(args[:3]))
    if min(dims) < MIN_DIMENSION:
        raise ctx.error(f"Cuboid() dimensions must be positive (at least {MIN_DIMENSION:g}), got "
                        f"{', '.join(a[:40] for a in args[:3])}")
    aligned = False
    if len(args) == 4:
        if args[3] not in ("True", "False"):
            raise ctx.error(f"Cuboid() aligned flag must be True or False, got {args[3]!r}")
        aligned = args[3] == "True"
    return CuboidStmt(name, (dims[0], dims[1], dims[2]), aligned, ctx.line)


def _parse_attach(ctx: _LineCtx, args: list[str]) -> AttachStmt:
    _expect_count(ctx, "attach", args, (8,))
    moved = _name(ctx, args[0], "attach() argument 1")
    target = _name(ctx, args[1], "attach() argument 2")
    vals = [_number(ctx, a, f"attach() argument {i + 3}") for i, a in enumerate(args[2:])]
    return AttachStmt(moved, target, (vals[0], vals[1], vals[2]), (vals[3], vals[4], vals[5]), ctx.line)


def _parse_squeeze(ctx: _LineCtx, args: list[str]) -> SqueezeStmt:
    _expect_count(ctx, "squeeze", args, (6,))
    names = [_name(ctx, a, f"squeeze() argument {i + 1}") for i, a in enumerate(args[:3])]
    face = args[3]
    if face not in FACES:
        raise ctx.error(f"squeeze() face must be one of {', '.join(FACES)}, got {face!r}")
    u = _number(ctx, args[4], "squeeze() argument 5")
    v = _number(ctx, args[5], "squeeze() argument 6")
    return SqueezeStmt(names[0], names[1], names[2], face, u, v, ctx.line)


def _axis(ctx: _LineCtx, command: str, token: str) -> str:
    if token not in AXES:
        raise ctx.error(f"{command}() axis must be X, Y or Z, got {token!r}")
    return token


def _parse_reflect(ctx: _LineCtx, args: list[str]) -> ReflectStmt:
    _expect_count(ctx, "reflect", args, (2,))
    return ReflectStmt(_name(ctx, args[0], "reflect() argument 1"), _axis(ctx, "reflect", args[1]), ctx.line)


def _parse_translate(ctx: _LineCtx, args: list[str]) -> TranslateStmt:
    _expect_count(ctx, "translate", args, (4,))
    name = _name(ctx, args[0], "translate() argument 1")
    axis = _axis(ctx, "translate", args[1])
    if not _INT_RE.match(args[2]) or int(args[2]) < 1:
        raise ctx.error(f"translate() count must be a positive integer, got {args[2]!r}")
    if int(args[2]) > MAX_TRANSLATE_COUNT:
        raise ctx.error(f"translate() count {args[2]} exceeds the limit of {MAX_TRANSLATE_COUNT}")
    distance = _number(ctx, args[3], "translate() argument 4")
    return TranslateStmt(name, axis, int(args[2]), distance, ctx.line)


_COMMANDS = {
    "attach": _parse_attach,
    "squeeze": _parse_squeeze,
    "reflect": _parse_reflect,
    "translate": _parse_translate,
}


def _parse_statement(ctx: _LineCtx, text: str) -> Statement:
    """One statement line (inside a block) to its dataclass."""
    assign = _ASSIGN_RE.match(text)
    if assign:
        name, rhs = assign.groups()
        call = _CALL_RE.match(rhs.strip())
        if not call or call.group(1) != "Cuboid":
            raise ctx.error(f"expected '{name} = Cuboid(...)', got {text!r}")
        return _parse_cuboid(ctx, name, _split_args(call.group(2)))
    call = _CALL_RE.match(text)
    if not call:
        raise ctx.error(f"cannot parse statement {text!r}")
    command, arg_text = call.groups()
    if command == "Cuboid":
        raise ctx.error("Cuboid() must be assigned to a name")
    parser = _COMMANDS.get(command)
    if parser is None:
        raise ctx.error(f"unknown command {command!r}")
    return parser(ctx, _split_args(arg_text))


def _check_block(source: str, block: Block) -> None:
    """Name-resolution checks within one block, in statement order."""
    if not block.statements:
        raise ShapeAssemblyError(f"block {block.name} is empty (expected bbox = Cuboid(...))", source, block.line)
    first = block.statements[0]
    if not (isinstance(first, CuboidStmt) and first.name == "bbox"):
        raise ShapeAssemblyError(f"block {block.name} must start with bbox = Cuboid(...)", source, first.line)
    declared: set[str] = set()
    for stmt in block.statements:
        ctx = _LineCtx(source, stmt.line)
        if isinstance(stmt, CuboidStmt):
            if stmt.name in declared:
                raise ctx.error(f"cuboid {stmt.name!r} declared twice in block {block.name}")
            declared.add(stmt.name)
            continue
        if isinstance(stmt, AttachStmt):
            used = [stmt.moved, stmt.target]
            moved = stmt.moved
        elif isinstance(stmt, SqueezeStmt):
            used = [stmt.moved, stmt.first, stmt.second]
            moved = stmt.moved
        else:
            used = [stmt.cuboid]
            moved = stmt.cuboid
        for name in used:
            if name not in declared:
                raise ctx.error(f"undefined cuboid {name!r}")
        if moved == "bbox":
            raise ctx.error("the bounding box cannot be moved or copied")


def _check_hierarchy(ast: ProgramAST) -> None:
    """Every ``Program_*`` cuboid needs its block, and the block graph must be a tree-like DAG."""
    children: dict[str, list[tuple[str, int]]] = {}
    for block in ast.blocks.values():
        refs = []
        for stmt in block.statements[1:]:
            if isinstance(stmt, CuboidStmt) and stmt.name.startswith(SUBPROGRAM_PREFIX):
                if stmt.name not in ast.blocks:
                    raise ShapeAssemblyError(f"missing Assembly block for {stmt.name}", ast.source, stmt.line)
                refs.append((stmt.name, stmt.line))
        children[block.name] = refs

    # Iterative depth-first search: grey = on the current path, black = done.
    state: dict[str, str] = {ast.root: "grey"}
    stack: list[tuple[str, int]] = [(ast.root, 0)]
    while stack:
        name, i = stack.pop()
        refs = children[name]
        if i == len(refs):
            state[name] = "black"
            continue
        stack.append((name, i + 1))
        child, line = refs[i]
        if state.get(child) == "grey":
            raise ShapeAssemblyError(f"recursive sub-program {child}", ast.source, line)
        if child not in state:
            state[child] = "grey"
            stack.append((child, 0))


def parse_program(text: str, source: str = "<string>") -> ProgramAST:
    """Parse program text into a :class:`ProgramAST`, raising
    :class:`ShapeAssemblyError` (with ``source:line``) on malformed input."""
    from parsel_core.config import limit

    blocks: dict[str, Block] = {}
    order: list[str] = []
    current: tuple[str, int, list[Statement]] | None = None
    bound = limit("max_magnitude")  # (once: a program has thousands of numbers)
    for lineno, raw in enumerate(text.splitlines(), start=1):
        ctx = _LineCtx(source, lineno, bound)
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith("Assembly"):
            match = _BLOCK_OPEN_RE.match(line)
            if not match:
                raise ctx.error(f"malformed block header {line!r} (expected 'Assembly NAME {{')")
            if current is not None:
                raise ctx.error(f"unbalanced braces: block {current[0]} (line {current[1]}) is not closed")
            name = match.group(1)
            if name in blocks:
                raise ctx.error(f"duplicate Assembly block {name}")
            current = (name, lineno, [])
            continue
        if line == "}":
            if current is None:
                raise ctx.error("unbalanced braces: '}' without an open Assembly block")
            name, start, stmts = current
            blocks[name] = Block(name, tuple(stmts), start)
            order.append(name)
            current = None
            continue
        if current is None:
            raise ctx.error(f"statement outside an Assembly block: {line!r}")
        current[2].append(_parse_statement(ctx, line))
    if current is not None:
        raise ShapeAssemblyError(f"unbalanced braces: block {current[0]} is not closed", source, current[1])
    if not order:
        raise ShapeAssemblyError("missing Program block: no 'Assembly NAME {' found", source, None)
    ast = ProgramAST(blocks, order[0], source)
    for block in blocks.values():
        _check_block(source, block)
    _check_hierarchy(ast)
    return ast
