"""parsel: parameterized shape editing with language.

The core defines the data model (hexahedra, parts, relations, shape graphs), the
editing DSL, programs and the plugin hooks; CAS backends, loaders, detectors, LLM
providers and deformers come from plugins. ``edit``, ``check``, ``apply``, ``export``,
``proxydural`` and ``variations`` (:mod:`parsel_core.api`) run whole jobs from Python.

Importing the package costs only pluggy: the public names below load their modules
(and numpy) on first use, so ``parsel --help`` and plugin registration stay cheap.
"""

from __future__ import annotations

import importlib
from typing import Any

import pluggy

__version__ = "0.1.0"

hookimpl = pluggy.HookimplMarker("parsel")

#: Public name -> the module that defines it (imported on first access).
_LAZY = {
    "ParselError": "parsel_core.errors",
    "ShapeGraph": "parsel_core.graph",
    "Hexahedron": "parsel_core.hexahedron",
    **{name: "parsel_core.ops" for name in (
        "ChangeCount", "ChangeDelta", "EditOp", "KeepFixed", "Rotate", "Scale1D", "Scale2D", "Scale3D", "Shear",
        "Translate")},
    "Part": "parsel_core.part",
    **{name: "parsel_core.program" for name in (
        "CompiledProgram", "Evaluation", "Parameter", "Program", "compile_program", "evaluate")},
    **{name: "parsel_core.relations" for name in (
        "Attachment", "GroundContact", "ReflectionSymmetry", "Relation", "RotationSymmetry", "TranslationSymmetry")},
    **{name: "parsel_core.api" for name in (
        "EditResult", "apply", "check", "edit", "export", "proxydural", "variations")},
}

__all__ = [
    "Attachment", "ChangeCount", "ChangeDelta", "CompiledProgram", "EditOp", "EditResult", "Evaluation",
    "GroundContact",
    "Hexahedron", "KeepFixed", "Parameter", "ParselError", "Part", "Program", "ReflectionSymmetry", "Relation",
    "Rotate", "RotationSymmetry", "Scale1D", "Scale2D", "Scale3D", "ShapeGraph", "Shear", "Translate",
    "TranslationSymmetry", "apply", "check", "compile_program", "edit", "evaluate", "export", "hookimpl",
    "proxydural", "variations",
]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'parsel_core' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})

