"""The readable text form of programs: one op per line, parsed back with :mod:`ast`.

Example::

    # parsel program
    param x in [0, 0.5] default 0.25
    scale_1d(seat, origin=(0, 0.45, 0), dir=(1, 0, 0), amount=x)
    translate(face(seat, "v+"), dir=(0, 1, 0), amount=0.5 * x)
    change_count("translation_0", amount=2 * x, mode="top_down")

A line ``layer`` starts a new layer of a layered program (``Program.plus``): the ops
below it edit the rest shape too, and their displacements add to those above.

An operand is a part id (a bare name when it is an identifier, a string otherwise), or
``face(part, "u+")`` / ``edge(part, "u+v-")`` / ``corner(part, "u+v+w-")`` for a
feature. Keyword values are tuples of numbers, strings, or (for ``amount``) an
expression. Lines are parsed into trees and checked against the registered ops;
nothing is executed.
"""

from __future__ import annotations

import ast
import math
import re
from collections.abc import Mapping
from typing import Any

from parsel_core.errors import ProgramFormatError
from parsel_core.expressions import parse_expression
from parsel_core.ops import EditOp, op_from_dict, op_to_dict

_PARAM = re.compile(
    r"^param\s+(?P<name>[A-Za-z][A-Za-z0-9_]*)\s+in\s+\[\s*(?P<lo>[^,\]]+)\s*,\s*(?P<hi>[^\]]+)\]"
    r"(?:\s+default\s+(?P<default>\S+))?\s*$")
_IDENTIFIER = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_FEATURE_CALLS = ("face", "edge", "corner")


def _format_value(value: Any) -> str:
    if isinstance(value, tuple):
        return "(" + ", ".join(repr(float(v)) for v in value) + ")"
    return repr(value)


def op_to_text(op: EditOp) -> str:
    """One line: ``name(operand, key=value, ..., amount=expr)``."""
    data = op_to_dict(op)
    operand = op.operand if _IDENTIFIER.match(op.operand) and op.operand not in _FEATURE_CALLS else repr(op.operand)
    if op.feature is not None:
        operand = f"{('face', 'edge', 'corner')[len(op.feature) // 2 - 1]}({operand}, {op.feature!r})"
    args = [operand]
    for key, value in op.params().items():
        args.append(f"{key}={_format_value(value)}")
    args.append(f"amount={data['amount']}")
    return f"{op.name}({', '.join(args)})"


def program_to_text(program) -> str:
    """The text form: ``param`` lines, then the ops a line each; ``layer`` starts a summed
    layer and ``layer on top`` an outer one, whose following ops end with ``follows=(part, point)``."""
    lines = ["# parsel program"]
    for p in program.parameters:
        lines.append(f"param {p.name} in [{p.lo!r}, {p.hi!r}] default {p.default!r}")
    follow_of = program.follow_of()
    for i, part in enumerate(program.layer_slices):
        if i or i in program.outer:
            lines.append("layer on top" if i in program.outer else "layer")
        for k in range(part.start, part.stop):
            line = op_to_text(program.ops[k])
            if k in follow_of:
                f = follow_of[k]
                line = f"{line[:-1]}, follows=({f.part!r}, {_format_value(f.point)}))"
            lines.append(line)
    return "\n".join(lines) + "\n"


def _take_follows(line: str, where: str) -> tuple[str, tuple[str, Any] | None]:
    """An op line without its ``follows=(part, point)`` argument, and that argument."""
    if "follows" not in line:
        return line, None
    try:
        tree = ast.parse(line.strip(), mode="eval").body
    except SyntaxError:
        return line, None  # op_from_text says what does not parse
    if not isinstance(tree, ast.Call):
        return line, None
    keep = [k for k in tree.keywords if k.arg != "follows"]
    given = [k for k in tree.keywords if k.arg == "follows"]
    if not given:
        return line, None
    if len(given) > 1:
        raise ProgramFormatError(f"{where}: argument 'follows' given twice")
    value = _literal(given[0].value, f"{where}: follows")
    if not (isinstance(value, tuple) and len(value) == 2 and isinstance(value[0], str)):
        raise ProgramFormatError(f"{where}: follows must be (part, (x, y, z))")
    tree.keywords = keep
    return ast.unparse(tree), value


def _literal(node: ast.AST, where: str) -> Any:
    """Numbers, strings and tuples/lists of numbers (with unary minus)."""
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float, str)) and not isinstance(
            node.value, bool):
        return node.value
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        value = _literal(node.operand, where)
        if isinstance(value, (int, float)):
            return -value if isinstance(node.op, ast.USub) else value
    if isinstance(node, (ast.Tuple, ast.List)):
        return tuple(_literal(elt, where) for elt in node.elts)
    raise ProgramFormatError(f"{where}: expected a number, string or tuple, got {ast.unparse(node)!r}")


def _operand(node: ast.AST, where: str) -> tuple[str, str | None]:
    if isinstance(node, ast.Name):
        return node.id, None
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value, None
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in _FEATURE_CALLS:
        if len(node.args) != 2 or node.keywords:
            raise ProgramFormatError(f"{where}: {node.func.id}() takes a part and a feature name")
        part, _ = _operand(node.args[0], where)
        feature = node.args[1]
        if not (isinstance(feature, ast.Constant) and isinstance(feature.value, str)):
            raise ProgramFormatError(f"{where}: feature name must be a string like 'u+'")
        expected = {"face": 2, "edge": 4, "corner": 6}[node.func.id]
        if len(feature.value) != expected:
            raise ProgramFormatError(f"{where}: {feature.value!r} is not a {node.func.id} name")
        return part, feature.value
    raise ProgramFormatError(f"{where}: operand must be a part name, a string or face/edge/corner(...), "
                             f"got {ast.unparse(node)!r}")


def op_from_text(line: str, registry: Mapping[str, type[EditOp]], where: str = "<op>") -> EditOp:
    """Parse one op line against the registered ops."""
    try:
        tree = ast.parse(line.strip(), mode="eval").body
    except SyntaxError as exc:
        hint = " (quote part names that are not identifiers, e.g. 'leg.000')" if re.search(
            r"[A-Za-z_]\w*\.\d", line) else ""
        raise ProgramFormatError(f"{where}: does not parse: {exc.msg}{hint}") from None
    if not isinstance(tree, ast.Call) or not isinstance(tree.func, ast.Name):
        raise ProgramFormatError(f"{where}: expected an op call like scale_1d(part, ...)")
    name = tree.func.id
    if name not in registry:
        raise ProgramFormatError(f"{where}: unknown op {name!r} (known: {', '.join(sorted(registry))})")
    if len(tree.args) != 1:
        raise ProgramFormatError(f"{where}: {name}() takes exactly one operand, then keyword arguments")
    operand, feature = _operand(tree.args[0], where)
    data: dict[str, Any] = {"op": name, "operand": operand}
    if feature is not None:
        data["feature"] = feature
    for keyword in tree.keywords:
        if keyword.arg is None:
            raise ProgramFormatError(f"{where}: ** arguments are not allowed")
        if keyword.arg in data:
            raise ProgramFormatError(f"{where}: argument {keyword.arg!r} given twice")
        if keyword.arg == "amount":
            node = keyword.value
            text = node.value if isinstance(node, ast.Constant) and isinstance(node.value, str) else ast.unparse(node)
            try:
                parse_expression(text)
            except ProgramFormatError as exc:
                raise ProgramFormatError(f"{where}: {exc}") from None
            data["amount"] = text
        else:
            data[keyword.arg] = _literal(keyword.value, f"{where}: {keyword.arg}")
    return op_from_dict(data, registry, where)


def program_from_text(text: str, registry: Mapping[str, type[EditOp]] | None = None, source: str = "<program>"):
    """Parse the text form; errors name the source and line number."""
    from parsel_core.program import Follow, Parameter, Program

    if registry is None:
        from parsel_core.plugins import edit_operators

        registry = edit_operators()
    from parsel_core.config import check_limit

    lines = text.splitlines()
    check_limit("max_program_lines", f"{source}: lines", len(lines))
    params, ops, layers, outer, follows = [], [], [], [], {}
    for number, raw in enumerate(lines, start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        where = f"{source}:{number}"
        words = line.split("#", 1)[0].split()
        if words == ["layer", "on", "top"] and not ops and not outer:  # the first layer is an outer one
            outer.append(0)
            continue
        if words in (["layer"], ["layer", "on", "top"]):
            if len(ops) == sum(layers):
                raise ProgramFormatError(f"{where}: 'layer' must follow at least one op (a layer has ops)")
            layers.append(len(ops) - sum(layers))
            if words == ["layer", "on", "top"]:
                outer.append(len(layers))
            continue
        if line.split()[0] == "param":
            line = line.split("#", 1)[0].strip()  # op lines keep theirs: ast skips comments
            match = _PARAM.match(line)
            if not match:
                raise ProgramFormatError(f"{where}: expected 'param NAME in [LO, HI] default VALUE'")
            try:
                lo, hi = float(match["lo"]), float(match["hi"])
                default = float(match["default"]) if match["default"] is not None else None
            except ValueError:
                raise ProgramFormatError(f"{where}: range and default must be numbers") from None
            if not all(math.isfinite(v) for v in (lo, hi) + ((default,) if default is not None else ())):
                raise ProgramFormatError(f"{where}: range and default must be finite")
            try:
                params.append(Parameter(match["name"], lo, hi, default))
            except ProgramFormatError as exc:
                raise ProgramFormatError(f"{where}: {exc}") from None
            continue
        try:
            line, follow = _take_follows(line, where)
            if follow is not None:
                follows.setdefault((follow[0], tuple(follow[1]) if isinstance(follow[1], tuple) else follow[1]),
                                   []).append(len(ops))
            ops.append((where, op_from_text(line, registry, where)))
        except (RecursionError, MemoryError) as exc:  # the parser's own stack
            raise ProgramFormatError(f"{where}: does not parse: nested too deeply ({type(exc).__name__})") from None
        except (ValueError, OverflowError) as exc:  # digits beyond int(), numbers beyond float
            raise ProgramFormatError(f"{where}: does not parse: {' '.join(str(exc).split())[:120]}") from None
    if not params:
        params = [Parameter("x")]
    declared = {p.name for p in params}
    for where, op in ops:
        unknown = sorted(op.parameters - declared)
        if unknown:
            raise ProgramFormatError(f"{where}: amount {op.amount!r} uses undeclared parameter(s) "
                                     f"{', '.join(unknown)} (declare with 'param NAME in [LO, HI]')")
    ops = [op for _, op in ops]
    if layers or outer:
        if len(ops) == sum(layers):
            raise ProgramFormatError(f"{source}: the last 'layer' line has no ops after it")
        layers.append(len(ops) - sum(layers))
    try:
        program = Program(tuple(ops), tuple(params), {}, tuple(layers), tuple(outer),
                          tuple(Follow(part, point, tuple(indices)) for (part, point), indices in follows.items()))
    except ProgramFormatError as exc:
        raise ProgramFormatError(f"{source}: {exc}") from None
    program.check_numbers(source)
    return program


def seed_from_text(text: str, source: str = "--seed"):
    """A seed edit as users type it: ops separated by ``;`` or newlines, ``param`` lines allowed.

    Read like any program text (a seed without ``param`` lines gets ``x`` in [0, 1]);
    ``parsel edit --seed`` and batch cases both take seeds this way.
    """
    lines = [line.strip() for chunk in text.split("\n") for line in chunk.split(";") if line.strip()]
    if not lines:
        raise ProgramFormatError(f"{source}: the seed is empty")
    return program_from_text("\n".join(lines), source=source)


def short_number(value: float, digits: int = 12, tolerance: float = 1e-7) -> str:
    """The shortest decimal (at most ``digits`` significant digits) within ``tolerance``
    (relative, absolute below 1; 1e-7 is float32 rounding, the precision of mesh files) of
    ``value``: float noise such as 0.4299999922513962 (a float32 0.43) or 0.999999999999
    reads 0.43 and 1."""
    bound = tolerance * max(1.0, abs(value))
    for precision in range(1, digits + 1):
        text = format(value, f".{precision}g")
        if abs(float(text) - value) <= bound:
            return text
    return format(value, f".{digits}g")


def display_text(text: str, digits: int = 12) -> str:
    """Program text with every number shortened by :func:`short_number`, for people to read
    (pages, summaries); files keep the full-precision form. Quoted names are left alone."""
    import io
    import tokenize

    out_lines = []
    for line in text.splitlines(keepends=True):
        try:
            tokens = list(tokenize.generate_tokens(io.StringIO(line).readline))
        except (tokenize.TokenError, IndentationError, SyntaxError):
            out_lines.append(line)
            continue
        pieces, column = [], 0
        for token in tokens:
            if token.type == tokenize.NUMBER and token.start[0] == 1:
                start, end = token.start[1], token.end[1]
                pieces.append(line[column:start])
                try:
                    pieces.append(short_number(float(token.string), digits))
                except ValueError:
                    pieces.append(token.string)
                column = end
        pieces.append(line[column:])
        out_lines.append("".join(pieces))
    return "".join(out_lines)
