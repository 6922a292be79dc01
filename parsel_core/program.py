"""Editing programs: ordered edit ops plus the control parameters their amounts use.

A program is data. Evaluating it at parameter values gives every part's corners (and
the instances of groups whose count or spacing it changes). A *layered* program
(:meth:`Program.plus`, ``layers``) is a sum of edits: each layer's ops run on the rest
shape and the layers' corner displacements add, so edits solved one at a time on the
rest shape compose without breaking any relation (docs/aep.md, "Several parameters"). Three evaluators share the
ops' point maps: :func:`evaluate` (numpy, the reference), :func:`symbolic_corners` (CAS
expressions, what edit propagation reasons about) and :class:`CompiledProgram` (the
symbolic corners lambdified once, so a slider step is one vectorised call).
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any

import numpy as np

from parsel_core import opmath
from parsel_core.cas import CASBackend
from parsel_core.errors import ParameterRangeError, ParselError, ProgramFormatError, UnknownPartError
from parsel_core.expressions import numpy_functions, parse_expression
from parsel_core.graph import GROUP_KINDS, ShapeGraph
from parsel_core.layout import RestLayout, group_instances, rest_layout
from parsel_core.ops import EditOp, GroupOp, op_from_dict, op_to_dict

PROGRAM_FORMAT = "parsel.program"
PROGRAM_VERSION = 1
_IDENTIFIER = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


@dataclass(frozen=True)
class Parameter:
    """A control parameter (a slider): its name, its range [lo, hi] and its default."""

    name: str
    lo: float = 0.0
    hi: float = 1.0
    default: float | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not _IDENTIFIER.match(self.name) or self.name in ("pi", "e"):
            raise ProgramFormatError(f"parameter name {self.name!r} must be an identifier (not pi or e)")
        for key in ("lo", "hi"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not _finite(value):
                raise ProgramFormatError(f"parameter {self.name!r}: {key} must be a finite number, got {value!r}")
            object.__setattr__(self, key, float(value) + 0.0)  # + 0.0: no -0.0 end
        if self.lo > self.hi:
            raise ProgramFormatError(f"parameter {self.name!r}: range [{self.lo}, {self.hi}] is empty")
        default = self.lo if self.default is None else self.default
        if isinstance(default, bool) or not isinstance(default, (int, float)):
            raise ProgramFormatError(f"parameter {self.name!r}: default must be a number, got {default!r}")
        object.__setattr__(self, "default", float(default))
        self.check(self.default)

    def check(self, value: Any) -> None:
        """Raise :class:`ParameterRangeError` if any value lies outside [lo, hi]."""
        if type(value) is float:  # (a slider step: no array made)
            if math.isfinite(value) and self.lo - 1e-12 <= value <= self.hi + 1e-12:
                return
        values = np.asarray(value, dtype=float)
        if not np.all(np.isfinite(values)):
            raise ParameterRangeError(f"parameter {self.name!r}: value {value!r} is not a finite number")
        if np.any(values < self.lo - 1e-12) or np.any(values > self.hi + 1e-12):
            bad = values[(values < self.lo - 1e-12) | (values > self.hi + 1e-12)].ravel()[0]
            raise ParameterRangeError(f"parameter {self.name!r}: value {bad:g} is outside its range "
                                      f"[{self.lo:g}, {self.hi:g}]")

    def samples(self, count: int, seed: int = 0) -> np.ndarray:
        """``count`` values: both ends of the range and uniform random ones between."""
        rng = np.random.default_rng(seed)
        inner = rng.uniform(self.lo, self.hi, size=max(count - 2, 0)) if self.hi > self.lo else \
            np.full(max(count - 2, 0), self.lo)
        return np.concatenate([[self.lo, self.hi], inner])[:count]


def _finite(value: int | float) -> bool:
    try:
        return math.isfinite(value)
    except OverflowError:  # an integer beyond any float
        return False


def _bad_follow(value: Any) -> Follow:
    raise ProgramFormatError(f"follows: each entry must be an object with part, point and ops, got {value!r}")


@dataclass(frozen=True)
class Follow:
    """Ops of an outer layer whose points travel with one point of a part.

    Before the layer runs, ``point`` (a point of ``part`` at rest) is found where the layers
    before it moved it, by its cage coordinates in the part; call that displacement ``d``.
    Each op in ``ops`` (indices into the program) then runs conjugated by it,
    ``p -> op(p - d) + d``: the op with its origin carried along (docs/aep.md, "Several
    parameters"). A door's turn about its hinge, after a widening moved the hinge, still
    turns the door (and its handle) about the hinge."""

    part: str
    point: tuple[float, float, float]
    ops: tuple[int, ...]

    def __post_init__(self) -> None:
        from parsel_core.ops import as_vector

        if not isinstance(self.part, str) or not self.part:
            raise ProgramFormatError(f"follows: part must be a part id, got {self.part!r}")
        object.__setattr__(self, "point", as_vector(self.point, "follows.point"))
        ops = self.ops
        if isinstance(ops, (str, bytes)) or not isinstance(ops, Iterable):
            raise ProgramFormatError(f"follows: ops must be a list of op indices, got {ops!r}")
        ops = tuple(ops)
        if not ops or any(isinstance(i, bool) or not isinstance(i, int) or i < 0 for i in ops):
            raise ProgramFormatError(f"follows: ops must be op indices (0 or more), got {list(ops)!r}")
        object.__setattr__(self, "ops", tuple(sorted(set(ops))))

    def to_dict(self) -> dict[str, Any]:
        return {"part": self.part, "point": list(self.point), "ops": list(self.ops)}

    def shifted(self, offset: int) -> Follow:
        return Follow(self.part, self.point, tuple(i + offset for i in self.ops))


@dataclass(frozen=True)
class Program:
    """Ordered edit ops and the parameters their amounts use.

    Programs stack three ways: ``then`` (the second edits the output of the first),
    ``plus`` (layers: each edits the rest shape, their displacements add) and ``atop``
    (an *outer* layer: it runs after the sum, on the shape the other layers made, its ops'
    origins carried along by ``follows``). ``layers`` holds the number of ops in each layer;
    ``()`` is one layer, a plain sequence. ``outer`` lists the outer layers by index: they
    run after every other layer, in their order.
    """

    ops: tuple[EditOp, ...]
    parameters: tuple[Parameter, ...] = (Parameter("x"),)
    metadata: Mapping[str, Any] = field(default_factory=dict, compare=False)
    layers: tuple[int, ...] = ()
    outer: tuple[int, ...] = ()
    follows: tuple[Follow, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "ops", tuple(self.ops))
        object.__setattr__(self, "parameters", tuple(self.parameters))
        layers = self.layers
        if isinstance(layers, (str, bytes)) or not isinstance(layers, Iterable):
            raise ProgramFormatError(f"layers must be a list of op counts, got {layers!r}")
        layers = tuple(layers)
        if any(isinstance(n, bool) or not isinstance(n, int) or n < 1 for n in layers):
            raise ProgramFormatError(f"layers must be positive op counts, got {list(layers)!r}")
        if layers and sum(layers) != len(self.ops):
            raise ProgramFormatError(f"layers {list(layers)!r} count {sum(layers)} ops, the program has "
                                     f"{len(self.ops)}")
        # One layer is a plain sequence, unless it is marked outer (a turn that later layers go beneath).
        object.__setattr__(self, "layers", layers if len(layers) > 1 or (layers and tuple(self.outer) == (0,)) else ())
        self._check_outer()
        names = [p.name for p in self.parameters]
        if len(set(names)) != len(names):
            twice = sorted({n for n in names if names.count(n) > 1})
            raise ProgramFormatError(f"program declares parameter(s) twice: {', '.join(twice)}")
        for i, op in enumerate(self.ops):
            unknown = sorted(op.parameters - set(names))
            if unknown:
                raise ProgramFormatError(f"op {i} ({op.name} on {op.operand!r}): amount {op.amount!r} uses "
                                         f"undeclared parameter(s) {', '.join(unknown)}")

    def _check_outer(self) -> None:
        outer = self.outer
        if isinstance(outer, (str, bytes)) or not isinstance(outer, Iterable):
            raise ProgramFormatError(f"outer must be a list of layer indices, got {outer!r}")
        outer = tuple(outer)
        count = len(self.layers) or 1
        if any(isinstance(i, bool) or not isinstance(i, int) or not 0 <= i < count for i in outer):
            raise ProgramFormatError(f"outer must list layers 0 to {count - 1}, got {list(outer)!r}")
        if outer and not self.layers:
            raise ProgramFormatError("outer layers need a layered program (a plain program is one layer)")
        object.__setattr__(self, "outer", tuple(sorted(set(outer))))
        follows = self.follows
        if isinstance(follows, (str, bytes, Mapping)) or not isinstance(follows, Iterable):
            raise ProgramFormatError(f"follows must be a list, got {follows!r}")
        follows = tuple(f if isinstance(f, Follow) else Follow(**f) if isinstance(f, Mapping) and
                        set(f) == {"part", "point", "ops"} else _bad_follow(f) for f in follows)
        in_outer = {i for k in self.outer for i in range(self.layer_slices[k].start, self.layer_slices[k].stop)}
        seen: set[int] = set()
        for f in follows:
            for i in f.ops:
                if i not in in_outer:
                    raise ProgramFormatError(f"follows: op {i} is not in an outer layer")
                if i in seen:
                    raise ProgramFormatError(f"follows: op {i} follows two points")
                seen.add(i)
        object.__setattr__(self, "follows", follows)

    @property
    def layer_order(self) -> tuple[int, ...]:
        """Layers in the order they run: the summed ones, then the outer ones."""
        count = len(self.layer_slices)
        return tuple(i for i in range(count) if i not in self.outer) + self.outer

    def follow_of(self) -> dict[int, Follow]:
        """Which point each following op travels with, by op index."""
        return {i: f for f in self.follows for i in f.ops}

    def check_numbers(self, source: str = "<program>") -> None:
        """Refuse what a file or a model could slip in: too many ops, coordinates or ranges
        beyond ``max_magnitude``, amounts that are not finite over their parameters' ranges."""
        from parsel_core.config import check_limit, limit
        from parsel_core.expressions import check_finite

        check_limit("max_ops", f"{source}: ops", len(self.ops))
        bound = limit("max_magnitude")
        for p in self.parameters:
            if max(abs(p.lo), abs(p.hi)) > bound:
                raise ProgramFormatError(f"{source}: parameter {p.name!r}: range [{p.lo:g}, {p.hi:g}] is over the "
                                         f"limit max_magnitude = {bound:g} (raise it with PARSEL_MAX_MAGNITUDE)")
        ranges = {p.name: (p.lo, p.hi) for p in self.parameters}
        for f in self.follows:
            if any(not abs(v) <= bound for v in f.point):
                raise ProgramFormatError(f"{source}: follows point {list(f.point)!r} of {f.part!r} is over the limit "
                                         f"max_magnitude = {bound:g} (raise it with PARSEL_MAX_MAGNITUDE)")
        for i, op in enumerate(self.ops):
            where = f"{source}: op {i} ({op.name} on {op.operand!r})"
            for key, value in op.params().items():
                values = value if isinstance(value, tuple) else (value,)
                if any(isinstance(v, (int, float)) and not abs(v) <= bound for v in values):
                    raise ProgramFormatError(f"{where}: {key} {value!r} is over the limit max_magnitude = "
                                             f"{bound:g} (raise it with PARSEL_MAX_MAGNITUDE)")
            check_finite(parse_expression(op.amount), ranges, f"{where}: amount")

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    def parameter(self, name: str) -> Parameter:
        for p in self.parameters:
            if p.name == name:
                return p
        raise ParselError(f"program has no parameter {name!r} (has: {', '.join(self.parameter_names)})")

    def values(self, values: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """Every parameter's value: the given ones (range-checked), defaults for the rest."""
        values = dict(values or {})
        unknown = sorted(set(values) - set(self.parameter_names))
        if unknown:
            raise ParselError(f"program has no parameter(s) {', '.join(unknown)} "
                              f"(has: {', '.join(self.parameter_names)})")
        out = {}
        for p in self.parameters:
            value = values.get(p.name, p.default)
            p.check(value)
            out[p.name] = value
        return out

    @property
    def layer_slices(self) -> tuple[slice, ...]:
        """The ops of each layer as slices of ``ops`` (one slice for a plain program)."""
        sizes = self.layers or (len(self.ops),)
        starts = np.cumsum((0,) + sizes[:-1])
        return tuple(slice(int(start), int(start) + size) for start, size in zip(starts, sizes))

    def layer_programs(self) -> tuple[Program, ...]:
        """Each layer as a program of its own, with the parameters its amounts use."""
        out = []
        for part in self.layer_slices:
            ops = self.ops[part]
            used = set().union(*(op.parameters for op in ops))
            out.append(Program(ops, tuple(p for p in self.parameters if p.name in used), dict(self.metadata)))
        return tuple(out)

    def _merged_parameters(self, other: Program) -> tuple[Parameter, ...]:
        params = {p.name: p for p in self.parameters}
        for p in other.parameters:
            if p.name in params and params[p.name] != p:
                raise ProgramFormatError(f"cannot stack programs: parameter {p.name!r} differs "
                                         f"({params[p.name]} vs {p})")
            params.setdefault(p.name, p)
        return tuple(params.values())

    def then(self, other: Program) -> Program:
        """Stack programs: ``other`` edits the output of this one. Shared parameters must agree.

        Sequential stacking moves parts with origins fixed for the rest shape, so it keeps
        relations only when the second program does not depend on what the first moved;
        programs solved separately on the rest shape compose with :meth:`plus`."""
        if self.layers or other.layers:
            raise ProgramFormatError("cannot stack a layered program with then (layers edit the rest shape); "
                                     "add layers with plus or atop")
        return Program(self.ops + other.ops, self._merged_parameters(other), {**self.metadata, **other.metadata})

    def plus(self, other: Program) -> Program:
        """Superpose programs: ``other``'s layers edit the rest shape too, and their corner
        displacements add to this program's. Shared parameters must agree.

        Every relation is linear in the corners and holds at rest, so displacements that
        each keep a relation keep it when added: at every combination of the parameters."""
        return self._stacked(other, outer=False, follows=())

    def atop(self, other: Program, follows: Iterable[Follow] = ()) -> Program:
        """Add ``other`` as an outer layer: it runs after every summed layer, on the shape they
        made, each op in ``follows`` (indices into ``other``) with its origin carried along.

        For edits that turn parts: a turn summed with a widening shears the part (the
        displacements add, the maps do not compose); on top, the widened part is turned."""
        return self._stacked(other, outer=True, follows=tuple(follows))

    def _stacked(self, other: Program, outer: bool, follows: tuple[Follow, ...]) -> Program:
        mine = self.layers or ((len(self.ops),) if self.ops else ())
        theirs = other.layers or ((len(other.ops),) if other.ops else ())
        params, meta = self._merged_parameters(other), {**self.metadata, **other.metadata}
        count = len(mine)
        other_outer = tuple(i + count for i in other.outer)
        if outer:
            if len(theirs) > 1:
                raise ProgramFormatError("an outer layer is a program of one layer")
            if not theirs:
                return dataclasses.replace(self, parameters=params, metadata=meta)
            other_outer += (count,)
            other_follows = other.follows + follows
        else:
            other_follows = other.follows
        shifted = tuple(f.shifted(len(self.ops)) for f in other_follows)
        return Program(self.ops + other.ops, params, meta, mine + theirs, self.outer + other_outer,
                       self.follows + shifted)

    def with_metadata(self, metadata: Mapping[str, Any]) -> Program:
        """The same program with other metadata."""
        return dataclasses.replace(self, metadata=dict(metadata))

    def with_parameters(self, parameters: Iterable[Parameter]) -> Program:
        """The same ops and layers with other parameter ranges."""
        return dataclasses.replace(self, parameters=tuple(parameters))

    def renamed(self, old: str, new: str) -> Program:
        """The same program with parameter ``old`` called ``new`` (in its amounts too)."""
        import ast
        import copy

        from parsel_core.expressions import parse_expression

        class Rename(ast.NodeTransformer):
            def visit_Name(self, node: ast.Name) -> ast.Name:
                return ast.copy_location(ast.Name(new if node.id == old else node.id, node.ctx), node)

        def rename(text: str) -> str:  # on a copy: parsed trees are cached and shared
            return ast.unparse(Rename().visit(copy.deepcopy(parse_expression(text).tree)))

        ops = tuple(dataclasses.replace(op, amount=rename(op.amount)) if old in op.parameters else op
                    for op in self.ops)
        params = tuple(dataclasses.replace(p, name=new) if p.name == old else p for p in self.parameters)
        return dataclasses.replace(self, ops=ops, parameters=params, metadata=dict(self.metadata))

    def validate(self, shape: ShapeGraph) -> None:
        """Check every operand against the shape; errors name the op and the part."""
        for i, op in enumerate(self.ops):
            where = f"op {i} ({op.name})"
            if op.acts_on == "group":
                if op.operand not in shape.relations:
                    raise UnknownPartError(f"{where}: shape {shape.name!r} has no symmetry group {op.operand!r}")
                if shape.relations[op.operand].kind not in GROUP_KINDS:
                    raise ProgramFormatError(f"{where}: relation {op.operand!r} is a "
                                             f"{shape.relations[op.operand].kind}, not a translation or rotation group")
            else:
                if op.operand not in shape.parts and op.operand not in shape.virtual_parents:
                    raise UnknownPartError(f"{where}: shape {shape.name!r} has no part {op.operand!r}")
                if op.operand in shape.virtual_parents and op.feature is not None:
                    raise ProgramFormatError(f"{where}: feature ops on a group's virtual parent "
                                             f"{op.operand!r} are not supported; edit its members")
        for f in self.follows:
            if f.part not in shape.parts and f.part not in shape.virtual_parents:
                raise UnknownPartError(f"follows: shape {shape.name!r} has no part {f.part!r}")
            for i in f.ops:
                if self.ops[i].acts_on != "part":
                    raise ProgramFormatError(f"follows: op {i} ({self.ops[i].name}) lays out a group; only part "
                                             "ops follow a point")
        modes: dict[str, str] = {}
        for op in self.ops:
            if isinstance(op, GroupOp) and modes.setdefault(op.operand, op.mode) != op.mode:
                raise ProgramFormatError(f"group {op.operand!r} is edited in both top_down and bottom_up mode")

    @property
    def edited_parts(self) -> set[str]:
        return {op.operand for op in self.ops if op.acts_on == "part" and op.name != "keep_fixed"}

    # -- JSON form ---------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        data: dict[str, Any] = {
            "format": PROGRAM_FORMAT,
            "version": PROGRAM_VERSION,
            "parameters": [{"name": p.name, "lo": p.lo, "hi": p.hi, "default": p.default} for p in self.parameters],
            "ops": [op_to_dict(op) for op in self.ops],
        }
        if self.layers:
            data["layers"] = list(self.layers)
        if self.outer:
            data["outer"] = list(self.outer)
        if self.follows:
            data["follows"] = [f.to_dict() for f in self.follows]
        if self.metadata:
            data["metadata"] = dict(self.metadata)
        return data

    def to_json(self) -> str:
        """Deterministic JSON text (sorted metadata keys, shortest round-trip floats)."""
        return json.dumps(self.to_dict(), indent=2, sort_keys=False) + "\n"

    @classmethod
    def from_dict(cls, data: Any, registry: Mapping[str, type[EditOp]] | None = None,
                  source: str = "<program>") -> Program:
        if registry is None:
            from parsel_core.plugins import edit_operators

            registry = edit_operators()
        if not isinstance(data, Mapping):
            raise ProgramFormatError(f"{source}: a program must be a JSON object")
        if data.get("format") != PROGRAM_FORMAT:
            raise ProgramFormatError(f"{source}: not a parsel program (expected \"format\": \"{PROGRAM_FORMAT}\")")
        if type(data.get("version")) is not int or data.get("version") != PROGRAM_VERSION:  # true is not 1
            raise ProgramFormatError(f"{source}: unsupported program version {data.get('version')!r} "
                                     f"(this parsel reads {PROGRAM_VERSION})")
        unknown = sorted(set(data) - {"format", "version", "parameters", "ops", "metadata", "layers", "outer",
                                      "follows"})
        if unknown:
            raise ProgramFormatError(f"{source}: unknown field(s) {', '.join(unknown)}")
        params = []
        if not isinstance(data.get("parameters", []), list):
            raise ProgramFormatError(f"{source}: field 'parameters' must be a list")
        for i, item in enumerate(data.get("parameters", [])):
            if not isinstance(item, Mapping) or set(item) - {"name", "lo", "hi", "default"} or "name" not in item:
                raise ProgramFormatError(f"{source}: parameters[{i}] must be an object with name, lo, hi, default")
            try:
                params.append(Parameter(**item))
            except ProgramFormatError as exc:
                raise ProgramFormatError(f"{source}: parameters[{i}]: {exc}") from None
        ops_data = data.get("ops")
        if not isinstance(ops_data, list):
            raise ProgramFormatError(f"{source}: field 'ops' must be a list")
        from parsel_core.config import check_limit

        check_limit("max_ops", f"{source}: ops", len(ops_data))  # before building any
        ops = [op_from_dict(item, registry, where=f"{source}: ops[{i}]") for i, item in enumerate(ops_data)]
        metadata = data.get("metadata", {})
        if not isinstance(metadata, Mapping):
            raise ProgramFormatError(f"{source}: field 'metadata' must be an object")
        layers = data.get("layers", [])
        if not isinstance(layers, list):
            raise ProgramFormatError(f"{source}: field 'layers' must be a list of op counts")
        outer, follows = data.get("outer", []), data.get("follows", [])
        if not isinstance(outer, list):
            raise ProgramFormatError(f"{source}: field 'outer' must be a list of layer indices")
        if not isinstance(follows, list):
            raise ProgramFormatError(f"{source}: field 'follows' must be a list")
        try:
            program = cls(tuple(ops), tuple(params), dict(metadata), tuple(layers), tuple(outer), tuple(follows))
        except ProgramFormatError as exc:
            raise ProgramFormatError(f"{source}: {exc}") from None
        program.check_numbers(source)
        return program

    @classmethod
    def from_json(cls, text: str, registry: Mapping[str, type[EditOp]] | None = None,
                  source: str = "<program>") -> Program:
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ProgramFormatError(f"{source}: invalid JSON at line {exc.lineno} column {exc.colno}: {exc.msg}") \
                from None
        except (ValueError, RecursionError) as exc:  # a number too long to convert, nesting too deep
            raise ProgramFormatError(f"{source}: not usable JSON: {type(exc).__name__}") from None
        return cls.from_dict(data, registry, source)

    def to_text(self) -> str:
        from parsel_core.textform import program_to_text

        return program_to_text(self)

    @classmethod
    def from_text(cls, text: str, registry: Mapping[str, type[EditOp]] | None = None,
                  source: str = "<program>") -> Program:
        from parsel_core.textform import program_from_text

        return program_from_text(text, registry, source)


@dataclass(frozen=True)
class Evaluation:
    """Corners after a program: ``parts`` (..., 8, 3) for every part and virtual parent,
    ``instances`` (n, 8, 3) for each group whose layout a group op changed (scalar values).

    Members of a laid-out group take their instance's corners, so relations are checked on
    the layout; instances past the old count exist only in ``instances``."""

    parts: dict[str, np.ndarray]
    instances: dict[str, np.ndarray] = field(default_factory=dict)
    #: Members of a group whose count dropped below their index (their corners are NaN).
    removed: frozenset[str] = frozenset()


NUMPY_MATH = SimpleNamespace(sin=np.sin, cos=np.cos, sqrt=np.sqrt)


def top_down_groups(program: Program) -> set[str]:
    """Groups the program lays out top-down: ops on their virtual parent move the anchors only."""
    return _top_down(program.ops)


def _top_down(ops: Sequence[EditOp]) -> set[str]:
    return {op.operand for op in ops if isinstance(op, GroupOp) and op.mode == "top_down"}


def anchor_groups(program: Program) -> list[set[str]]:
    """For each op, the groups whose virtual parent carries only layout anchors there: those its
    own layer lays out top-down. A layer moves a group's members with their parent when it does
    not lay the group out itself, as it did when it was solved alone."""
    out: list[set[str]] = []
    for part in program.layer_slices:
        groups = _top_down(program.ops[part])
        out.extend(groups for _ in program.ops[part])
    return out


def laid_out_groups(program: Program) -> set[str]:
    """Groups whose instances a group op re-lays out."""
    return {op.operand for op in program.ops if isinstance(op, GroupOp)}


def op_targets(op: EditOp, shape: ShapeGraph, anchors_only: Iterable[str] = ()) -> list[str]:
    """The parts a part op moves: its operand and, for a group's virtual parent, every
    member too (unless the group is laid out top-down, in ``anchors_only``)."""
    if op.operand in shape.virtual_parents and op.operand not in anchors_only:
        return [op.operand, *shape.relations[op.operand].members]
    return [op.operand]


def _run_part_ops(ops: Sequence[EditOp], shape: ShapeGraph, corners: dict[str, Any], amounts: Sequence[Any],
                  math_ns: Any, anchors_only: set[str], shifts: Sequence[Any] | None = None) -> dict[str, Any]:
    for k, (op, amount) in enumerate(zip(ops, amounts)):
        if op.acts_on != "part":
            continue
        shift = shifts[k] if shifts is not None else None
        for target in op_targets(op, shape, anchors_only):
            if target not in corners:  # a part the caller left out (symbolic_corners' ``only``)
                continue
            if shift is None:
                corners[target] = op.apply(corners[target], amount, math_ns)
            else:  # the op with its points carried by the shift (Follow): p -> op(p - d) + d
                corners[target] = op.apply(corners[target] - shift, amount, math_ns) + shift
    return corners


def follow_weights(shape: ShapeGraph, follow: Follow) -> np.ndarray:
    """The cage coordinates (8,) of a Follow's point in its part at rest."""
    from parsel_core.cage import point_weights

    return point_weights(shape.rest_corners()[follow.part], np.asarray([follow.point], dtype=float))[0]


def _displacement(weights: np.ndarray, corners: Any, point: tuple[float, float, float]) -> Any:
    """Where the point with cage coordinates ``weights`` moved in ``corners`` (..., 8, 3): (..., 1, 3)."""
    moved = (np.asarray(weights)[:, None] * corners).sum(axis=-2)
    return (moved - np.asarray(point, dtype=float))[..., None, :]


def _apply_part_ops(program: Program, shape: ShapeGraph, corners: dict[str, Any], amounts: Sequence[Any],
                    math_ns: Any) -> dict[str, Any]:
    """Run the part ops in order. An op on a virtual parent moves the parent and, with the
    same point map, every member (affine ops map contained boxes exactly) — unless the group
    is laid out top-down, where the parent only carries the anchors of the layout.

    In a layered program each layer runs on the rest ``corners`` and the result is the
    rest corners plus every layer's displacement (a part no layer moves keeps its array).
    Outer layers then run in turn on that sum, their following ops conjugated by how far
    the layers before them moved the followed point (:class:`Follow`)."""
    slices = program.layer_slices
    if len(slices) == 1:
        return _run_part_ops(program.ops, shape, corners, amounts, math_ns, top_down_groups(program))
    rest = dict(corners)
    total = dict(corners)
    outer = set(program.outer)
    for i, part in enumerate(slices):
        if i in outer:
            continue
        ops = program.ops[part]
        layer = _run_part_ops(ops, shape, dict(rest), amounts[part], math_ns, _top_down(ops))
        for pid, moved in layer.items():
            if moved is not rest[pid]:
                total[pid] = total[pid] + (moved - rest[pid])
    follow_of = program.follow_of()
    for i in program.outer:
        part = slices[i]
        shifts_of = {f: _displacement(follow_weights(shape, f), total[f.part], f.point)
                     for f in {follow_of[k] for k in range(part.start, part.stop) if k in follow_of}}
        shifts = [shifts_of[follow_of[k]] if k in follow_of else None for k in range(part.start, part.stop)]
        ops = program.ops[part]
        total = _run_part_ops(ops, shape, total, amounts[part], math_ns, _top_down(ops), shifts)
    return total


def _group_rest_layout(shape: ShapeGraph, rest: Mapping[str, np.ndarray], group_id: str, first: GroupOp
                       ) -> RestLayout:
    """The :func:`~parsel_core.layout.rest_layout` of ``group_id``, in the mode of its first group op."""
    relation = shape.relations[group_id]
    return rest_layout(relation, rest[group_id], [rest[m] for m in relation.members], first.mode == "top_down")


def rest_layouts(program: Program, shape: ShapeGraph) -> dict[str, RestLayout]:
    """The rest layout of every group a group op of ``program`` lays out."""
    rest = shape.rest_corners()
    first: dict[str, GroupOp] = {}
    for op in program.ops:
        if isinstance(op, GroupOp):
            first.setdefault(op.operand, op)
    return {group_id: _group_rest_layout(shape, rest, group_id, op) for group_id, op in first.items()}


def _lay_out(program: Program, shape: ShapeGraph, corners: dict[str, np.ndarray], amounts: Sequence[Any],
             batch: tuple[int, ...], layouts: Mapping[str, RestLayout] | None = None,
             max_count: float | None = None) -> tuple[dict[str, np.ndarray], frozenset[str]]:
    """Apply group layouts: member j takes instance j's corners; members past the new count
    are *removed* (their corners become NaN). Returns scalar-evaluation instances too.
    ``layouts``: :func:`rest_layouts` of the program, when already made; ``max_count``: the
    ``max_instances`` limit, when already read (else read here, once for every sample)."""
    from parsel_core.config import limit

    per_group: dict[str, list[tuple[GroupOp, Any]]] = {}
    for op, amount in zip(program.ops, amounts):
        if isinstance(op, GroupOp):
            per_group.setdefault(op.operand, []).append((op, amount))
    instances: dict[str, np.ndarray] = {}
    removed: set[str] = set()
    if not per_group:
        return instances, frozenset(removed)
    rest = shape.rest_corners()
    if max_count is None:
        max_count = limit("max_instances")
    for group_id, ops in per_group.items():
        relation = shape.relations[group_id]
        members = relation.members
        rest_members = [rest[m] for m in members]
        layout = layouts[group_id] if layouts is not None else _group_rest_layout(shape, rest, group_id, ops[0][0])
        for m in members:
            c = corners[m]
            corners[m] = np.array(c if np.shape(c) == batch + (8, 3) else np.broadcast_to(c, batch + (8, 3)),
                                  dtype=float)
        for index in np.ndindex(*batch) if batch else [()]:
            sample_ops = [(op, float(np.asarray(amount)[index] if batch else amount)) for op, amount in ops]
            laid = group_instances(relation, rest[group_id], rest_members, np.asarray(corners[group_id])[index],
                                   [corners[m][index] for m in members], sample_ops, layout, max_count)
            for j, m in enumerate(members):
                if j < len(laid):
                    corners[m][index] = laid[j]
                else:
                    corners[m][index] = np.nan
                    removed.add(m)
            if not batch:
                instances[group_id] = laid
    return instances, frozenset(removed)


def op_amounts(program: Program, values: Mapping[str, Any]) -> list[np.ndarray]:
    """Each op's amount at the parameter ``values`` (scalars or equal-shaped arrays), as
    arrays of their common shape."""
    batch, arrays = _amount_arrays(values)
    functions = numpy_functions()
    return [_amount(op, arrays, batch, functions) for op in program.ops]


def op_amount(op: EditOp, values: Mapping[str, Any]) -> np.ndarray:
    """One op's amount at the parameter ``values``, as :func:`op_amounts` makes it."""
    batch, arrays = _amount_arrays(values)
    return _amount(op, arrays, batch, numpy_functions())


def _amount_arrays(values: Mapping[str, Any]) -> tuple[tuple[int, ...], dict[str, np.ndarray]]:
    batch = np.broadcast_shapes(*(np.shape(v) for v in values.values())) if values else ()
    return batch, {k: np.broadcast_to(np.asarray(v, dtype=float), batch) for k, v in values.items()}


def _amount(op: EditOp, arrays: Mapping[str, np.ndarray], batch: tuple[int, ...], functions) -> np.ndarray:
    return np.broadcast_to(np.asarray(parse_expression(op.amount).build(arrays, functions), dtype=float), batch)


def evaluate(program: Program, shape: ShapeGraph, values: Mapping[str, Any] | None = None) -> Evaluation:
    """Reference numeric evaluation with numpy.

    Parameter values may be scalars or equal-shaped arrays (a batch of slider positions);
    corners then get the batch shape in front. Group instances are laid out for scalar
    values only (their count can differ between samples).
    """
    program.validate(shape)
    values = program.values(values)
    batch = np.broadcast_shapes(*(np.shape(v) for v in values.values())) if values else ()
    amounts = [amount[..., None, None] if batch else float(amount) for amount in op_amounts(program, values)]
    corners = {pid: np.broadcast_to(c, batch + (8, 3)).copy() for pid, c in shape.rest_corners().items()}
    corners = _apply_part_ops(program, shape, corners, amounts, NUMPY_MATH)
    group_amounts = [a[..., 0, 0] if batch else a for a in amounts]
    instances, removed = _lay_out(program, shape, corners, group_amounts, batch)
    return Evaluation(corners, instances, removed)


def symbolic_amounts(program: Program, backend: CASBackend) -> list[Any]:
    """Each op's amount as a backend expression."""
    return [backend.parse(op.amount) for op in program.ops]


def symbolic_corners(program: Program, shape: ShapeGraph, backend: CASBackend,
                     only: Iterable[str] | None = None) -> dict[str, np.ndarray]:
    """Corners as (8, 3) object arrays of expressions in the control parameters.

    Parts no op touches keep their float corners. ``only`` limits the work to the
    parts a caller needs (relations of a few parts, say): the ops of the others are not
    applied (a part's corners depend only on the ops on it, on its group and, in a layered
    program, on the parts its ops follow).
    """
    program.validate(shape)
    rest = shape.rest_corners()
    wanted = set(rest) if only is None else set(only)
    touched = {target for op in program.ops if op.acts_on == "part" for target in op_targets(op, shape)}
    # Touched parts start as CAS numbers so every corner entry is an expression.
    followed = {f.part for f in program.follows}
    corners: dict[str, Any] = {pid: backend.corners(rest[pid]) if pid in touched else rest[pid]
                               for pid in rest if pid in wanted or pid in followed}
    corners = _apply_part_ops(program, shape, corners, symbolic_amounts(program, backend), opmath)
    return {pid: c for pid, c in corners.items() if pid in wanted}


class CompiledProgram:
    """A program lambdified once for one shape; calling it is a slider step.

    The symbolic corners of the edited parts are compiled into a single numpy function
    of the parameters; untouched parts are constants. Group layouts are computed from
    the compiled corners and the compiled group amounts.
    """

    def __init__(self, program: Program, shape: ShapeGraph, backend: CASBackend) -> None:
        from parsel_core.config import limit

        self.program = program
        self.shape = shape
        self.backend = backend
        self.rest = shape.rest_corners()
        symbolic = symbolic_corners(program, shape, backend)
        self.edited = [pid for pid, c in symbolic.items() if np.asarray(c).dtype == object]
        exprs = [e for pid in self.edited for e in symbolic[pid].ravel()]
        group_amounts = [backend.parse(op.amount) for op in program.ops if isinstance(op, GroupOp)]
        self._group_ops = [op for op in program.ops if isinstance(op, GroupOp)]
        self._layouts = rest_layouts(program, shape)
        #: The ``max_instances`` limit as it was at compile time (with a parsel.toml, each
        #: read parses the file: too slow for a slider step).
        self._max_instances = limit("max_instances") if self._group_ops else None
        self._function = backend.compile(program.parameter_names, exprs + group_amounts) if exprs or group_amounts \
            else None
        self._n_corner_values = len(exprs)

    def __call__(self, values: Mapping[str, Any] | None = None) -> Evaluation:
        values = self.program.values(values)
        batch = np.broadcast_shapes(*(np.shape(v) for v in values.values())) if values else ()
        # (the rest corners are read-only arrays: one slider position takes them as they are)
        corners: dict[str, np.ndarray] = dict(self.rest) if not batch else \
            {pid: np.broadcast_to(c, batch + (8, 3)) for pid, c in self.rest.items()}
        instances: dict[str, np.ndarray] = {}
        removed: frozenset[str] = frozenset()
        if self._function is not None:
            args = [np.broadcast_to(np.asarray(values[n], dtype=float), batch) for n in self.program.parameter_names]
            out = np.asarray(self._function(*args), dtype=float)
            out = np.broadcast_to(out, (out.shape[0],) + batch)
            flat = np.moveaxis(out[: self._n_corner_values], 0, -1)
            for i, pid in enumerate(self.edited):
                corners[pid] = flat[..., i * 24:(i + 1) * 24].reshape(batch + (8, 3))
            if self._group_ops:
                amounts: list[Any] = [None] * len(self.program.ops)
                group_values = iter(out[self._n_corner_values:])
                for i, op in enumerate(self.program.ops):
                    if isinstance(op, GroupOp):
                        amounts[i] = next(group_values)
                instances, removed = _lay_out(self.program, self.shape, corners, amounts, batch, self._layouts,
                                              self._max_instances)
        return Evaluation(dict(corners), instances, removed)


def compile_program(program: Program, shape: ShapeGraph, backend: CASBackend) -> CompiledProgram:
    """Validate and lambdify ``program`` for ``shape`` with ``backend``."""
    program.validate(shape)
    return CompiledProgram(program, shape, backend)


def evaluator(program: Program, shape: ShapeGraph, backend: str | None = None
              ) -> Callable[[Mapping[str, Any] | None], Evaluation]:
    """The numeric evaluation of ``program`` on ``shape``: the numpy reference (:func:`evaluate`)
    without ``backend``, else the program compiled by that CAS backend (the slider page's
    path), so that ``check``, ``apply`` and ``render`` can show what a backend computes."""
    if backend is None:
        return lambda values=None: evaluate(program, shape, values)
    from parsel_core.plugins import get_cas_backend

    return compile_program(program, shape, get_cas_backend(backend))
