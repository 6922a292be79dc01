"""Reading the replies of every task into plain values, and the keys votes compare.

Each task's reply ends with a code block in a tiny format (docs/language.md):

* ``seed_edit``: calls of the reply API (:mod:`parsel_core.language.api`);
* ``type_hints``: ``hints = {"leg": "translate", "seat": "keep"}``;
* ``reflection_validity`` / ``group_validity``: ``valid = True`` or ``valid = False``;
* ``proxydural`` / ``variations``: ``requests = ["...", ...]``;
* ``one_shot``: a whole program in the core's text form.

All of them are read from the syntax tree; literals are taken with their types checked,
nothing is evaluated. A reply that does not fit is a :class:`ReplyError` whose message
is the reason recorded for that sample.
"""

from __future__ import annotations

import ast
import json
from collections.abc import Mapping
from typing import Any

from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.language.api import ReplyError, SeedReply, parse_code, parse_seed_code, read_blocks
from parsel_core.ops import EditOp, op_to_dict

#: Hint types the solver understands (paper 6.2.1, plus ``keep`` for parts to hold fixed).
HINT_TYPES = ("translate", "rotate", "scale", "keep")
MAX_REQUESTS = 20


def _single_assignment(code: str, name: str) -> ast.expr:
    """The value of the one statement ``name = <literal>`` the code must consist of."""
    body = parse_code(code)
    statements = [node for node in body if not (isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant)
                                               and isinstance(node.value.value, str))]
    if not statements:
        raise ReplyError(f"no '{name} = ...' in the reply")
    for node in statements:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            raise ReplyError(f"line {node.lineno}: imports are not allowed")
    if len(statements) != 1:
        raise ReplyError(f"the code must be the single statement '{name} = ...', found {len(statements)} statements")
    node = statements[0]
    if not (isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name)
            and node.targets[0].id == name):
        raise ReplyError(f"line {node.lineno}: expected '{name} = ...'")
    return node.value


def _string(node: ast.expr, what: str) -> str:
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    raise ReplyError(f"{what} must be a string literal, got {ast.unparse(node)!r}")


def parse_hints(reply: str, shape: ShapeGraph) -> dict[str, str]:
    """``hints = {part or label: type}`` -> hint type per part id (labels expand to their parts)."""
    return read_blocks(reply, lambda code: hints_code(code, shape))[0]


def hints_code(code: str, shape: ShapeGraph) -> dict[str, str]:
    value = _single_assignment(code, "hints")
    if not isinstance(value, ast.Dict):
        raise ReplyError("hints must be a dict literal like {\"leg\": \"translate\"}")
    by_label: dict[str, list[str]] = {}
    for pid, part in shape.parts.items():
        by_label.setdefault(part.label, []).append(pid)
    hints: dict[str, str] = {}
    for key_node, value_node in zip(value.keys, value.values):
        if key_node is None:
            raise ReplyError("** in hints is not allowed")
        key = _string(key_node, "a hints key")
        kind = _string(value_node, f"the hint for {key!r}").strip().lower()
        if kind not in HINT_TYPES:
            raise ReplyError(f"hint {kind!r} for {key!r} is not one of {', '.join(HINT_TYPES)}")
        if key in shape.parts or key in shape.virtual_parents:
            ids = [key]
        elif key in by_label:
            ids = by_label[key]
        else:
            raise ReplyError(f"hints name unknown part {key!r}")
        for pid in ids:
            if hints.get(pid, kind) != kind:
                raise ReplyError(f"hints give {pid!r} two types ({hints[pid]} and {kind})")
            hints[pid] = kind
    return dict(sorted(hints.items()))


def parse_validity(reply: str) -> bool:
    """``valid = True`` (the relation should hold) or ``valid = False`` (the request breaks it)."""
    return read_blocks(reply, validity_code)[0]


def validity_code(code: str) -> bool:
    value = _single_assignment(code, "valid")
    if isinstance(value, ast.Constant) and isinstance(value.value, bool):
        return value.value
    raise ReplyError(f"valid must be True or False, got {ast.unparse(value)!r}")


def parse_requests(reply: str) -> tuple[str, ...]:
    """``requests = ["make the legs longer", ...]``: edit requests (proxydural, variations)."""
    return read_blocks(reply, requests_code)[0]


def requests_code(code: str) -> tuple[str, ...]:
    value = _single_assignment(code, "requests")
    if not isinstance(value, (ast.List, ast.Tuple)):
        raise ReplyError("requests must be a list of strings")
    items = tuple(" ".join(_string(e, "each request").split()) for e in value.elts)
    if not items:
        raise ReplyError("requests is empty")
    if len(items) > MAX_REQUESTS:
        raise ReplyError(f"too many requests ({len(items)}, limit {MAX_REQUESTS})")
    if any(not item for item in items):
        raise ReplyError("a request is empty")
    return items


def parse_one_shot(reply: str, shape: ShapeGraph, registry: Mapping[str, type[EditOp]] | None = None):
    """A whole program in the core's text form (the paper's one-shot baseline), checked against the shape."""
    return read_blocks(reply, lambda code: one_shot_code(code, shape, registry))[0]


def one_shot_code(code: str, shape: ShapeGraph, registry: Mapping[str, type[EditOp]] | None = None):
    from parsel_core.program import Program

    try:
        program = Program.from_text(code, registry=registry, source="reply")
        program.validate(shape)
    except ParselError as exc:
        raise ReplyError(str(exc)) from None
    if not program.ops:
        raise ReplyError("the program has no ops")
    return program


def parse_seed(reply: str, shape: ShapeGraph, registry: Mapping[str, type[EditOp]] | None = None) -> SeedReply:
    return read_blocks(reply, lambda code: parse_seed_code(code, shape, registry))[0]


# -- what votes compare -------------------------------------------------------------------


def _rounded(value: Any) -> Any:
    if isinstance(value, float):
        return round(value, 6) + 0.0
    if isinstance(value, (list, tuple)):
        return [_rounded(v) for v in value]
    return value


def ops_key(ops) -> str:
    """Ops as canonical JSON (floats to 1e-6), so equal edits from different samples vote together."""
    return json.dumps([{k: _rounded(v) for k, v in op_to_dict(op).items()} for op in ops], sort_keys=True)


def vote_key(task: str, value: Any) -> str:
    """The comparable form of a parsed reply of ``task``."""
    if isinstance(value, SeedReply):
        return json.dumps({"cannot": value.cannot}) if value.cannot is not None else ops_key(value.ops)
    if task == "one_shot":
        return ops_key(value.ops)
    return json.dumps(value, sort_keys=True)


def to_json(value: Any) -> Any:
    """A parsed reply as plain JSON for the record."""
    if isinstance(value, SeedReply):
        if value.cannot is not None:
            return {"cannot_edit": value.cannot}
        return {"ops": [op_to_dict(op) for op in value.ops]}
    if hasattr(value, "to_dict") and hasattr(value, "ops"):
        return value.to_dict()
    if isinstance(value, tuple):
        return list(value)
    return value
