"""parsel relation detectors: symmetries, attachments and ground contact (reference section 2).

Registers one ``RelationDetector`` per family (``reflection``, ``translation``,
``rotation``, ``attachment``, ``ground``) through ``parsel_relation_detectors``, and
offers :func:`detect_relations` (all families, conflicts resolved) and, in
:mod:`parsel_relations.labels`, directional labels and text descriptions of shapes for
prompts. See docs/relations.md.
"""

from __future__ import annotations

from parsel_core import hookimpl
from parsel_relations.detect import (
    DEFAULT_RELATIVE_TOLERANCE,
    FAMILIES,
    AttachmentDetector,
    FamilyDetector,
    GroundDetector,
    ReflectionDetector,
    RotationDetector,
    TranslationDetector,
    absolute_tolerance,
    detect_all,
    detect_family,
    detect_relations,
    detectors,
)
from parsel_relations.labels import describe_shape, directional_labels

__version__ = "0.1.0"

__all__ = [
    "DEFAULT_RELATIVE_TOLERANCE", "FAMILIES", "AttachmentDetector", "FamilyDetector", "GroundDetector",
    "ReflectionDetector", "RotationDetector", "TranslationDetector", "absolute_tolerance", "describe_shape",
    "detect_all", "detect_family", "detect_relations", "detectors", "directional_labels",
]


@hookimpl
def parsel_relation_detectors():
    """One detector per relation family."""
    return detectors()
