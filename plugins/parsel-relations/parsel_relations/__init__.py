"""parsel relation detectors: symmetries, attachments and ground contact (reference section 2).

Registers one ``RelationDetector`` per family (``reflection``, ``translation``,
``rotation``, ``attachment``, ``ground``) through ``parsel_relation_detectors``, and
offers :func:`detect_relations` (all families, conflicts resolved). Directional labels
and the description of a shape for prompts live in the core (:mod:`parsel_core.labels`,
:mod:`parsel_core.language.describe`). See docs/relations.md.
"""

from __future__ import annotations

import importlib
from typing import Any

from parsel_core import hookimpl

__version__ = "0.1.0"

__all__ = [
    "DEFAULT_RELATIVE_TOLERANCE", "FAMILIES", "AttachmentDetector", "FamilyDetector", "GroundDetector",
    "ReflectionDetector", "RotationDetector", "TranslationDetector", "absolute_tolerance",
    "detect_all", "detect_family", "detect_relations", "detectors",
]


def __getattr__(name: str) -> Any:
    """The names above come from :mod:`parsel_relations.detect`, imported on first use so
    that registering the plugin costs nothing."""
    if name not in __all__:
        raise AttributeError(f"module 'parsel_relations' has no attribute {name!r}")
    return getattr(importlib.import_module("parsel_relations.detect"), name)


@hookimpl
def parsel_relation_detectors():
    """One detector per relation family."""
    from parsel_relations.detect import detectors

    return detectors()
