"""The default prompt templates, registered through ``parsel_prompt_templates``.

The templates are data files in ``parsel_core/language/prompts/`` (inside the package,
so an editable install and a wheel both find them next to this module). Each is
Markdown with six sections (reference section 6): overview, output specification,
examples, shape and request, steps, guidelines. Placeholders are ``{{name}}``;
:func:`render` fills them and refuses a template that leaves one unfilled, so a
plugin's replacement template fails loudly instead of sending a broken prompt.
"""

from __future__ import annotations

import re
from pathlib import Path

from parsel_core import hookimpl
from parsel_core.errors import ParselError

PROMPT_DIR = Path(__file__).with_name("prompts")
#: Every template the language layer uses, with the placeholders each needs.
TEMPLATE_FIELDS: dict[str, tuple[str, ...]] = {
    "seed_edit": ("shape", "picture", "request", "operators"),
    "type_hints": ("shape", "picture", "request"),
    "reflection_validity": ("shape", "picture", "request", "relation"),
    "group_validity": ("shape", "picture", "request", "relation"),
    "one_shot": ("shape", "picture", "request"),
    "proxydural": ("shape", "count"),
    "variations": ("shape", "request", "count"),
}
SECTIONS = ("Overview", "Output specification", "Examples", "Shape and request", "Steps", "Guidelines")
_PLACEHOLDER = re.compile(r"\{\{\s*([A-Za-z_][A-Za-z0-9_]*)\s*\}\}")


def default_templates() -> dict[str, Path]:
    """Template name -> the bundled file."""
    return {name: PROMPT_DIR / f"{name}.md" for name in TEMPLATE_FIELDS}


@hookimpl
def parsel_prompt_templates():
    return default_templates()


def get_template(name: str) -> str:
    """The template text: the registered one (plugins override), else the bundled file."""
    from parsel_core.plugins import prompt_templates

    templates = prompt_templates()
    if name in templates:
        return templates[name]
    path = default_templates().get(name)
    if path is None:
        known = ", ".join(sorted(set(templates) | set(TEMPLATE_FIELDS)))
        raise ParselError(f"unknown prompt template {name!r} (known: {known})")
    return path.read_text(encoding="utf-8")


#: Operators the seed-edit template describes in its own words; every other registered
#: operator (a plugin's) is listed by :func:`describe_operators` from its signature and docstring.
DESCRIBED_OPERATORS = frozenset({"translate", "rotate", "scale_1d", "scale_2d", "scale_3d", "shear",
                                 "change_count", "change_delta", "keep_fixed"})


def operator_signature(cls) -> str:
    """``twist(target, origin=..., axis=..., amount=...)``: how the reply API calls an operator."""
    import dataclasses

    skip = {"operand", "feature", "amount"}
    names = [f.name for f in dataclasses.fields(cls) if f.name not in skip]
    first = "group" if getattr(cls, "acts_on", "part") == "group" else "target"
    return f"{cls.name}({', '.join([first, *(f'{n}=...' for n in names), 'amount=...'])})"


def describe_operators(registry) -> str:
    """One bullet per registered operator the template does not already describe (plugin
    operators), with its signature, its fields' kinds and its docstring's first paragraph."""
    lines = []
    for name in sorted(registry):
        if name in DESCRIBED_OPERATORS:
            continue
        cls = registry[name]
        doc = " ".join((cls.__doc__ or "").strip().split("\n\n")[0].split())
        kinds = [f"`{f}` is a direction" for f in getattr(cls, "unit_fields", ())]
        kinds += [f"`{f}` is a point" for f in getattr(cls, "point_fields", ())]
        detail = f" ({'; '.join(kinds)})" if kinds else ""
        lines.append(f"  - `{operator_signature(cls)}` (from a plugin): {doc or 'no description'}{detail}\n")
    return "".join(lines)


def render(name: str, **fields: object) -> str:
    """Fill a template's ``{{placeholders}}``; every placeholder must be given."""
    text = get_template(name)
    missing = sorted({m for m in _PLACEHOLDER.findall(text) if m not in fields})
    if missing:
        raise ParselError(f"prompt template {name!r} needs {', '.join(missing)}, which the language layer "
                          "does not provide")
    return _PLACEHOLDER.sub(lambda m: str(fields[m.group(1)]), text)
