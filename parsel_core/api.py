"""The Python API: the whole job in one call, for integrators and for the CLI alike.

``edit`` runs the pipeline of ``parsel edit`` (language layer or expert seed, solver,
relation report) and returns an :class:`EditResult` with everything the command writes;
``check``, ``apply``, ``export``, ``proxydural`` and ``variations`` do the same for the
other commands. The ``parsel`` command is a thin caller of these functions: it parses
arguments, writes the result's files and prints a summary.

A language-model provider is given by name (``"offline"``, ``"litellm"``, ``"replay"``
or any installed) or as an object with a ``complete`` method (an
:class:`parsel_core.interfaces.LLMProvider`), which is registered for the duration of
the call only::

    from parsel_core import edit
    result = edit("chair", "make the chair wider")
    print(result.program.to_text(), result.report.counts())

Nothing here writes files: each result has ``files()`` (name -> text), which
:func:`parsel_core.io.write_outdir` writes all at once.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from parsel_core import hookimpl
from parsel_core.errors import ParselError
from parsel_core.verbosity import log_solver_stats, logger

if TYPE_CHECKING:  # importing this module stays cheap (the CLI imports it to build its parser)
    from parsel_core.graph import ShapeGraph
    from parsel_core.program import Evaluation, Program
    from parsel_core.report import RelationReport

    ShapeLike = ShapeGraph | str | Path
    ProgramLike = Program | str | Path

#: The most requests (proxydural sliders, variants) one call asks for: each is a full edit.
MAX_REQUESTS = 20

__all__ = [
    "EditResult", "ProxyduralResult", "VariationsResult", "apply", "check", "edit", "export", "proxydural",
    "records_jsonl", "solve_request", "variations",
]


def as_shape(shape: ShapeLike) -> ShapeGraph:
    """A shape graph as is, else a bundled example name or a file (``load_shape``)."""
    from parsel_core.graph import ShapeGraph

    if isinstance(shape, ShapeGraph):
        return shape
    from parsel_core.loading import load_shape

    return load_shape(str(shape))


def as_program(program: ProgramLike) -> Program:
    """A program as is, else a program file (JSON or text form)."""
    from parsel_core.program import Program

    if isinstance(program, Program):
        return program
    from parsel_core.loading import load_program

    return load_program(program)


def records_jsonl(records: Iterable[Mapping[str, Any]]) -> str:
    """Prompt and reply records as JSON lines (the replay provider's format)."""
    return "".join(json.dumps(r, sort_keys=True) + "\n" for r in records)


def report_json(report: RelationReport) -> str:
    return json.dumps(report.to_dict(), indent=1) + "\n"


class _ProviderPlugin:
    """Registers a caller's provider object under its name for one call."""

    def __init__(self, provider: Any) -> None:
        self.provider = provider

    @hookimpl
    def parsel_llm_providers(self) -> list[Any]:
        return [self.provider]


@contextmanager
def provider_name(provider: Any) -> Iterator[str]:
    """The registry name to pass to the language layer for ``provider`` (a name or an object)."""
    if isinstance(provider, str):
        yield provider
        return
    if not callable(getattr(provider, "complete", None)):
        raise ParselError(f"provider {provider!r} is neither a provider name nor an object with complete()")
    from parsel_core.plugins import registered

    name = getattr(provider, "name", "") or type(provider).__name__
    if getattr(provider, "name", "") != name:
        try:
            provider.name = name
        except AttributeError:
            raise ParselError(f"provider {provider!r} has no name and takes none") from None
    with registered(_ProviderPlugin(provider), name=f"parsel-api-provider-{id(provider)}"):
        yield name


@dataclass
class EditResult:
    """What :func:`edit` produced: the program, its relation report, every prompt and
    reply (``record``), token and cost ``accounting``, per-stage ``timings`` in seconds,
    the relations the solver could not keep (``rejected``) and the language layer's
    ``inference`` (``None`` in expert mode)."""

    shape: ShapeGraph
    program: Program
    report: RelationReport
    record: list[dict[str, Any]] = field(default_factory=list)
    accounting: dict[str, Any] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)
    rejected: list[str] = field(default_factory=list)
    inference: Any = None

    def files(self) -> dict[str, str]:
        """What ``parsel edit`` writes: program.json, report.json and (with a request) record.jsonl."""
        files = {"program.json": self.program.to_json(), "report.json": report_json(self.report)}
        if self.inference is not None:
            files["record.jsonl"] = records_jsonl(self.record)
        return files


def _inference_options(api_base: str | None, replay: str | Path | None, cache_dir: str | Path | None,
                       extra: Mapping[str, Any] | None) -> dict[str, Any]:
    options = {"api_base": api_base, "replay": None if replay is None else str(replay),
               "cache_dir": None if cache_dir is None else str(cache_dir), **dict(extra or {})}
    return {k: v for k, v in options.items() if v is not None}


def edit(shape: ShapeLike, request: str | None = None, seed: str | Program | None = None, *,
         provider: Any = "offline", model: str | None = None, mode: str = "full", samples: int = 5,
         hints: Mapping[str, str] | None = None, breaks: Sequence[str] = (), solver: str = "aep",
         backend: str | None = None, tau: float | None = None, nhbd: bool = True, breaking: bool = True,
         api_base: str | None = None, replay: str | Path | None = None, cache_dir: str | Path | None = None,
         timeout: float | None = None, retries: int | None = None, with_image: bool = False,
         provider_options: Mapping[str, Any] | None = None,
         solver_options: Mapping[str, Any] | None = None, on: ProgramLike | None = None) -> EditResult:
    """A request in words (through the language layer) or a seed edit (expert mode) -> a
    complete program with its relation report (``parsel edit``).

    ``on`` (a program or a program file, ``parsel edit --on``) grows an existing program:
    the request is solved on the rest shape and added as a new layer with its own
    parameter (:func:`parsel_core.joint.add_layer`), and the report checks the joint box
    of all the parameters.

    ``seed`` is op text (``"scale_1d(seat, ..., amount=x)"``) or a :class:`Program`;
    ``hints`` and ``breaks`` add to (and override) what the language layer infers.
    ``timeout`` and ``retries`` go to the provider (seconds per call, retries after a rate
    limit or server error); ``with_image`` sends a picture of the shape with the prompts;
    ``solver_options`` go to the solver as they are (after ``nhbd``, ``breaking``, ``tau``).
    ``provider`` is a registered name or a provider object. Raises ``ParselError`` on bad
    input and ``InferenceError`` (with the prompt record attached) when no usable seed
    comes back.
    """
    from parsel_core.interfaces import SolveRequest
    from parsel_core.plugins import get_cas_backend, get_named, solvers
    from parsel_core.program import Program
    from parsel_core.report import check_program, report_from_errors
    from parsel_core.textform import seed_from_text

    if seed is None and not request:
        raise ParselError('an edit needs a request in words or a seed op (expert mode), e.g. '
                          '"scale_1d(seat, origin=(0, 0.45, 0), dir=(1, 0, 0), amount=x)"')
    chosen = get_named("solver", solvers(), solver)
    get_cas_backend(backend)  # fail early on an unknown backend
    timings: dict[str, float] = {}
    started = time.perf_counter()
    graph = as_shape(shape)
    timings["load_s"] = time.perf_counter() - started
    base = None if on is None else base_program(on, graph)
    hints = dict(hints or {})
    breaks = list(breaks)
    metadata: dict[str, Any] = {"solver": chosen.name, "shape": graph.name}
    inference = None
    if seed is not None:
        seed_program = seed if isinstance(seed, Program) else seed_from_text(seed)
        seed_program.validate(graph)
        metadata["seed"] = seed if isinstance(seed, str) else seed_program.to_text().strip()
        if request:
            metadata["request"] = request
    else:
        from parsel_core.language import infer

        started = time.perf_counter()
        extra = {"timeout": timeout, "retries": retries, **dict(provider_options or {})}
        if with_image:
            from parsel_core.language.picture import shape_picture

            extra["image"] = shape_picture(graph)
        with provider_name(provider) as name:
            inference = infer(graph, request, provider=name, model=model, mode=mode, samples=samples,
                              options=_inference_options(api_base, replay, cache_dir, extra))
        timings["infer_s"] = time.perf_counter() - started
        seed_program = inference.seed
        hints = {**inference.hints, **hints}
        breaks = sorted(set(inference.breaks) | set(breaks))
        metadata.update({"request": request, "provider": name, "mode": mode})
        if model:
            metadata["model"] = model
    metadata.update({"hints": dict(hints), "breaks": breaks})
    options: dict[str, Any] = {"nhbd": nhbd, "breaking": breaking, "backend": backend}
    if tau is not None:
        options["tau"] = tau
    options.update(solver_options or {})
    solve = SolveRequest(graph, seed_program, hints, tuple(breaks), options)
    started = time.perf_counter()
    if inference is not None and inference.program is not None:  # one-shot: the model wrote it all
        program, rejected, stats = inference.program, [], {}
        metadata["solver"] = "none (one-shot)"
    else:
        result = chosen.run(solve)
        program, rejected, stats = result.program, list(result.rejected), dict(result.stats)
    timings["solve_s"] = time.perf_counter() - started
    program = program.with_metadata(metadata)
    if base is not None:
        program, breaks = _on_base(graph, base, program, metadata, breaks)
        solve = SolveRequest(graph, seed_program, hints, tuple(breaks), options)
    started = time.perf_counter()
    online = stats.get("online") if isinstance(stats.get("online"), dict) else None
    if online is not None and "errors" in online and base is None:  # a solver that re-solves per value checked itself
        report = report_from_errors(graph, online["errors"], solve.breaks, online["samples"])
    else:
        report = check_program(graph, program, solve.breaks)
    timings["check_s"] = time.perf_counter() - started
    report.extra.update({"shape": graph.name, "solver": metadata["solver"], "rejected": rejected,
                         "stats": {**stats, "load_s": timings["load_s"]}})
    log_solver_stats(stats, timings, rejected, metadata["solver"])
    if inference is not None:
        report.extra["language"] = inference.summary()
    return EditResult(graph, program, report, list(inference.record) if inference else [],
                      dict(inference.accounting) if inference else {}, timings, rejected, inference)


def base_program(on: ProgramLike, graph: ShapeGraph) -> Program:
    """The program ``edit(on=...)`` grows: read (a file or an OUTDIR of parsel edit) and checked
    against the shape, every error one line naming the file."""
    from parsel_core.program import Program

    if isinstance(on, Program):
        where, program = "--on program", on
    else:
        path = Path(on)
        if path.is_dir():
            path = path / "program.json"
        if not path.is_file():
            raise ParselError(f"{path}: no such program file (--on takes the program.json of an earlier parsel edit "
                              f"or proxydural)")
        where, program = str(path), as_program(path)
    named = program.metadata.get("shape")
    if isinstance(named, str) and named and named != graph.name:
        raise ParselError(f"{where}: is a program for shape {named!r}, not {graph.name!r}")
    try:
        program.validate(graph)
    except ParselError as exc:
        raise ParselError(f"{where}: does not match shape {graph.name!r}: {exc}") from None
    return program


def _on_base(graph: ShapeGraph, base: Program, program: Program, metadata: Mapping[str, Any],
             breaks: Sequence[str]) -> tuple[Program, list[str]]:
    """``program`` (one request, solved on the rest shape) added to ``base`` as a new layer; the
    metadata lists every layer's request and the relations any of them may break."""
    from parsel_core.joint import add_layer

    text = metadata.get("request") or metadata.get("seed") or ""
    combined, name = add_layer(graph, base, program, str(text))
    all_breaks = sorted(set(base.metadata.get("breaks") or ()) | set(breaks))
    meta = {**{k: v for k, v in metadata.items() if k not in ("request", "seed", "hints", "breaks")},
            "application": "stacked", "requests": combined.metadata["requests"], "breaks": all_breaks}
    return combined.with_metadata(meta), all_breaks


def check(shape: ShapeLike, program: ProgramLike, breaks: Iterable[str] = (), samples: int = 50,
          backend: str | None = None) -> RelationReport:
    """The relation report of any program on a shape over its parameter range (``parsel check``);
    ``backend`` evaluates through that CAS backend instead of the numpy reference."""
    from parsel_core.report import check_program

    return check_program(as_shape(shape), as_program(program), tuple(breaks), samples=samples, backend=backend)


def apply(shape: ShapeLike, program: ProgramLike, values: Mapping[str, float] | None = None) -> Evaluation:
    """The edited shape's corners at parameter ``values`` (defaults for the others), checked against the range."""
    from parsel_core.program import evaluate

    graph, program = as_shape(shape), as_program(program)
    program.validate(graph)
    return evaluate(program, graph, program.values(values))


def export(shape: ShapeLike, program: ProgramLike, path: str | Path, values: Mapping[str, float] | None = None,
           sweep: int | None = None, progress: bool = False, backend: str | None = None) -> list[Path]:
    """Write the edited shape with the exporter the suffix of ``path`` picks (``parsel apply``).

    With ``sweep=N``, N files ``stem_000.ext`` ... across the first parameter's range,
    all written or none (``progress``: a display on stderr). ``backend`` evaluates through
    that CAS backend instead of the numpy reference. Returns the paths written.
    """
    import numpy as np

    from parsel_core.io import write_all
    from parsel_core.plugins import exporter_for
    from parsel_core.program import Program, evaluator

    where = "" if isinstance(program, Program) else f"{program}: "
    graph, program = as_shape(shape), as_program(program)
    program.validate(graph)
    values = program.values(values)
    output = Path(path)
    exporter = exporter_for(graph, output)
    evaluate = evaluator(program, graph, backend)
    logger.debug(f"exporter {getattr(exporter, 'name', type(exporter).__name__)}, evaluated with "
                 f"{backend or 'the numpy reference'}")
    if sweep is None:
        started = time.perf_counter()
        exporter.export(graph, evaluate(values), output)
        logger.debug(f"{output}: {time.perf_counter() - started:.3f} s")
        return [output]
    if sweep < 2:
        raise ParselError("--sweep needs at least 2 steps")
    if not program.parameters:
        raise ParselError(f"{where}the program has no parameter to sweep")
    parameter = program.parameters[0]
    suffix = next(ext for ext in exporter.extensions if output.name.lower().endswith(ext))
    stem = output.name[: -len(suffix)]
    paths = [output.with_name(f"{stem}_{i:03d}{suffix}") for i in range(sweep)]
    xs = np.linspace(parameter.lo, parameter.hi, sweep)
    bar = _progress(sweep, "files", progress)  # watertight exporters take seconds per file

    def write(i: int, target: Path) -> None:
        started = time.perf_counter()
        exporter.export(graph, evaluate({**values, parameter.name: float(xs[i])}), target)
        logger.debug(f"{target}: {time.perf_counter() - started:.3f} s")
        bar.update(1)

    write_all(paths, write)
    bar.close()
    return paths


def solve_request(shape: ShapeGraph, text: str, records: list[dict[str, Any]], *, provider: Any = "offline",
                  model: str | None = None, samples: int = 5, backend: str | None = None,
                  api_base: str | None = None, cache_dir: str | Path | None = None,
                  provider_options: Mapping[str, Any] | None = None) -> tuple[Program, list[str], list[str]]:
    """One request in words -> (program, rejected relations, breaks) through the language
    layer and AEP; the prompts and replies are appended to ``records``."""
    from parsel_core.interfaces import SolveRequest
    from parsel_core.language import infer
    from parsel_core.plugins import get_named, solvers

    with provider_name(provider) as name:
        inference = infer(shape, text, provider=name, model=model, samples=samples,
                          options=_inference_options(api_base, None, cache_dir, provider_options))
    records.extend(inference.record)
    solver = get_named("solver", solvers(), "aep")
    result = solver.run(SolveRequest(shape, inference.seed, inference.hints, tuple(inference.breaks),
                                     {"backend": backend}))
    log_solver_stats(result.stats, None, result.rejected, f"{solver.name} ({text})")
    return result.program, list(result.rejected), list(inference.breaks)


def _progress(total: int, desc: str, enabled: bool) -> Any:
    from parsel_core.progress import progress

    return progress(total, desc, enabled=enabled)


def _check_count(count: int) -> None:
    if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= MAX_REQUESTS:
        raise ParselError(f"the number of requests must be an integer from 1 to {MAX_REQUESTS}, got {count!r}")


def _solve_each(graph: ShapeGraph, texts: Sequence[str], records: list[dict[str, Any]], name: str, what: str,
                progress: bool, **options: Any) -> Iterator[tuple[str, Program | None, list[str], str | None]]:
    """Each request solved on the rest shape, in order: (text, program, breaks, None), or
    (text, None, [], why) when the language layer gave no usable seed. Shared by
    ``proxydural`` and ``variations``, which differ only in what they do with the programs."""
    from parsel_core.language import InferenceError

    bar = _progress(len(texts), what, progress)
    try:
        for text in texts:
            bar.update(1)
            try:
                program, _, request_breaks = solve_request(graph, text, records, provider=name, **options)
            except InferenceError as exc:
                yield text, None, [], str(exc)
                continue
            yield text, program, request_breaks, None
    finally:
        bar.close()


@dataclass
class ProxyduralResult:
    """A proxydural model: one stacked program with a slider per request (``used``),
    requests that gave no program (``skipped``), the report with all sliders moving and
    the counts with each slider alone (``per_slider``)."""

    shape: ShapeGraph
    program: Program
    report: RelationReport
    per_slider: dict[str, dict[str, int]]
    used: list[dict[str, str]]
    skipped: list[dict[str, str]]
    record: list[dict[str, Any]]

    def files(self) -> dict[str, str]:
        return {"program.json": self.program.to_json(), "report.json": report_json(self.report),
                "record.jsonl": records_jsonl(self.record)}


def proxydural(shape: ShapeLike, count: int = 5, *, provider: Any = "offline", model: str | None = None,
               samples: int = 5, backend: str | None = None, api_base: str | None = None,
               cache_dir: str | Path | None = None, provider_options: Mapping[str, Any] | None = None,
               progress: bool = False, check_samples: int = 200) -> ProxyduralResult:
    """Proxydural modelling (paper 8.1): ``count`` requests proposed for the shape, one
    program each, added as layers with one slider each (``parsel proxydural``).

    Each request is solved on the rest shape and its displacements add to the others'
    (:func:`parsel_core.joint.add_layer`), so every combination of the sliders keeps each
    relation every slider keeps alone. The report checks the joint box (its corners and
    ``check_samples`` random points) first, then each slider alone (``per_slider``)."""
    from parsel_core.joint import add_layer
    from parsel_core.language import proxydural_requests
    from parsel_core.report import check_each_parameter, check_program

    _check_count(count)
    graph = as_shape(shape)
    options = {"model": model, "samples": samples, "backend": backend, "api_base": api_base,
               "cache_dir": cache_dir, "provider_options": provider_options}
    with provider_name(provider) as name:
        proposal = proxydural_requests(graph, count=count, provider=name, model=model)
        records = list(proposal.record)
        composed, used, skipped, breaks = None, [], [], set()
        for i, (text, program, request_breaks, reason) in enumerate(
                _solve_each(graph, proposal.requests, records, name, "requests", progress, **options), start=1):
            if program is None:
                skipped.append({"request": text, "reason": str(reason)})
                continue
            try:
                composed, parameter = add_layer(graph, composed, program, text, name=f"x{i}")
            except ParselError as exc:  # its layout or its collapse does not combine with the others
                skipped.append({"request": text, "reason": str(exc)})
                continue
            used.append({"request": text, "parameter": parameter})
            breaks.update(request_breaks)
    if composed is None:
        raise ParselError(f"none of the {len(proposal.requests)} proposed requests could be turned into a program")
    composed = composed.with_metadata({"solver": "aep", "shape": graph.name, "application": "proxydural",
                                       "requests": used, "breaks": sorted(breaks)})
    report = check_program(graph, composed, sorted(breaks), samples=check_samples)
    per_slider = check_each_parameter(graph, composed, sorted(breaks))
    report.extra.update({"shape": graph.name, "requests": used, "skipped": skipped, "per_slider": per_slider})
    return ProxyduralResult(graph, composed, report, per_slider, used, skipped, records)


@dataclass
class Variant:
    """One variant of a family: its request and either its program and report or why it was skipped."""

    request: str
    program: Program | None = None
    report: RelationReport | None = None
    skipped: str | None = None


@dataclass
class VariationsResult:
    """A shape variation family: variants of one request, one program each."""

    shape: ShapeGraph
    request: str
    variants: list[Variant]
    record: list[dict[str, Any]]

    def files(self) -> dict[str, str]:
        """What ``parsel variations`` writes: numbered programs and reports, a summary, the record."""
        files: dict[str, str] = {}
        summary = []
        for i, variant in enumerate(self.variants, start=1):
            if variant.program is None or variant.report is None:
                summary.append({"request": variant.request, "skipped": variant.skipped})
                continue
            name = f"variation_{i:02d}"
            files[f"{name}.program.json"] = variant.program.to_json()
            files[f"{name}.report.json"] = report_json(variant.report)
            summary.append({"request": variant.request, "program": f"{name}.program.json",
                            "counts": variant.report.counts()})
        files["variations.json"] = json.dumps({"request": self.request, "shape": self.shape.name,
                                               "variants": summary}, indent=1) + "\n"
        files["record.jsonl"] = records_jsonl(self.record)
        return files


def variations(shape: ShapeLike, request: str, count: int = 3, *, provider: Any = "offline",
               model: str | None = None, samples: int = 5, backend: str | None = None, api_base: str | None = None,
               cache_dir: str | Path | None = None, provider_options: Mapping[str, Any] | None = None,
               progress: bool = False) -> VariationsResult:
    """Shape variation families (paper 8.2): ``count`` variants of ``request``, one program
    each (``parsel variations``); a variant with several parameters is checked on their
    joint box, as every report is."""
    from parsel_core.language import variation_requests
    from parsel_core.report import check_program

    _check_count(count)
    graph = as_shape(shape)
    variants: list[Variant] = []
    options = {"model": model, "samples": samples, "backend": backend, "api_base": api_base,
               "cache_dir": cache_dir, "provider_options": provider_options}
    with provider_name(provider) as name:
        proposal = variation_requests(graph, request, count=count, provider=name, model=model)
        records = list(proposal.record)
        for text, program, request_breaks, reason in _solve_each(graph, proposal.requests, records, name,
                                                                 "variants", progress, **options):
            if program is None:
                variants.append(Variant(text, skipped=reason))
                continue
            program = program.with_metadata({"solver": "aep", "shape": graph.name, "application": "variations",
                                             "request": text, "family": request})
            variants.append(Variant(text, program, check_program(graph, program, request_breaks)))
    if not any(v.program is not None for v in variants):
        raise ParselError(f"none of the variants of {request!r} could be turned into a program")
    return VariationsResult(graph, request, variants, records)
