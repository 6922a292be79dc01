"""Evaluation and batch cases: one JSON object per line of a ``.jsonl`` file.

The schema is documented in docs/evaluation.md. A case names a shape, says how its
program is inferred (expert inputs, recorded language-model outputs, or a live language
model) and may carry a ground-truth program to score the result against.

Structural problems of the file (bad JSON, wrong field types, duplicate ids) are
reported at once, naming ``file:line``, before anything runs: a batch of thousands
should not fail on line 900 after an hour. Problems that need the shape (an unknown
part, a missing shape file, a ground truth that does not parse) belong to the case and
are recorded as its failure when it runs.
"""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from parsel_core.errors import ParselError

#: Kinds of case. Only ``edit`` runs in this version; the others are reserved for the
#: proxydural-modelling and variation-family applications (reference section 8).
KINDS = ("edit",)
RESERVED_KINDS = ("proxydural", "variations")
MODES = ("expert", "language")
HINT_TYPES = ("translate", "rotate", "scale", "keep")
_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,127}$")
#: Names in a batch OUTDIR that a case id must not take.
RESERVED_IDS = ("results.jsonl",)
FIELDS = ("id", "kind", "shape", "request", "seed", "hints", "breaks", "llm", "ground_truth", "mode", "solver",
          "options", "language", "target")
LLM_FIELDS = ("seed", "hints", "breaks", "program")
LANGUAGE_FIELDS = ("provider", "model", "mode", "samples", "options")


class CaseFormatError(ParselError):
    """A cases file that cannot be read: the message names the file and line."""


@dataclass(frozen=True)
class LanguageSettings:
    """How to call the language layer for a case without recorded outputs."""

    provider: str = "offline"
    model: str | None = None
    mode: str = "full"
    samples: int = 5
    options: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Inputs:
    """A seed edit (op text), type hints and breakable relations: what an expert enters,
    or what a language model inferred. ``program`` (optional) is a whole program a
    one-shot model wrote: inline program JSON or a path."""

    seed: str | None = None
    hints: Mapping[str, str] = field(default_factory=dict)
    breaks: tuple[str, ...] = ()
    program: Mapping[str, Any] | str | None = None


@dataclass(frozen=True)
class Case:
    """One line of a cases file, validated, with paths resolved against the file's folder.

    ``expert`` holds the expert inputs (the case's ``seed``/``hints``/``breaks``):
    what expert mode solves from, and the reference the language-model metrics compare
    with. ``recorded`` holds a language model's recorded outputs (``llm``).
    """

    id: str
    shape: str
    kind: str = "edit"
    request: str | None = None
    expert: Inputs | None = None
    recorded: Inputs | None = None
    ground_truth: Mapping[str, Any] | str | None = None
    mode: str = "expert"
    solver: str = "aep"
    options: Mapping[str, Any] = field(default_factory=dict)
    language: LanguageSettings = field(default_factory=LanguageSettings)
    line: int = 0
    #: A target (mesh, point cloud or shape) the case's program is fitted to (parsel-fit).
    target: str | None = None


def _where(source: str, line: int) -> str:
    return f"{source}:{line}"


def _resolve(value: str, base: Path) -> str:
    """A path relative to the cases file when it exists there; otherwise as written (an
    example name, or a path relative to the working directory)."""
    candidate = base / value
    if not Path(value).is_absolute() and candidate.exists():
        return str(candidate.resolve())
    return value


def _seed_text(value: Any, where: str) -> str | None:
    if value is None:
        return None
    if isinstance(value, str) and value.strip():
        return value
    if isinstance(value, list) and value and all(isinstance(v, str) and v.strip() for v in value):
        return "\n".join(value)
    raise CaseFormatError(f"{where}: 'seed' must be op text or a list of op texts")


def _hints(value: Any, where: str) -> dict[str, str]:
    if value is None:
        return {}
    if not isinstance(value, Mapping) or not all(isinstance(k, str) and isinstance(v, str) for k, v in value.items()):
        raise CaseFormatError(f"{where}: 'hints' must be an object mapping part ids to "
                              f"{'|'.join(HINT_TYPES)}")
    for part, kind in value.items():
        if kind not in HINT_TYPES:
            raise CaseFormatError(f"{where}: hint {part}={kind}: unknown type (known: {', '.join(HINT_TYPES)})")
    return dict(sorted(value.items()))


def _breaks(value: Any, where: str) -> tuple[str, ...]:
    if value is None:
        return ()
    if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
        raise CaseFormatError(f"{where}: 'breaks' must be a list of relation ids")
    return tuple(sorted(set(value)))


def _program_ref(value: Any, name: str, where: str, base: Path) -> Mapping[str, Any] | str | None:
    if value is None:
        return None
    if isinstance(value, Mapping):
        return dict(value)
    if isinstance(value, str) and value:
        return _resolve(value, base)
    raise CaseFormatError(f"{where}: '{name}' must be a program (JSON object) or a path to one")


def default_id(data: Mapping[str, Any]) -> str:
    """A stable id for a case without one: the shape's name and a hash of the case's content.

    Content, not line number: inserting a line must not rename every case after it, or
    resuming a batch would redo finished work under new names.
    """
    digest = hashlib.sha1(json.dumps(data, sort_keys=True, separators=(",", ":")).encode()).hexdigest()[:10]
    stem = Path(str(data.get("shape", "case"))).name
    for suffix in (".json", ".txt", ".obj", ".glb"):
        stem = stem.removesuffix(suffix)
    stem = re.sub(r"[^A-Za-z0-9._-]+", "_", stem).strip("._-") or "case"
    return f"{stem[:80]}-{digest}"


def parse_case(data: Any, source: str = "<cases>", line: int = 0, base: Path | None = None) -> Case:
    """Validate one case object; relative paths are resolved against ``base``."""
    where = _where(source, line)
    base = base or Path.cwd()
    if not isinstance(data, Mapping):
        raise CaseFormatError(f"{where}: a case must be a JSON object")
    unknown = sorted(set(data) - set(FIELDS))
    if unknown:
        raise CaseFormatError(f"{where}: unknown field(s) {', '.join(unknown)} (known: {', '.join(FIELDS)})")
    kind = data.get("kind", "edit")
    if kind in RESERVED_KINDS:
        raise CaseFormatError(f"{where}: kind {kind!r} is reserved for the applications and not supported by "
                              f"this version of parsel-batch (supported: {', '.join(KINDS)})")
    if kind not in KINDS:
        raise CaseFormatError(f"{where}: unknown kind {kind!r} (known: {', '.join(KINDS)})")
    shape = data.get("shape")
    if not isinstance(shape, str) or not shape:
        raise CaseFormatError(f"{where}: 'shape' (an example name or a shape file) is required")
    case_id = data.get("id", default_id(data))
    if not isinstance(case_id, str) or not _ID.match(case_id) or case_id in RESERVED_IDS:
        raise CaseFormatError(f"{where}: id {case_id!r} must be 1-128 letters, digits, '.', '_' or '-', "
                              "starting with a letter or digit (it names the case's output folder)")
    request = data.get("request")
    if request is not None and (not isinstance(request, str) or not request.strip()):
        raise CaseFormatError(f"{where}: 'request' must be non-empty text")
    seed = _seed_text(data.get("seed"), where)
    expert = None
    if seed is not None or "hints" in data or "breaks" in data:
        if seed is None:
            raise CaseFormatError(f"{where}: expert 'hints' or 'breaks' need a 'seed'")
        expert = Inputs(seed, _hints(data.get("hints"), where), _breaks(data.get("breaks"), where))
    recorded = None
    if "llm" in data:
        llm = data["llm"]
        if not isinstance(llm, Mapping) or set(llm) - set(LLM_FIELDS):
            raise CaseFormatError(f"{where}: 'llm' must be an object with fields {', '.join(LLM_FIELDS)}")
        program = _program_ref(llm.get("program"), "llm.program", where, base)
        llm_seed = _seed_text(llm.get("seed"), f"{where}: llm")
        if llm_seed is None and program is None:
            raise CaseFormatError(f"{where}: 'llm' needs the model's 'seed' (or a one-shot 'program')")
        recorded = Inputs(llm_seed, _hints(llm.get("hints"), f"{where}: llm"),
                          _breaks(llm.get("breaks"), f"{where}: llm"), program)
    mode = data.get("mode") or ("language" if recorded is not None else "expert" if expert is not None
                                else "language")
    if mode not in MODES:
        raise CaseFormatError(f"{where}: unknown mode {mode!r} (known: {', '.join(MODES)})")
    if mode == "expert" and expert is None:
        raise CaseFormatError(f"{where}: expert mode needs a 'seed'")
    if mode == "language" and recorded is None and request is None:
        raise CaseFormatError(f"{where}: language mode needs a 'request' (or recorded 'llm' outputs)")
    solver = data.get("solver", "aep")
    if not isinstance(solver, str) or not solver:
        raise CaseFormatError(f"{where}: 'solver' must be a solver name")
    options = data.get("options", {})
    if not isinstance(options, Mapping):
        raise CaseFormatError(f"{where}: 'options' must be an object (solver options)")
    language = data.get("language", {})
    if not isinstance(language, Mapping) or set(language) - set(LANGUAGE_FIELDS):
        raise CaseFormatError(f"{where}: 'language' must be an object with fields {', '.join(LANGUAGE_FIELDS)}")
    try:
        settings = LanguageSettings(**language)
    except TypeError as exc:
        raise CaseFormatError(f"{where}: 'language': {exc}") from None
    if not isinstance(settings.samples, int) or isinstance(settings.samples, bool) or settings.samples < 1:
        raise CaseFormatError(f"{where}: 'language.samples' must be a positive integer")
    target = data.get("target")
    if target is not None and (not isinstance(target, str) or not target):
        raise CaseFormatError(f"{where}: 'target' must be a mesh, point-cloud or shape file, or a shape name")
    return Case(
        id=case_id, shape=_resolve(shape, base), kind=kind, request=request, expert=expert, recorded=recorded,
        ground_truth=_program_ref(data.get("ground_truth"), "ground_truth", where, base), mode=mode,
        solver=solver, options=dict(options), language=settings, line=line,
        target=_resolve(target, base) if target is not None else None,
    )


def read_cases(path: str | Path) -> list[Case]:
    """Every case of a ``.jsonl`` file (blank lines and ``#`` lines skipped), ids unique."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise CaseFormatError(f"{path}: cannot read cases: {exc.strerror}") from None
    except UnicodeDecodeError:
        raise CaseFormatError(f"{path}: cases file is not UTF-8 text") from None
    cases: list[Case] = []
    seen: dict[str, int] = {}
    base = path.resolve().parent
    for number, raw in enumerate(text.splitlines(), start=1):
        if not raw.strip() or raw.lstrip().startswith("#"):
            continue
        try:
            data = json.loads(raw)
        except json.JSONDecodeError as exc:
            raise CaseFormatError(f"{path}:{number}: invalid JSON at column {exc.colno}: {exc.msg}") from None
        case = parse_case(data, str(path), number, base)
        if case.id in seen:
            raise CaseFormatError(f"{path}:{number}: case id {case.id!r} is also on line {seen[case.id]}")
        seen[case.id] = number
        cases.append(case)
    if not cases:
        raise CaseFormatError(f"{path}: no cases")
    return cases


def case_ids(cases: Sequence[Case]) -> list[str]:
    return [c.id for c in cases]
