"""Replies in the formats a model would write: reasoning, then one code block.

The offline provider's answers go through the same parser and votes as a hosted
model's, so these functions write exactly the reply formats of docs/language.md.
"""

from __future__ import annotations

import json
import re

import numpy as np

from parsel_core.language.describe import ShapeSummary
from parsel_offline.interpreter import AXIS_WORDS, Interpretation, Origin, SeedOp

_API_NAMES = {"part", "group", "cannot_edit", "x", "pi", "e"}
_DIRECTIONS = {"x": (1, 0, 0), "-x": (-1, 0, 0), "y": (0, 1, 0), "-y": (0, -1, 0), "z": (0, 0, 1), "-z": (0, 0, -1)}
_FACE_AXIS = {"right": (0, 1), "left": (0, -1), "top": (1, 1), "bottom": (1, -1), "front": (2, 1), "back": (2, -1)}


def _block(code: str) -> str:
    return f"```python\n{code.rstrip()}\n```\n"


def _variable(pid: str, taken: dict[str, str]) -> str:
    if pid in taken:
        return taken[pid]
    name = re.sub(r"\W", "_", pid).strip("_").lower() or "p"
    if name[0].isdigit() or name in _API_NAMES or name.startswith("change_") or name in (
            "translate", "rotate", "scale_1d", "scale_2d", "scale_3d", "shear", "keep_fixed"):
        name = f"p_{name}"
    base, n = name, 2
    while name in taken.values():
        name, n = f"{base}_{n}", n + 1
    taken[pid] = name
    return name


def _words(words: tuple[str, ...]) -> str:
    return ", ".join(json.dumps(w) for w in words)


def api_code(ops: list[SeedOp]) -> str:
    """The seed ops as reply-API code."""
    taken: dict[str, str] = {}
    lines: list[str] = []
    for op in ops:
        if op.group:
            lines.append(f"{op.op}(group({json.dumps(op.target)}), amount={op.amount}, mode={json.dumps(op.mode)})")
            continue
        if op.target not in taken:
            lines.append(f"{_variable(op.target, taken)} = part({json.dumps(op.target)})")
        var = taken[op.target]
        target = f"{var}.{'face' if len(op.feature) == 1 else 'edge'}({_words(op.feature)})" if op.feature else var
        args = [target]
        if op.origin is not None:
            args.append(f"origin={_origin_code(op.origin, var)}")
        args.extend(f"{key}={json.dumps(value)}" for key, value in op.dirs)
        args.append(f"amount={op.amount}")
        if op.mode:
            args.append(f"mode={json.dumps(op.mode)}")
        lines.append(f"{op.op}({', '.join(args)})")
    return "\n".join(lines)


def _origin_code(origin: Origin, var: str) -> str:
    if origin.kind == "center":
        return f"{var}.center()"
    if origin.kind in ("face", "edge"):
        return f"{var}.{origin.kind}({_words(origin.words)})"
    return "(" + ", ".join(repr(float(v)) for v in origin.point) + ")"


def seed_reply(interpretation: Interpretation) -> str:
    reasoning = " ".join(interpretation.reasons) or "The request names one edit."
    return f"{reasoning}\n\n{_block(api_code(interpretation.ops))}"


def hints_reply(interpretation: Interpretation) -> str:
    if interpretation.hint_keys:
        reasoning = "; ".join(interpretation.hint_reasons) + "."
    else:
        reasoning = "The request says nothing about how the other parts should follow."
    body = ", ".join(f"{json.dumps(k)}: {json.dumps(v)}" for k, v in interpretation.hint_keys.items())
    return f"{reasoning}\n\n{_block('hints = {' + body + '}')}"


def validity_reply(interpretation: Interpretation, relation_id: str | None) -> str:
    if relation_id in interpretation.break_reasons:
        reasoning = f"For {relation_id}: {interpretation.break_reasons[relation_id]}, so it breaks."
        return f"{reasoning}\n\n{_block('valid = False')}"
    reasoning = (f"The request edits the parts of {relation_id} alike or leaves them both alone, so the relation "
                 "should still hold.")
    return f"{reasoning}\n\n{_block('valid = True')}"


def cannot_reply(task: str, reason: str) -> str:
    """What to answer when the request is not understood: say so, in each task's format."""
    text = f"I do not understand this request: {reason}."
    if task in ("seed_edit", "one_shot"):
        return f"{text}\n\n{_block(f'cannot_edit({json.dumps(reason)})')}"
    if task == "type_hints":
        return f"{text}\n\n{_block('hints = {}')}"
    if task in ("reflection_validity", "group_validity"):
        return f"{text} Keeping the relation.\n\n{_block('valid = True')}"
    return text


# -- the one-shot baseline: the seed ops written out with numbers -----------------------------


def _face_point(shape: ShapeSummary, pid: str, words: tuple[str, ...]) -> np.ndarray:
    part = shape.parts[pid]
    point = np.asarray(part.centre, dtype=float).copy()
    for word in words:
        axis, sign = _FACE_AXIS[word]
        point[axis] += sign * part.size[axis] / 2
    return point


def _feature_name(words: tuple[str, ...]) -> str:
    names = sorted((_FACE_AXIS[w][0], ("u", "v", "w")[_FACE_AXIS[w][0]] + ("+" if _FACE_AXIS[w][1] > 0 else "-"))
                    for w in words)
    return "".join(n for _, n in names)


def _vector(values) -> str:
    return "(" + ", ".join(repr(round(float(v), 6) + 0.0) for v in values) + ")"


def program_text(interpretation: Interpretation, shape: ShapeSummary) -> str:
    """The seed ops in the core's program text form (boxes read as axis-aligned)."""
    lines = ["param x in [0, 1]"]
    for op in interpretation.ops:
        operand = repr(op.target)
        if op.group:
            lines.append(f"{op.op}({operand}, amount={op.amount}, mode={op.mode!r})")
            continue
        if op.feature:
            kind = "face" if len(op.feature) == 1 else "edge"
            operand = f"{kind}({operand}, {_feature_name(op.feature)!r})"
        args = [operand]
        if op.origin is not None:
            if op.origin.kind == "point":
                point = np.asarray(op.origin.point)
            elif op.origin.kind == "center" or op.origin.part not in shape.parts:
                pid = op.origin.part or op.target
                point = np.asarray(shape.parts[pid].centre) if pid in shape.parts else shape.centre
            else:
                point = _face_point(shape, op.origin.part, op.origin.words)
            args.append(f"origin={_vector(point)}")
        args.extend(f"{key}={_vector(_DIRECTIONS[value])}" for key, value in op.dirs)
        args.append(f"amount={op.amount}")
        lines.append(f"{op.op}({', '.join(args)})")
    return "\n".join(lines)


def one_shot_reply(interpretation: Interpretation, shape: ShapeSummary) -> str:
    reasoning = " ".join(interpretation.reasons) + (" I write the primary edit; I cannot work out the secondary "
                                                    "edits by rule.")
    return f"{reasoning}\n\n```\n{program_text(interpretation, shape)}\n```\n"


# -- the applications ----------------------------------------------------------------------------


def _plural(label: str) -> str:
    words = label.replace("_", " ").replace(".", " ").split()
    last = words[-1]
    if last.endswith("f"):
        last = last[:-1] + "ves"
    elif last.endswith(("s", "x", "ch", "sh")):
        last += "es"
    elif last.endswith("y") and len(last) > 1 and last[-2] not in "aeiou":
        last = last[:-1] + "ies"
    else:
        last += "s"
    return " ".join(words[:-1] + [last])


def _object_word(shape: ShapeSummary, interpreter) -> str:
    return interpreter.category[0] if interpreter.category else "object"


def proxydural_requests(shape: ShapeSummary, count: int) -> list[str]:
    """Independent ways this shape may vary, each phrased so the interpreter reads it."""
    from parsel_offline.interpreter import Interpreter

    interpreter = Interpreter(shape)
    name = _object_word(shape, interpreter)
    requests = [f"make the {name} wider", f"make the {name} taller", f"make the {name} deeper"]
    supports = interpreter.supports()
    if supports:
        label = shape.parts[supports[0]].label
        requests += [f"make the {_plural(label)} thicker", f"taper the {_plural(label)}"]
    for group in shape.groups():
        requests.append(f"add more {_plural(shape.parts[group.members[0]].label)}")
    if "door" in interpreter.labels:
        requests.append("open the doors")
    return requests[:max(1, count)]


def variation_requests(shape: ShapeSummary, request: str, count: int) -> list[str]:
    """The request with different secondary effects spelled out."""
    from parsel_offline.interpreter import Interpreter

    interpreter = Interpreter(shape)
    variants = []
    supports = interpreter.supports()
    if supports:
        variants.append(f"{request} and splay the {_plural(shape.parts[supports[0]].label)}")
    main = interpreter.main_part()
    neighbours = sorted({m for r in shape.relations_of(main) if r.kind == "attachment" for m in r.members} - {main}
                        - set(supports))
    labels = list(dict.fromkeys(shape.parts[p].label for p in neighbours))
    counts = shape.labels()
    for label in labels:
        noun = _plural(label) if len(counts[label]) > 1 else label.replace("_", " ")
        variants.append(f"{request} but keep the {noun} fixed")
    for group in shape.groups():
        variants.append(f"{request} and add more {_plural(shape.parts[group.members[0]].label)}")
    return variants[:max(1, count)] or [request]


def requests_reply(requests: list[str], what: str) -> str:
    body = ",\n            ".join(json.dumps(r) for r in requests)
    return f"{what}\n\n{_block('requests = [' + body + ']')}"


__all__ = ["AXIS_WORDS", "api_code", "cannot_reply", "hints_reply", "one_shot_reply", "program_text",
           "proxydural_requests", "requests_reply", "seed_reply", "validity_reply", "variation_requests"]
