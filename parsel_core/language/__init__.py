"""The language layer: from an edit request in words to a seed edit, hints and breakable relations.

``infer(shape, request, provider=..., mode=..., samples=...)`` is the entry point (paper
section 6); see docs/language.md for the prompts, the reply API and the providers.
"""

from __future__ import annotations

from parsel_core.language.api import ReplyError, SeedReply, extract_code, parse_seed_code, parse_seed_reply
from parsel_core.language.describe import describe_shape, read_description, read_relation_id, read_request
from parsel_core.language.engine import (
    MODES,
    Inference,
    InferenceError,
    Proposal,
    build_tasks,
    get_provider,
    infer,
    proxydural_requests,
    variation_requests,
)
from parsel_core.language.replies import HINT_TYPES, parse_hints, parse_one_shot, parse_requests, parse_validity

__all__ = [
    "HINT_TYPES", "MODES", "Inference", "InferenceError", "Proposal", "ReplyError", "SeedReply", "build_tasks",
    "describe_shape", "extract_code", "get_provider", "infer", "parse_hints", "parse_one_shot", "parse_requests",
    "parse_seed_code", "parse_seed_reply", "parse_validity", "proxydural_requests", "read_description",
    "read_relation_id", "read_request", "variation_requests",
]
