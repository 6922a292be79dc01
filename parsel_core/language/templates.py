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
    "seed_edit": ("shape", "request"),
    "type_hints": ("shape", "request"),
    "reflection_validity": ("shape", "request", "relation"),
    "group_validity": ("shape", "request", "relation"),
    "one_shot": ("shape", "request"),
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


def render(name: str, **fields: object) -> str:
    """Fill a template's ``{{placeholders}}``; every placeholder must be given."""
    text = get_template(name)
    missing = sorted({m for m in _PLACEHOLDER.findall(text) if m not in fields})
    if missing:
        raise ParselError(f"prompt template {name!r} needs {', '.join(missing)}, which the language layer "
                          "does not provide")
    return _PLACEHOLDER.sub(lambda m: str(fields[m.group(1)]), text)
