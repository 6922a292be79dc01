"""Running one case: inference, edit propagation, relation report and metrics.

:func:`run_case` is what a worker executes, locally or on a Dask cluster. It never
raises for a problem of the case itself: the failure is the case's result (a record
with the error and a traceback summary), so one bad asset cannot stop a batch of
thousands. Its outputs are deterministic: the program, the report and the record carry no timings,
except the record's :data:`VOLATILE_KEYS` (wall time, language-model accounting).
"""

from __future__ import annotations

import json
import time
import traceback
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

from parsel_batch.cases import Case, Inputs
from parsel_batch.metrics import language_metrics, program_metrics
from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.program import Program

#: Lines of the traceback kept in a record (the whole traceback goes to error.txt).
TRACEBACK_LINES = 6
#: Keys of a record whose value is null when a metric cannot be computed.
EMPTY_METRICS: dict[str, Any] = {"J_prog": None, "D_geo": None, "rel": None, "rel_considered": None,
                                 "rel_disagreeing": None, "acc_se": None, "acc_r": None, "J_T": None, "match": None}


class CaseError(ParselError):
    """A case that cannot run as written (no language layer, a ground truth that does not load)."""


@dataclass(frozen=True)
class RunDefaults:
    """Settings from the command line that apply to every case unless the case says otherwise."""

    backend: str | None = None


@dataclass
class CaseOutcome:
    """What a worker sends back: the record (a results.jsonl line) and the files of the case's folder."""

    id: str
    record: dict[str, Any]
    files: dict[str, str] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.record.get("status") == "ok"


@lru_cache(maxsize=16)
def _shape(spec: str) -> ShapeGraph:
    """Shapes are read once per worker: cases often share an asset (several requests each)."""
    from parsel_core.loading import load_shape

    return load_shape(spec)


def parse_seed(text: str, where: str) -> Program:
    """Seed op text (ops separated by ``;`` or newlines, ``param`` lines allowed) -> a program,
    read like ``parsel edit --seed``: a seed without ``param`` lines gets ``x`` in [0, 1]."""
    from parsel_core.textform import seed_from_text

    try:
        return seed_from_text(text, source=where)
    except ParselError as exc:
        raise CaseError(str(exc)) from None


def load_program_ref(ref: Mapping[str, Any] | str, where: str) -> Program:
    """A program given inline (its JSON object) or as a path (``.json`` or text form)."""
    from parsel_core.loading import load_program

    if isinstance(ref, Mapping):
        return Program.from_dict(ref, source=where)
    if not Path(ref).exists():
        raise CaseError(f"{where}: no such program file {ref!r}")
    return load_program(ref)


def _seed_text(program: Program) -> str:
    from parsel_core.textform import op_to_text

    return "\n".join(op_to_text(op) for op in program.ops)


@dataclass
class _Inferred:
    """What inference gave: a seed (or a one-shot program), hints, breaks, and provenance."""

    seed: Program | None
    hints: dict[str, str]
    breaks: list[str]
    program: Program | None = None
    source: str = "expert"
    extra: dict[str, Any] = field(default_factory=dict)


def _from_inputs(inputs: Inputs, source: str, case: Case) -> _Inferred:
    seed = parse_seed(inputs.seed, f"case {case.id}: {source} seed") if inputs.seed is not None else None
    program = load_program_ref(inputs.program, f"case {case.id}: {source} program") \
        if inputs.program is not None else None
    return _Inferred(seed, dict(inputs.hints), list(inputs.breaks), program, source)


def _language(shape: ShapeGraph, case: Case, common: dict[str, Any]) -> tuple[_Inferred, Any]:
    """The whole edit through :func:`parsel_core.api.edit` with the case's language-model settings."""
    from parsel_core import api

    settings = case.language
    try:
        result = api.edit(shape, case.request, provider=settings.provider, model=settings.model, mode=settings.mode,
                          samples=settings.samples, provider_options=dict(settings.options) or None, **common)
    except ImportError as exc:
        raise CaseError(f"case {case.id}: language mode needs parsel_core.language, which is not available "
                        f"({exc}); give a 'seed' (expert mode) or recorded 'llm' outputs") from None
    inference = result.inference
    extra = {"provider": settings.provider, "model": settings.model, "mode": inference.mode,
             "votes": inference.votes}
    inferred = _Inferred(inference.seed, dict(inference.hints), list(inference.breaks), inference.program,
                         "language", {"summary": extra, "accounting": dict(inference.accounting)})
    return inferred, result


def _edit(case: Case, defaults: RunDefaults) -> tuple[dict[str, Any], dict[str, str]]:
    """Run an ``edit`` case; returns the record's fields and the output files.

    The pipeline (language layer, solver, relation report) is :func:`parsel_core.api.edit`;
    a recorded one-shot program is taken as it is."""
    from parsel_core import api
    from parsel_core.report import check_program

    shape = _shape(case.shape)
    options = dict(case.options)
    common = {"solver": case.solver, "backend": options.pop("backend", defaults.backend), "solver_options": options}
    result = None
    if case.mode == "expert" or case.recorded is not None:
        if case.mode == "expert":
            assert case.expert is not None
            inferred = _from_inputs(case.expert, "expert", case)
        else:
            inferred = _from_inputs(case.recorded, "llm", case)
        if inferred.program is None:
            assert inferred.seed is not None
            result = api.edit(shape, seed=inferred.seed, hints=inferred.hints, breaks=inferred.breaks, **common)
    else:
        inferred, result = _language(shape, case, common)
    if result is not None:
        program, rejected, report = result.program, list(result.rejected), result.report
        # timings would make outputs differ between runs
        stats = {k: v for k, v in report.extra.get("stats", {}).items() if k not in ("time_s", "load_s")}
    else:  # a recorded one-shot program: the answer as it is
        inferred.program.validate(shape)
        program, rejected, stats, report = inferred.program, [], {}, None
    metadata: dict[str, Any] = {"case": case.id, "solver": case.solver if inferred.program is None else None,
                                "shape": shape.name, "mode": case.mode, "source": inferred.source}
    if case.request is not None:
        metadata["request"] = case.request
    metadata.update({"seed": _seed_text(inferred.seed) if inferred.seed is not None else None,
                     "hints": dict(inferred.hints), "breaks": list(inferred.breaks)})
    program = program.with_metadata(metadata)
    if report is None:
        report = check_program(shape, program, inferred.breaks)
    report.extra.clear()  # the batch record's own keys, in its own order
    report.extra.update({"case": case.id, "shape": shape.name, "solver": metadata["solver"], "rejected": rejected,
                         "stats": stats})
    if inferred.source == "language":
        report.extra["inference"] = inferred.extra["summary"]
    metrics = dict(EMPTY_METRICS)
    ground_truth = None
    if case.ground_truth is not None:
        ground_truth = load_program_ref(case.ground_truth, f"case {case.id}: ground_truth")
        ground_truth.validate(shape)
        metrics.update(program_metrics(shape, program, ground_truth, report.states()).to_dict())
    if case.mode == "language" and case.expert is not None:
        expert_seed = parse_seed(case.expert.seed, f"case {case.id}: expert seed")
        reference = ground_truth if ground_truth is not None else expert_seed
        seed = inferred.seed if inferred.seed is not None else inferred.program
        metrics.update(language_metrics(shape, seed, inferred.hints, inferred.breaks, reference,
                                        case.expert.hints, case.expert.breaks).to_dict())
    record: dict[str, Any] = {
        "shape": shape.name, "ops": len(program.ops), "parameters": [p.name for p in program.parameters],
        "relations": report.counts(), "rejected": rejected, "metrics": metrics,
    }
    if inferred.source != "expert":
        record["inferred"] = {"seed": metadata["seed"], "hints": dict(inferred.hints),
                              "breaks": list(inferred.breaks), "one_shot": inferred.program is not None}
    if "accounting" in inferred.extra:
        record["accounting"] = inferred.extra["accounting"]
    files = {"program.json": program.to_json(), "report.json": json.dumps(report.to_dict(), indent=1) + "\n"}
    if case.target is not None:
        record["fit"], files["fitted.json"] = _fit(shape, program, case)
    return record, files


def _fit(shape: ShapeGraph, program: Program, case: Case) -> tuple[dict[str, Any], str]:
    """Fit the case's program to its target (parsel-fit): the record's ``fit`` and ``fitted.json``."""
    try:
        from parsel_fit.fit import fit_program, fitted_program
        from parsel_fit.targets import load_target
    except ImportError as exc:
        raise CaseError(f"case {case.id}: a 'target' needs the parsel-fit plugin ({exc})") from None
    result = fit_program(shape, program, load_target(case.target))
    fitted = fitted_program(program, result, case.target, timings=False)
    record = {"values": result.values, "distance_before": result.distance_before,
              "distance_after": result.distance_after, "evaluations": result.evaluations}
    return record, fitted.to_json()


def error_summary(exc: BaseException) -> dict[str, Any]:
    """Type, one-line message and the last lines of the traceback: enough to triage a batch."""
    lines = traceback.format_exception(exc)
    tail = [line.rstrip() for chunk in lines for line in chunk.rstrip().splitlines()][-TRACEBACK_LINES:]
    message = " ".join(str(exc).split()) or type(exc).__name__
    return {"type": type(exc).__name__, "message": message, "traceback": tail}


def run_case(case: Case, defaults: RunDefaults | None = None) -> CaseOutcome:
    """Run one case; a failure becomes a ``failed`` record, never an exception."""
    defaults = defaults or RunDefaults()
    started = time.perf_counter()
    base: dict[str, Any] = {"id": case.id, "kind": case.kind, "mode": case.mode, "request": case.request}
    try:
        fields, files = _edit(case, defaults)
        record = {**base, "status": "ok", **fields, "error": None}
    except Exception as exc:  # the case's failure is its result; the batch goes on
        record = {**base, "status": "failed", "error": error_summary(exc)}
        files = {"error.txt": "".join(traceback.format_exception(exc))}
    record["elapsed_s"] = round(time.perf_counter() - started, 6)
    return CaseOutcome(case.id, record, files)


#: Record fields that differ between two runs of the same case: wall time and the language
#: layer's accounting (its seconds, cache hits). They go to results.jsonl only.
VOLATILE_KEYS = ("elapsed_s", "accounting")


def deterministic(record: Mapping[str, Any]) -> dict[str, Any]:
    """A record without its volatile fields: what two runs of the same case agree on."""
    return {k: v for k, v in record.items() if k not in VOLATILE_KEYS}
