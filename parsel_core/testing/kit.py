"""The checks of the conformance kit, one :class:`Check` per hook contribution and property.

Each check raises ``AssertionError`` with a message that names the plugin and the
contribution at fault, or :class:`NotApplicable` when there is nothing to check (an
operator the slider page cannot draw has no JavaScript form to compare). The checks
use only the core (the built-in ``tiny_table`` and a lone box), so a plugin package
needs nothing else to run them.
"""

from __future__ import annotations

import argparse
import builtins
import dataclasses
import inspect
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from parsel_core.errors import ParselError

#: Slider values every operator is checked at (batched and one by one).
AMOUNTS = (0.0, 0.35, -0.2, 0.8)
#: How far the numeric and symbolic paths may differ (corners are O(1)).
ATOL = 1e-9
#: A mirror plane in general position: no axis-aligned coincidences to hide a wrong sign.
MIRROR_ORIGIN = (0.1, 0.2, -0.3)
MIRROR_NORMAL = tuple(np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5]))


class NotApplicable(Exception):
    """The check has nothing to check for this contribution (reported as a skip)."""


@dataclass(frozen=True)
class Check:
    """One check: a readable id (``plugin: what``) and the function that runs it."""

    id: str
    run: Callable[[], None]


def _box_shape():
    from parsel_core.graph import ShapeGraph
    from parsel_core.hexahedron import Hexahedron
    from parsel_core.part import Part

    return ShapeGraph([Part("box", "box", Hexahedron.from_bounds((-0.4, 0.1, -0.3), (0.6, 1.2, 0.5)))], name="box")


def _require(ok: object, message: str) -> None:
    """``assert`` that keeps its message one line (pytest rewrites asserts and appends the expression)."""
    if not ok:
        raise AssertionError(message)


def _one_line(message: str, what: str) -> None:
    _require(message and "\n" not in message.strip(), f"{what}: the error is not one line: {message!r}")


# -- edit operators ---------------------------------------------------------------------------

def _operator_checks(plugin: str, cls: Any) -> list[Check]:
    from parsel_core.ops import EditOp

    name = getattr(cls, "name", "") or repr(cls)
    where = f"{plugin}: operator {name!r}"

    def is_operator() -> None:
        _require(isinstance(cls, type) and issubclass(cls, EditOp), f"{where} is not an EditOp subclass")
        _require(isinstance(cls.name, str) and cls.name.isidentifier(),
                 f"{where}: name must be an identifier (its name in programs)")
        _require(dataclasses.is_dataclass(cls) and cls.__dataclass_params__.frozen,
                 f"{where}: must be a frozen dataclass (ops are values)")
        _require(cls.acts_on in ("part", "group"), f"{where}: acts_on must be 'part' or 'group'")
        cls("box")  # defaults for every field but the operand

    checks = [Check(f"{where} is a frozen EditOp dataclass", is_operator)]
    if not (isinstance(cls, type) and issubclass(cls, EditOp)):
        return checks
    checks += [
        Check(f"{where} round-trips through JSON and text", lambda: _round_trip(where, cls)),
        Check(f"{where} gives one-line errors naming the op", lambda: _validation(where, cls)),
    ]
    if cls.acts_on == "part":
        checks += [
            Check(f"{where}: batched numeric path = per-sample", lambda: _batched(where, cls)),
            Check(f"{where}: symbolic path = numeric path", lambda: _symbolic(where, cls)),
            Check(f"{where}: mirrors under reflection", lambda: _mirror(where, cls)),
            Check(f"{where}: JavaScript form = numeric path", lambda: _javascript(where, cls)),
        ]
    return checks


def _program(cls: Any, feature: str | None = None, amount: str = "x"):
    from parsel_core.program import Parameter, Program

    return Program((cls("box", amount=amount, feature=feature),), (Parameter("x", -1.0, 1.0, 0.0),))


def _round_trip(where: str, cls: Any) -> None:
    from parsel_core.program import Program

    program = _program(cls) if cls.acts_on == "part" else _program(cls, amount="x")
    _require(Program.from_json(program.to_json()) == program, f"{where}: JSON form does not read back the same op")
    _require(Program.from_text(program.to_text()) == program, f"{where}: text form does not read back the same op")


def _validation(where: str, cls: Any) -> None:
    from parsel_core.ops import op_from_dict
    from parsel_core.plugins import edit_operators

    registry = edit_operators()
    _require(registry.get(cls.name) is cls, f"{where}: not registered under its name (another plugin replaces it?)")
    bad_fields = {**{f: "abc" for f in cls.point_fields}, **{f: [0, 0, 0] for f in cls.unit_fields}}
    for field_name, value in bad_fields.items():
        try:
            op_from_dict({"op": cls.name, "operand": "box", field_name: value}, registry, where="op 0")
        except ParselError as exc:
            _one_line(str(exc), where)
            _require(field_name in str(exc), f"{where}: the error for a bad {field_name!r} does not name it: {exc}")
        else:
            raise AssertionError(f"{where}: a bad {field_name!r} ({value!r}) was accepted")
    program = _program(cls)
    program = type(program)((dataclasses.replace(program.ops[0], operand="no_such_part"),), program.parameters)
    try:
        program.validate(_box_shape())
    except ParselError as exc:
        _one_line(str(exc), where)
        _require("no_such_part" in str(exc), f"{where}: the error for an unknown operand does not name it: {exc}")
    else:
        raise AssertionError(f"{where}: an op on an unknown part validated")


def _variants(cls: Any) -> Iterator[tuple[str, Any]]:
    yield "whole part", _program(cls)
    yield "face v+", _program(cls, feature="v+")
    yield "amount x*x - x", _program(cls, amount="x*x - x")


def _agrees_with_numeric(where: str, cls: Any, path: str, other: Callable[[Any, Any, np.ndarray], Any]) -> None:
    """Compare another evaluation path with the batched numeric one on every variant of the op.

    ``other(program, shape, xs)`` returns the corners ``(len(xs), 8, 3)`` of the path under
    test; the error names the variant, the path, the slider value and the corner.
    """
    from parsel_core.program import evaluate

    shape = _box_shape()
    xs = np.array(AMOUNTS)
    for label, program in _variants(cls):
        numeric = evaluate(program, shape, {"x": xs}).parts["box"]
        _require(numeric.shape == (len(xs), 8, 3), f"{where} ({label}): batched corners have shape {numeric.shape}")
        try:
            got = np.asarray(other(program, shape, xs), dtype=float)
        except Exception as exc:
            raise AssertionError(f"{where} ({label}): {path} fails: {type(exc).__name__}: {exc}") from None
        error = np.abs(got - numeric)
        if float(error.max()) > ATOL:
            i, k, _ = np.unravel_index(int(np.argmax(error)), error.shape)
            raise AssertionError(f"{where} ({label}): {path} and the numeric path disagree by "
                                 f"{float(error.max()):.3g} at x = {AMOUNTS[i]} (corner {k})")


def _batched(where: str, cls: Any) -> None:
    from parsel_core.program import evaluate

    def one_by_one(program: Any, shape: Any, xs: np.ndarray) -> np.ndarray:
        return np.stack([evaluate(program, shape, {"x": float(x)}).parts["box"] for x in xs])

    _agrees_with_numeric(where, cls, "the per-sample evaluation", one_by_one)
    moved = evaluate(_program(cls), _box_shape(), {"x": np.array(AMOUNTS)}).parts["box"]
    _require(np.all(np.isfinite(moved)), f"{where}: non-finite corners for x in {AMOUNTS}")


def _symbolic(where: str, cls: Any) -> None:
    from parsel_core.plugins import cas_backend_names, get_cas_backend
    from parsel_core.program import compile_program

    names = cas_backend_names()
    _require(names, f"{where}: no CAS backend is installed to check the symbolic path")
    for backend_name in names:
        backend = get_cas_backend(backend_name)
        _agrees_with_numeric(where, cls, f"the symbolic path ({backend_name})",
                             lambda program, shape, xs, b=backend: compile_program(program, shape, b)(
                                 {"x": xs}).parts["box"])


def _reflect(points: np.ndarray) -> np.ndarray:
    o, n = np.asarray(MIRROR_ORIGIN), np.asarray(MIRROR_NORMAL)
    return points - 2.0 * ((points - o) @ n)[..., None] * n


def _mirror(where: str, cls: Any) -> None:
    from parsel_core.expressions import numpy_functions, parse_expression
    from parsel_core.program import NUMPY_MATH

    op = cls("box")
    mirrored = op.mirrored(MIRROR_ORIGIN, MIRROR_NORMAL, "box")
    points = _box_shape().rest_corners()["box"]
    for x in AMOUNTS:
        amount = float(parse_expression(op.amount).build({"x": x}, numpy_functions()))
        mirrored_amount = float(parse_expression(mirrored.amount).build({"x": x}, numpy_functions()))
        expected = _reflect(op.transform(points, amount, NUMPY_MATH))
        got = mirrored.transform(_reflect(points), mirrored_amount, NUMPY_MATH)
        error = float(np.max(np.abs(np.asarray(got, dtype=float) - expected)))
        _require(error <= ATOL, f"{where}: the mirrored op does not map the mirror image of the box to the mirror "
                               f"image of the edited box (off by {error:.3g} at x = {x}); override mirrored()")


def _javascript(where: str, cls: Any) -> None:
    try:
        from parsel_view.opjs import NoJavaScriptForm, evaluate_point_map, point_map_js
        from parsel_view.scene import js_class
    except ImportError:
        raise NotApplicable("parsel-view is not installed") from None
    from parsel_core.program import NUMPY_MATH

    op = cls("box")
    if js_class(op) is not None:
        raise NotApplicable("the page implements this op by hand")
    try:
        text = point_map_js(op)
    except NoJavaScriptForm as exc:
        raise NotApplicable(f"no JavaScript form: {exc}") from None
    points = np.array([[0.3, -0.2, 0.9], [1.1, 0.5, -0.4], [0.0, 0.0, 0.0], [-0.7, 2.0, 0.25]])
    for x in AMOUNTS:
        expected = np.asarray(op.transform(points, x, NUMPY_MATH), dtype=float)
        got = np.array([evaluate_point_map(text, p, x) for p in points])
        error = float(np.max(np.abs(got - expected)))
        _require(error <= ATOL, f"{where}: the JavaScript point map differs from transform by {error:.3g} at x = {x}")


# -- the other hooks ---------------------------------------------------------------------------

def _instance(item: Any) -> Any:
    return item() if isinstance(item, type) else item


def _named(where: str, item: Any, base: type) -> Any:
    obj = _instance(item)
    _require(isinstance(obj, base), f"{where}: {item!r} is not a {base.__module__}.{base.__name__}")
    _require(isinstance(getattr(obj, "name", None), str) and obj.name, f"{where}: {item!r} has no name")
    return obj


def _backend_checks(plugin: str, item: Any) -> list[Check]:
    from parsel_core.cas import CASBackend, check_backend

    where = f"{plugin}: CAS backend {getattr(item, 'name', item)!r}"

    def run() -> None:
        _require(isinstance(item, type) and issubclass(item, CASBackend), f"{where}: must be a CASBackend subclass")
        try:
            check_backend(item())
        except Exception as exc:
            raise AssertionError(f"{where}: fails the backend self-check: {exc}") from None

    return [Check(f"{where} passes the backend self-check", run)]


def _loader_checks(plugin: str, item: Any) -> list[Check]:
    from parsel_core.interfaces import ShapeLoader

    where = f"{plugin}: shape loader {getattr(item, 'name', item)!r}"

    def run() -> None:
        loader = _named(where, item, ShapeLoader)
        _require(all(isinstance(e, str) and e.startswith(".") and e == e.lower() for e in loader.extensions),
                 f"{where}: extensions must be lower-case suffixes like '.glb'")
        with tempfile.TemporaryDirectory() as folder:
            bad = []
            for ext in loader.extensions:
                for label, content in (("garbage", b"\x00\x01 not a shape \xff"), ("empty", b"")):
                    path = Path(folder) / f"bad_{label}{ext}"
                    path.write_bytes(content)
                    bad.append((f"a {label} {ext} file", path))
            directory = Path(folder) / "bad_folder"
            directory.mkdir()
            (directory / "notes.txt").write_text("not a shape\n", encoding="utf-8")
            bad.append(("a folder of no shape", directory))
            for label, path in bad:
                if not loader.can_load(path):
                    continue
                try:
                    loader.load(path)
                except ParselError as exc:
                    _one_line(str(exc), where)
                    _require(path.name in str(exc), f"{where}: the error for {label} does not name it: {exc}")
                except Exception as exc:
                    raise AssertionError(f"{where}: {label} raises {type(exc).__name__}: {exc}, not a ParselError "
                                         f"naming it") from None
                else:
                    raise AssertionError(f"{where}: {label} ({path.name}) loaded without an error")

    return [Check(f"{where} refuses bad files with a ParselError naming them", run)]


def _detector_checks(plugin: str, item: Any) -> list[Check]:
    from parsel_core.examples import tiny_table
    from parsel_core.interfaces import RelationDetector
    from parsel_core.relations import Relation

    where = f"{plugin}: relation detector {getattr(item, 'name', item)!r}"

    def run() -> None:
        detector = _named(where, item, RelationDetector)
        shape = tiny_table()
        found = detector.detect(shape, 0.01 * shape.size)
        _require(isinstance(found, list), f"{where}: detect returned {type(found).__name__}, not a list")
        for relation in found:
            _require(isinstance(relation, Relation), f"{where}: detect returned {relation!r}, not a Relation")
            unknown = [m for m in relation.members if m not in shape.parts and m not in shape.virtual_parents]
            _require(not unknown, f"{where}: relation {relation.id!r} names unknown parts {unknown}")

    return [Check(f"{where} returns relations between the shape's parts", run)]


def _provider_checks(plugin: str, item: Any) -> list[Check]:
    where = f"{plugin}: LLM provider {getattr(item, 'name', item)!r}"

    def run() -> None:
        provider = _instance(item)
        _require(isinstance(getattr(provider, "name", None), str) and provider.name, f"{where}: has no name")
        complete = getattr(provider, "complete", None)
        _require(callable(complete), f"{where}: has no complete()")
        parameters = inspect.signature(complete).parameters
        takes_options = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters.values())
        for needed in ("prompt", "task", "samples"):
                _require(needed in parameters or (needed != "prompt" and takes_options),
                     f"{where}: complete() must take {needed!r} (complete(prompt, *, task, samples=1, **options))")
        _require(takes_options, f"{where}: complete() must accept **options (key=, sample=, api_base= ...)")

    return [Check(f"{where} has the complete() interface", run)]


def _deformer_checks(plugin: str, item: Any) -> list[Check]:
    from parsel_core.examples import tiny_table
    from parsel_core.interfaces import Deformer
    from parsel_core.loading import load_shape
    from parsel_core.plugins import example_shapes
    from parsel_core.program import Program, evaluate

    where = f"{plugin}: deformer {getattr(item, 'name', item)!r}"

    def run() -> None:
        deformer = _named(where, item, Deformer)
        shapes = [tiny_table()] + ([load_shape("chair")] if "chair" in example_shapes() else [])
        deformed = 0
        for shape in shapes:
            part = next(iter(shape.parts))
            program = Program.from_text(f"param x in [0, 1]\ntranslate({part!r}, dir=(0, 1, 0), amount=x)")
            try:
                out = deformer.deform(shape, evaluate(program, shape, {"x": 0.5}))
            except ParselError as exc:  # a shape it cannot deform (no meshes) must be said in one line
                _one_line(str(exc), where)
                continue
            _require(isinstance(out, Mapping), f"{where}: deform returned {type(out).__name__}, not a mapping")
            _require(all(isinstance(k, str) for k in out), f"{where}: deform returned keys that are not names")
            deformed += 1
        if not deformed:
            raise NotApplicable("no installed example shape is one this deformer can deform")

    return [Check(f"{where} returns a mapping of deformed meshes or a one-line error", run)]


@contextmanager
def _direct_writes(target: Path) -> Iterator[list[str]]:
    """Record opens of ``target`` for writing (an atomic exporter writes a temporary file instead)."""
    seen: list[str] = []
    original = builtins.open

    def watching(file, mode="r", *args, **kwargs):
        if isinstance(file, (str, Path)) and Path(file).resolve() == target.resolve() and set(mode) & set("wax+"):
            seen.append(mode)
        return original(file, mode, *args, **kwargs)

    builtins.open = watching
    try:
        yield seen
    finally:
        builtins.open = original


def _exporter_checks(plugin: str, item: Any) -> list[Check]:
    from parsel_core.examples import tiny_table
    from parsel_core.interfaces import Exporter
    from parsel_core.program import Program, evaluate

    where = f"{plugin}: exporter {getattr(item, 'name', item)!r}"

    def run() -> None:
        exporter = _named(where, item, Exporter)
        _require(exporter.extensions and all(e.startswith(".") and e == e.lower() for e in exporter.extensions),
                 f"{where}: extensions must be lower-case suffixes like '.obj'")
        shape = tiny_table()
        if not getattr(exporter, "can_export", lambda s: True)(shape):
            from parsel_core.loading import load_shape
            from parsel_core.plugins import example_shapes

            if "chair" not in example_shapes():
                raise NotApplicable("the exporter needs meshes and no example shape with meshes is installed")
            shape = load_shape("chair")
        part = next(iter(shape.parts))
        program = Program.from_text(f"param x in [0, 1]\ntranslate({part!r}, dir=(0, 1, 0), amount=x)")
        evaluation = evaluate(program, shape, {"x": 0.5})
        with tempfile.TemporaryDirectory() as folder:
            for ext in exporter.extensions:
                target = Path(folder) / f"edited{ext}"
                target.write_bytes(b"previous")
                with _direct_writes(target) as direct:
                    exporter.export(shape, evaluation, target)
                _require(not direct, f"{where}: writes straight into {target.name} (mode {direct[:1]}); write a "
                                     f"temporary file and rename it (parsel_core.io.atomic_write_bytes)")
                _require(target.stat().st_size > 0 and target.read_bytes() != b"previous",
                         f"{where}: {target.name} was not written")
                missing = Path(folder) / "missing" / f"edited{ext}"
                try:
                    exporter.export(shape, evaluation, missing)
                except ParselError as exc:
                    _one_line(str(exc), where)
                except Exception as exc:
                    raise AssertionError(f"{where}: writing into a missing folder raises {type(exc).__name__}, "
                                         f"not a ParselError") from None
                else:
                    raise AssertionError(f"{where}: writing into a missing folder did not fail")
            leftovers = sorted(p.name for p in Path(folder).iterdir() if not p.name.startswith("edited"))
            _require(not leftovers, f"{where}: left temporary files behind: {leftovers}")

    return [Check(f"{where} writes atomically and fails with a ParselError", run)]


def _solver_checks(plugin: str, item: Any) -> list[Check]:
    from parsel_core.examples import tiny_table
    from parsel_core.interfaces import Solver, SolveRequest, SolveResult
    from parsel_core.program import Program

    where = f"{plugin}: solver {getattr(item, 'name', item)!r}"
    seed_text = "scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)"

    def run() -> None:
        solver = _named(where, item, Solver)
        shape = tiny_table()
        seed = Program.from_text(seed_text)
        result = solver.run(SolveRequest(shape, seed, {}, (), {}))
        _require(isinstance(result, SolveResult), f"{where}: run returned {type(result).__name__}, not a SolveResult")
        _require(isinstance(result.program, Program), f"{where}: the result's program is not a Program")
        result.program.validate(shape)
        _require(seed.ops[0] in result.program.ops, f"{where}: the program does not contain the seed edit")
        bad = Program.from_text(seed_text.replace("top", "no_such_part"))
        try:
            solver.run(SolveRequest(shape, bad, {}, (), {}))
        except ParselError as exc:
            _one_line(str(exc), where)
            _require("no_such_part" in str(exc), f"{where}: the error for an unknown part does not name it: {exc}")
        except Exception as exc:
            raise AssertionError(f"{where}: a seed on an unknown part raises {type(exc).__name__}, not a "
                                 f"ParselError") from None
        else:
            raise AssertionError(f"{where}: a seed on an unknown part was solved")

    return [Check(f"{where} keeps the seed edit and refuses bad seeds", run)]


def _examples_checks(plugin: str, result: Any) -> list[Check]:
    from parsel_core.graph import ShapeGraph

    where = f"{plugin}: example shapes"

    def run() -> None:
        _require(isinstance(result, dict), f"{where}: the hook must return a dict, got {type(result).__name__}")
        for name, value in result.items():
            _require(isinstance(name, str) and name, f"{where}: bad name {name!r}")
            if isinstance(value, (str, Path)):
                _require(Path(value).exists(), f"{where}: {name!r} points to a missing file {value}")
            else:
                _require(callable(value), f"{where}: {name!r} is neither a path nor a callable")
                _require(isinstance(value(), ShapeGraph), f"{where}: {name!r} does not give a ShapeGraph")

    return [Check(f"{where} are shapes", run)]


def _templates_checks(plugin: str, result: Any) -> list[Check]:
    where = f"{plugin}: prompt templates"

    def run() -> None:
        _require(isinstance(result, dict), f"{where}: the hook must return a dict, got {type(result).__name__}")
        for name, value in result.items():
            _require(isinstance(name, str) and name, f"{where}: bad name {name!r}")
            if isinstance(value, Path):
                _require(value.is_file(), f"{where}: {name!r} points to a missing file {value}")
            else:
                _require(isinstance(value, str) and value.strip(), f"{where}: {name!r} is not text or a Path")

    return [Check(f"{where} are text", run)]


def _commands_checks(plugin: str, impl: Callable[..., Any]) -> list[Check]:
    where = f"{plugin}: commands"

    def run() -> None:
        parser = argparse.ArgumentParser(prog="parsel")
        sub = parser.add_subparsers(dest="command")
        impl(subparsers=sub)
        added = getattr(sub, "choices", {})
        _require(added, f"{where}: parsel_register_commands added no command")
        for name, command in added.items():
            func = command.get_default("func")
            _require(callable(func), f"{where}: {name!r} sets no func default (a callable returning an exit status)")

    return [Check(f"{where} set a func", run)]


def _no_network_at_import(plugin: str, module: str) -> Check:
    where = f"{plugin}: import"
    script = (
        "import socket, sys\n"
        "def refuse(*a, **k):\n"
        "    raise SystemExit('NETWORK: a connection was attempted at import')\n"
        "socket.socket.connect = refuse\nsocket.create_connection = refuse\nsocket.getaddrinfo = refuse\n"
        f"import importlib; importlib.import_module({module!r})\n"
    )

    def run() -> None:
        done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
        tail = (done.stderr or done.stdout).strip().splitlines()[-1:] or [""]
        _require(done.returncode == 0, f"{where} of {module!r} failed or used the network: {tail[0]}")

    return Check(f"{where} opens no network connection", run)


LIST_HOOKS: dict[str, Callable[[str, Any], list[Check]]] = {
    "parsel_edit_operators": _operator_checks,
    "parsel_cas_backends": _backend_checks,
    "parsel_shape_loaders": _loader_checks,
    "parsel_relation_detectors": _detector_checks,
    "parsel_llm_providers": _provider_checks,
    "parsel_deformers": _deformer_checks,
    "parsel_exporters": _exporter_checks,
    "parsel_solvers": _solver_checks,
}


def _hook_checks(plugin: str, hook: str, impl: Callable[..., Any]) -> list[Check]:
    if hook == "parsel_register_commands":
        return _commands_checks(plugin, impl)
    result = impl()
    if hook == "parsel_example_shapes":
        return _examples_checks(plugin, result)
    if hook == "parsel_prompt_templates":
        return _templates_checks(plugin, result)
    if hook not in LIST_HOOKS:
        return []

    def returns_list() -> None:
        _require(isinstance(result, list), f"{plugin}: {hook} must return a list, got {type(result).__name__}")

    checks = [Check(f"{plugin}: {hook} returns a list", returns_list)]
    for item in result if isinstance(result, list) else []:
        checks += LIST_HOOKS[hook](plugin, item)
    return checks


def plugin_checks(name: str) -> list[Check]:
    """Every check for the installed (or registered) plugin ``name``, an entry-point name."""
    from parsel_core.plugins import get_plugin_manager

    pm = get_plugin_manager()
    plugin = pm.get_plugin(name)
    record = pm.records.get(name)
    if plugin is None:
        installed = sorted(n for n, r in pm.records.items() if not r.builtin)

        def missing() -> None:
            if record is not None and record.error:
                raise AssertionError(f"{name}: failed to load: {record.error}")
            raise AssertionError(f"{name}: no such plugin is installed (installed: {', '.join(installed) or 'none'})")

        return [Check(f"{name}: is installed and loads", missing)]
    checks: list[Check] = []
    module = getattr(plugin, "__name__", None)
    if isinstance(module, str) and record is not None and not record.builtin:
        checks.append(_no_network_at_import(name, module))
    hooks = sorted(caller.name for caller in pm.get_hookcallers(plugin) or [])
    if not hooks:
        def no_hooks() -> None:
            raise AssertionError(f"{name}: implements no parsel hook (decorate functions with parsel_core.hookimpl)")

        checks.append(Check(f"{name}: implements a hook", no_hooks))
    for hook in hooks:
        impl = getattr(plugin, hook)
        try:
            checks += _hook_checks(name, hook, impl)
        except Exception as exc:
            message = f"{name}: {hook} raised {type(exc).__name__}: {exc}"

            def fails(message: str = message) -> None:
                raise AssertionError(message)

            checks.append(Check(f"{name}: {hook} runs", fails))
    return checks


def check_plugin(name: str) -> tuple[list[str], list[str], list[str]]:
    """Run every check of plugin ``name``: (passed, failed messages, skipped) check ids / messages."""
    passed, failed, skipped = [], [], []
    for check in plugin_checks(name):
        try:
            check.run()
        except NotApplicable as exc:
            skipped.append(f"{check.id}: {exc}")
        except AssertionError as exc:
            failed.append(str(exc))
        else:
            passed.append(check.id)
    return passed, failed, skipped
