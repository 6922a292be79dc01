"""The DSL's own operators (reference section 3), registered as a plugin."""

from __future__ import annotations

from parsel_core import hookimpl
from parsel_core.ops import BUILTIN_OPS


@hookimpl
def parsel_edit_operators():
    return list(BUILTIN_OPS)
