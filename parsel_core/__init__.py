"""parsel: parameterized shape editing with language.

The core defines the data model (hexahedra, parts, relations, shape graphs), the
editing DSL, programs and the plugin hooks; CAS backends, loaders, detectors, LLM
providers and deformers come from plugins.
"""

from __future__ import annotations

import pluggy

__version__ = "0.1.0"

hookimpl = pluggy.HookimplMarker("parsel")

from parsel_core.errors import ParselError  # noqa: E402
from parsel_core.graph import ShapeGraph  # noqa: E402
from parsel_core.hexahedron import Hexahedron  # noqa: E402
from parsel_core.ops import (  # noqa: E402
    ChangeCount,
    ChangeDelta,
    EditOp,
    KeepFixed,
    Rotate,
    Scale1D,
    Scale2D,
    Scale3D,
    Shear,
    Translate,
)
from parsel_core.part import Part  # noqa: E402
from parsel_core.program import CompiledProgram, Evaluation, Parameter, Program, compile_program, evaluate  # noqa: E402
from parsel_core.relations import (  # noqa: E402
    Attachment,
    GroundContact,
    ReflectionSymmetry,
    Relation,
    RotationSymmetry,
    TranslationSymmetry,
)

__all__ = [
    "Attachment", "ChangeCount", "ChangeDelta", "CompiledProgram", "EditOp", "Evaluation", "GroundContact",
    "Hexahedron", "KeepFixed", "Parameter", "ParselError", "Part", "Program", "ReflectionSymmetry", "Relation",
    "Rotate", "RotationSymmetry", "Scale1D", "Scale2D", "Scale3D", "ShapeGraph", "Shear", "Translate",
    "TranslationSymmetry", "compile_program", "evaluate", "hookimpl",
]
