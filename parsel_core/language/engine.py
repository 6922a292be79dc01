"""LLM-augmented inference (paper section 6): prompts, concurrent samples, voting.

From a request and a shape, :func:`infer` asks a provider for the seed edit, type hints
for other parts and, one prompt per symmetry relation, whether the request keeps that
relation (``full`` mode); or only the seed (``seed-only``); or a whole program
(``one-shot``, the paper's baseline). Every prompt is sampled ``samples`` times; all
calls are independent and run concurrently on threads. Each reply is parsed into a
value or rejected with a reason; valid values are majority-voted per task. Everything
sent and received is kept in ``Inference.record``, in the format the replay provider
reads back.
"""

from __future__ import annotations

import hashlib
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

from parsel_core.errors import ParselError
from parsel_core.graph import GROUP_KINDS, ShapeGraph
from parsel_core.interfaces import Completion, LLMProvider
from parsel_core.language.amounts import check_ops
from parsel_core.language.api import ReplyError, SeedReply, parse_seed_code, read_blocks
from parsel_core.language.cache import ResponseCache, cache_key
from parsel_core.language.describe import describe_shape, relation_block, request_block
from parsel_core.language.picture import PICTURE_TEXT
from parsel_core.language.replies import (
    hints_code,
    one_shot_code,
    requests_code,
    to_json,
    validity_code,
    vote_key,
)
from parsel_core.language.templates import describe_operators, render
from parsel_core.language.voting import Vote, majority, majority_per_key
from parsel_core.program import Parameter, Program

MODES = ("full", "seed-only", "one-shot")
_MODE_ALIASES = {"seed_only": "seed-only", "seedonly": "seed-only", "one_shot": "one-shot", "oneshot": "one-shot"}
DEFAULT_SAMPLES = 5
DEFAULT_WORKERS = 16
MAX_SAMPLES = 50
#: Options :func:`infer` handles itself; all others go to the provider's ``complete``.
ENGINE_OPTIONS = ("cache_dir", "workers", "registry")


class InferenceError(ParselError):
    """Inference failed (no valid seed, provider errors); ``record`` and ``accounting`` say why."""

    def __init__(self, message: str, record: list[dict[str, Any]] | None = None,
                 accounting: dict[str, Any] | None = None) -> None:
        super().__init__(message)
        self.record = record or []
        self.accounting = accounting or {}


@dataclass
class Inference:
    """What the language layer inferred for one request.

    ``seed`` is the seed edit (one parameter ``x``); ``hints`` maps part ids to
    ``translate``/``rotate``/``scale``/``keep``; ``breaks`` lists relation ids the request
    breaks on purpose; ``program`` is the model's whole program in one-shot mode (and
    ``seed`` then holds the same ops). ``record`` has one entry per prompt sample;
    ``accounting`` totals tokens, cost, calls and cache hits; ``votes`` says how each
    task's vote went.
    """

    seed: Program
    hints: dict[str, str]
    breaks: list[str]
    program: Program | None
    record: list[dict[str, Any]]
    accounting: dict[str, Any]
    votes: dict[str, Any] = field(default_factory=dict)
    request: str = ""
    mode: str = "full"

    def summary(self) -> dict[str, Any]:
        """A JSON-ready summary for reports (the record is kept apart: it is large)."""
        from parsel_core.ops import op_to_dict

        return {
            "request": self.request, "mode": self.mode,
            "seed": [op_to_dict(op) for op in self.seed.ops],
            "hints": dict(self.hints), "breaks": list(self.breaks),
            "votes": self.votes, "accounting": self.accounting,
        }


@dataclass(frozen=True)
class Task:
    """One prompt: its template name (the provider's ``task``), unique key and text."""

    name: str
    key: str
    prompt: str
    subject: str | None = None


def normalise_mode(mode: str) -> str:
    key = str(mode).strip().lower()
    key = _MODE_ALIASES.get(key, key)
    if key not in MODES:
        raise ParselError(f"unknown mode {mode!r} (modes: {', '.join(MODES)})")
    return key


def validity_task_name(kind: str) -> str:
    return "reflection_validity" if kind == "reflection" else "group_validity"


def build_tasks(shape: ShapeGraph, request: str, mode: str = "full", *, registry=None,
                picture: bool = False) -> list[Task]:
    """Every prompt a mode needs, in a fixed order: seed, hints, then one per symmetry relation.

    ``registry`` (default: the registered operators) is listed in the seed-edit prompt;
    ``picture`` says whether a picture of the shape goes with the prompts (they then say
    what it shows).
    """
    mode = normalise_mode(mode)
    if registry is None:
        from parsel_core.plugins import edit_operators

        registry = edit_operators()
    shape_text, request_text = describe_shape(shape), request_block(request)
    seen = {"shape": shape_text, "request": request_text, "picture": f"\n\n{PICTURE_TEXT}" if picture else ""}
    if mode == "one-shot":
        return [Task("one_shot", "one_shot", render("one_shot", **seen))]
    tasks = [Task("seed_edit", "seed_edit", render("seed_edit", **seen, operators=describe_operators(registry)))]
    if mode == "seed-only":
        return tasks
    tasks.append(Task("type_hints", "type_hints", render("type_hints", **seen)))
    for relation in shape.relations.values():
        if relation.kind != "reflection" and relation.kind not in GROUP_KINDS:
            continue
        name = validity_task_name(relation.kind)
        prompt = render(name, **seen, relation=relation_block(shape, relation.id))
        tasks.append(Task(name, f"{name}:{relation.id}", prompt, relation.id))
    return tasks


_REPLAY: LLMProvider | None = None


def get_provider(name: str) -> LLMProvider:
    """A registered provider by name; ``replay`` works even before it is registered as a built-in."""
    global _REPLAY
    from parsel_core.plugins import get_named, llm_providers

    table = llm_providers()
    if name == "replay" and name not in table:
        if _REPLAY is None:
            from parsel_core.language.replay import ReplayProvider

            _REPLAY = ReplayProvider()
        return _REPLAY
    return get_named("LLM provider", table, name)


def prompt_hash(prompt: str) -> str:
    """The SHA-256 of a prompt: the record keeps it so a replay can tell prompts apart."""
    return hashlib.sha256(prompt.encode("utf-8")).hexdigest()


def _parser(task: str, shape: ShapeGraph, registry) -> Callable[[str], Any]:
    """The reader of one code block of a ``task`` reply."""
    if task == "seed_edit":
        def seed(code: str) -> SeedReply:
            value = parse_seed_code(code, shape, registry)
            try:
                Program(value.ops).validate(shape)
            except ParselError as exc:
                raise ReplyError(str(exc)) from None
            check_ops(value.ops)
            return value
        return seed
    if task == "type_hints":
        return lambda code: hints_code(code, shape)
    if task in ("reflection_validity", "group_validity"):
        return validity_code
    if task == "one_shot":
        def one_shot(code: str) -> Program:
            program = one_shot_code(code, shape, registry)
            if len(program.parameters) != 1:
                raise ReplyError(f"the program must have one parameter, it has {len(program.parameters)}")
            parameter = program.parameters[0]
            check_ops(program.ops, parameter.name, parameter.lo, parameter.hi)
            return program
        return one_shot
    if task in ("proxydural", "variations"):
        return requests_code
    raise ParselError(f"no reply parser for task {task!r}")


@dataclass
class _Run:
    """The raw outcome of issuing tasks: record entries and parsed values per task key."""

    record: list[dict[str, Any]]
    values: dict[str, list[tuple[bool, Any]]]
    accounting: dict[str, Any]
    stopped: str | None = None

    def check_stopped(self, provider: str) -> None:
        """Raise one error when a call said the provider is unusable (bad key, model, request, dead server)."""
        if self.stopped is not None:
            skipped = self.accounting.get("skipped", 0)
            raise InferenceError(f"provider {provider!r} failed: {self.stopped}"
                                 + (f" ({skipped} further call{'s' if skipped != 1 else ''} not sent)"
                                    if skipped else ""), self.record, self.accounting)


def run_tasks(shape: ShapeGraph, tasks: Sequence[Task], *, provider: str, model: str | None, samples: int,
              options: Mapping[str, Any] | None = None) -> _Run:
    """Issue every (task, sample) call concurrently, parse the replies, keep the record."""
    options = dict(options or {})
    if isinstance(samples, bool) or not isinstance(samples, int) or not 1 <= samples <= MAX_SAMPLES:
        raise ParselError(f"samples must be a whole number from 1 to {MAX_SAMPLES}, got {samples!r}")
    engine = {k: options.pop(k) for k in ENGINE_OPTIONS if k in options}
    registry = engine.get("registry")
    if registry is None:
        from parsel_core.plugins import edit_operators

        registry = edit_operators()
    instance = get_provider(provider)
    cache = None
    if engine.get("cache_dir") and getattr(instance, "cacheable", True):
        cache = ResponseCache(engine["cache_dir"])
    parsers = {task.key: _parser(task.name, shape, registry) for task in tasks}
    call_options = {k: v for k, v in options.items() if v is not None}
    if model is not None:
        call_options["model"] = model
    image = call_options.get("image")
    if image is not None and not isinstance(image, (bytes, bytearray)):
        raise ParselError("the image option must be the bytes of a PNG picture")
    image_hash = hashlib.sha256(image).hexdigest() if image is not None else None
    stopped: list[str] = []  # the error that stopped the run, once a call fails for good
    stop_lock = threading.Lock()

    def call(task: Task, sample: int) -> dict[str, Any]:
        entry: dict[str, Any] = {"task": task.name, "key": task.key, "subject": task.subject, "sample": sample,
                                 "provider": provider, "model": model, "prompt": task.prompt,
                                 "prompt_sha256": prompt_hash(task.prompt), "reply": None,
                                 "parsed": None, "rejected": None, "error": None, "cached": False,
                                 "prompt_tokens": 0, "completion_tokens": 0, "cost": 0.0, "seconds": 0.0}
        if image_hash is not None:
            entry["image_sha256"] = image_hash
        started = time.perf_counter()
        completion: Completion | None = None
        cache_text = task.prompt if image_hash is None else f"{task.prompt}\n<image sha256={image_hash}>"
        key = cache_key(provider, model, cache_text, sample) if cache is not None else ""
        if cache is not None:
            completion = cache.get(key)
            entry["cached"] = completion is not None
        if completion is None:
            if stopped:
                entry["error"] = entry["rejected"] = f"not sent: an earlier call failed ({stopped[0]})"
                entry["skipped"] = True
                return entry
            try:
                replies = instance.complete(task.prompt, task=task.name, samples=1, key=task.key, sample=sample,
                                            **call_options)
                if not replies or not isinstance(replies[0], Completion):
                    raise ParselError(f"provider {provider!r} returned no completion")
                completion = replies[0]
            except Exception as exc:  # a failed call is recorded; one that says the provider is unusable stops the run
                entry["error"] = f"{type(exc).__name__}: {exc}" if not isinstance(exc, ParselError) else str(exc)
                entry["rejected"] = f"provider error: {entry['error']}"
                entry["seconds"] = time.perf_counter() - started
                if getattr(exc, "stops_run", False):
                    with stop_lock:
                        if not stopped:
                            stopped.append(entry["error"])
                return entry
            if cache is not None:
                cache.put(key, completion)
        entry.update(reply=completion.text, prompt_tokens=completion.prompt_tokens,
                     completion_tokens=completion.completion_tokens,
                     cost=0.0 if entry["cached"] else completion.cost)
        entry["seconds"] = time.perf_counter() - started
        entry["_unread"] = True
        return entry

    def read(task: Task, entry: dict[str, Any]) -> None:
        """The reply's code read into ``entry``, in the calling thread: CPython 3.11 keeps
        ``ast``'s recursion depth in module state, so replies parsed by several workers at
        once may fail (SystemError: AST constructor recursion depth mismatch)."""
        if not entry.pop("_unread", False):
            return
        started = time.perf_counter()
        try:
            value, block, blocks = read_blocks(entry["reply"], parsers[task.key])
            if blocks > 1:
                entry["code_block"] = f"{block + 1} of {blocks}"
        except ReplyError as exc:
            entry["rejected"] = str(exc)
        except RecursionError:
            entry["rejected"] = "reply is nested too deeply"
        except (ParselError, ValueError, TypeError, ArithmeticError) as exc:  # untrusted text must not crash a run
            entry["rejected"] = f"unusable reply: {type(exc).__name__}: {exc}"
        else:
            entry["_value"] = value
            entry["parsed"] = to_json(value)
        entry["seconds"] += time.perf_counter() - started

    jobs = [(task, sample) for task in tasks for sample in range(samples)]
    started = time.perf_counter()
    workers = max(1, min(int(engine.get("workers", DEFAULT_WORKERS)), len(jobs)))
    # The first call goes alone: a bad key, model or server then costs one call, not all of them.
    entries = [call(*jobs[0])]
    with ThreadPoolExecutor(max_workers=workers, thread_name_prefix="parsel-llm") as pool:
        entries.extend(pool.map(lambda job: call(*job), jobs[1:]))
    for (task, _), entry in zip(jobs, entries):
        read(task, entry)
    values: dict[str, list[tuple[bool, Any]]] = {task.key: [] for task in tasks}
    for entry in entries:
        ok = "_value" in entry
        values[entry["key"]].append((ok, entry.pop("_value", None)))
    accounting = {
        "provider": provider, "model": model, "samples": samples, "tasks": len(tasks),
        "calls": sum(1 for e in entries if not e["cached"] and not e.get("skipped")),
        "cache_hits": sum(1 for e in entries if e["cached"]),
        "errors": sum(1 for e in entries if e["error"] and not e.get("skipped")),
        "skipped": sum(1 for e in entries if e.get("skipped")),
        "rejected": sum(1 for e in entries if e["rejected"]),
        "prompt_tokens": sum(e["prompt_tokens"] for e in entries if not e["cached"]),
        "completion_tokens": sum(e["completion_tokens"] for e in entries if not e["cached"]),
        "cost": round(sum(e["cost"] for e in entries), 8),
        "seconds": round(time.perf_counter() - started, 4),
    }
    accounting["total_tokens"] = accounting["prompt_tokens"] + accounting["completion_tokens"]
    return _Run(entries, values, accounting, stopped[0] if stopped else None)


def _reasons(values: Sequence[tuple[bool, Any]], record: Sequence[dict[str, Any]], key: str) -> str:
    reasons = [f"sample {e['sample']}: {e['rejected']}" for e in record if e["key"] == key and e["rejected"]]
    return "; ".join(reasons[:5]) + (f"; ... ({len(reasons) - 5} more)" if len(reasons) > 5 else "")


def infer(shape: ShapeGraph, request: str, *, provider: str = "offline", model: str | None = None,
          mode: str = "full", samples: int = DEFAULT_SAMPLES, options: dict | None = None) -> Inference:
    """Seed edit, type hints and breakable relations for ``request`` on ``shape``.

    ``options``: ``cache_dir`` (reply cache, off when absent), ``workers`` (threads,
    default 16); every other key (``api_base``, ``timeout``, ``retries``,
    ``temperature``, ``replay`` ...) is passed to the provider. Raises
    :class:`InferenceError` (a :class:`ParselError`, with the record attached) when no
    sample gives a usable seed edit or the model says the request cannot be done.
    """
    if not isinstance(request, str) or not request.strip():
        raise ParselError("the edit request is empty")
    mode = normalise_mode(mode)
    registry = (options or {}).get("registry")
    tasks = build_tasks(shape, request, mode, registry=registry, picture=(options or {}).get("image") is not None)
    run = run_tasks(shape, tasks, provider=provider, model=model, samples=samples, options=options)
    run.check_stopped(provider)
    record, accounting = run.record, run.accounting
    votes: dict[str, Any] = {}

    def fail(message: str) -> InferenceError:
        return InferenceError(message, record, accounting)

    if mode == "one-shot":
        vote = majority(run.values["one_shot"], lambda v: vote_key("one_shot", v))
        votes["one_shot"] = vote.to_dict()
        if not vote.decided:
            raise fail(f"no valid program among {samples} one-shot replies from {provider!r}: "
                       f"{_reasons(run.values['one_shot'], record, 'one_shot')}")
        program = vote.winner
        program = Program(program.ops, program.parameters, {"request": request, "provider": provider,
                                                              "model": model, "mode": mode})
        return Inference(program, {}, [], program, record, accounting, votes, request, mode)

    seed_vote = majority(run.values["seed_edit"], lambda v: vote_key("seed_edit", v))
    votes["seed_edit"] = seed_vote.to_dict()
    if not seed_vote.decided:
        raise fail(f"no valid seed edit among {samples} replies from {provider!r}: "
                   f"{_reasons(run.values['seed_edit'], record, 'seed_edit')}")
    winner: SeedReply = seed_vote.winner
    if winner.cannot is not None:
        raise fail(f"{provider!r} cannot turn this request into an edit: {winner.cannot}")
    seed = Program(winner.ops, (Parameter("x"),), {"request": request, "provider": provider, "model": model,
                                                   "mode": mode})
    hints: dict[str, str] = {}
    breaks: list[str] = []
    if mode == "full":
        hints, detail = majority_per_key(run.values["type_hints"])
        valid = sum(ok for ok, _ in run.values["type_hints"])
        votes["type_hints"] = {"hints": hints, "counts": detail, "valid": valid,
                               "total": len(run.values["type_hints"])}
        for task in tasks:
            if task.subject is None:
                continue
            vote: Vote = majority(run.values[task.key], lambda v, name=task.name: vote_key(name, v))
            votes[task.key] = vote.to_dict()
            if vote.decided and vote.winner is False:
                breaks.append(task.subject)
    return Inference(seed, hints, breaks, None, record, accounting, votes, request, mode)


@dataclass
class Proposal:
    """Edit requests proposed by a model (proxydural models, variation families)."""

    requests: list[str]
    record: list[dict[str, Any]]
    accounting: dict[str, Any]
    votes: dict[str, Any] = field(default_factory=dict)


def _propose(shape: ShapeGraph, task: Task, provider: str, model: str | None, samples: int,
             options: dict | None) -> Proposal:
    run = run_tasks(shape, [task], provider=provider, model=model, samples=samples, options=options)
    run.check_stopped(provider)
    vote = majority(run.values[task.key], lambda v: vote_key(task.name, v))
    if not vote.decided:
        raise InferenceError(f"no valid list of requests among {samples} replies from {provider!r}: "
                             f"{_reasons(run.values[task.key], run.record, task.key)}", run.record, run.accounting)
    return Proposal(list(vote.winner), run.record, run.accounting, {task.key: vote.to_dict()})


def proxydural_requests(shape: ShapeGraph, *, count: int = 5, provider: str = "offline", model: str | None = None,
                        samples: int = 1, options: dict | None = None) -> Proposal:
    """Edit requests whose stacked programs make a proxydural model of the shape (paper 8.1)."""
    prompt = render("proxydural", shape=describe_shape(shape), count=int(count))
    return _propose(shape, Task("proxydural", "proxydural", prompt), provider, model, samples, options)


def variation_requests(shape: ShapeGraph, request: str, *, count: int = 3, provider: str = "offline",
                       model: str | None = None, samples: int = 1, options: dict | None = None) -> Proposal:
    """Variants of ``request`` with different secondary effects: a shape variation family (paper 8.2)."""
    prompt = render("variations", shape=describe_shape(shape), request=request_block(request), count=int(count))
    return _propose(shape, Task("variations", "variations", prompt), provider, model, samples, options)
