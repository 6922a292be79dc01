"""What the commands read: ``parsel edit`` output directories (or program files) and their shape.

``parsel edit`` writes ``OUTDIR/program.json`` with the shape's name in the program's
metadata (``"shape"``), so ``parsel view OUTDIR`` needs nothing else. Several programs
are added as layers with :meth:`Program.plus` (each was solved on the rest shape, so
their displacements add and every slider combination keeps the relations each keeps
alone; docs/aep.md); a parameter name that an earlier program already uses is renamed
(``x`` -> ``x_2``) in the later one, amounts included, so every program keeps its own
slider, labelled with its request.
"""

from __future__ import annotations

import ast
import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from parsel_core.errors import ParselError
from parsel_core.expressions import parse_expression
from parsel_core.graph import ShapeGraph
from parsel_core.program import Parameter, Program


@dataclass
class ViewInputs:
    """A program (stacked when several were given), the shape it edits and where both came from."""

    program: Program
    shape: ShapeGraph
    sources: list[Path]
    shape_spec: str


def program_path(spec: str | Path) -> Path:
    """``OUTDIR`` -> ``OUTDIR/program.json``; a file is taken as it is."""
    path = Path(spec)
    if path.is_dir():
        path = path / "program.json"
        if not path.is_file():
            raise ParselError(f"{spec}: directory has no program.json (expected the output of parsel edit)")
        return path
    if not path.exists():
        raise ParselError(f"{spec}: no such file or directory")
    return path


class _Rename(ast.NodeTransformer):
    def __init__(self, names: dict[str, str]) -> None:
        self.names = names

    def visit_Name(self, node: ast.Name) -> ast.AST:  # noqa: N802 - ast's name
        return ast.copy_location(ast.Name(self.names.get(node.id, node.id), node.ctx), node)


def rename_parameters(program: Program, names: dict[str, str]) -> Program:
    """The same program with parameters renamed, in its parameter list and in every amount."""
    if not names:
        return program
    ops = []
    for op in program.ops:
        tree = _Rename(names).visit(ast.parse(parse_expression(op.amount).text, mode="eval"))
        ops.append(dataclasses.replace(op, amount=ast.unparse(tree)))
    parameters = [Parameter(names.get(p.name, p.name), p.lo, p.hi, p.default) for p in program.parameters]
    return dataclasses.replace(program, ops=tuple(ops), parameters=tuple(parameters))


def stack_programs(programs: Sequence[Program]) -> Program:
    """Programs added as layers, each keeping its own parameters; ``metadata["requests"]``
    names each parameter's request."""
    from parsel_core.joint import requests_of

    result = programs[0]
    used = set(result.parameter_names)
    requests = requests_of(result)
    for i, program in enumerate(programs[1:], start=2):
        renames = {}
        for name in program.parameter_names:
            if name in used:
                new, k = f"{name}_{i}", i
                while new in used or new in program.parameter_names:
                    k += 1
                    new = f"{name}_{k}"
                renames[name] = new
        requests += [{"request": r["request"], "parameter": renames.get(r["parameter"], r["parameter"])}
                     for r in requests_of(program)]
        program = rename_parameters(program, renames)
        used.update(program.parameter_names)
        result = result.plus(program)
    meta = {k: v for k, v in dict(result.metadata).items() if k not in ("request", "seed", "requests")}
    return result.with_metadata({**meta, "requests": requests})


def read_inputs(specs: Sequence[str], shape_spec: str | None = None) -> ViewInputs:
    """Programs from ``specs`` (directories or files) and the shape from ``shape_spec`` or their metadata.

    Errors are one line naming the file: a missing program, a program without a shape
    name, programs naming different shapes, a program whose parts the shape lacks.
    """
    from parsel_core.loading import load_program, load_shape

    if not specs:
        raise ParselError("give at least one OUTDIR (or program file)")
    paths = [program_path(spec) for spec in specs]
    programs = [load_program(path) for path in paths]
    if shape_spec is None:
        named = {str(p.metadata["shape"]) for p in programs if p.metadata.get("shape")}
        if not named:
            raise ParselError(f"{paths[0]}: program metadata names no shape; pass --shape SHAPE")
        if len(named) > 1:
            raise ParselError(f"programs edit different shapes ({', '.join(sorted(named))}); pass --shape SHAPE")
        shape_spec = named.pop()
    try:
        shape = load_shape(shape_spec)
    except ParselError as exc:
        raise ParselError(f"{paths[0]}: shape {shape_spec!r}: {exc}") from None
    for path, program in zip(paths, programs):
        try:
            program.validate(shape)
        except ParselError as exc:
            raise ParselError(f"{path}: does not match shape {shape.name!r}: {exc}") from None
    program = stack_programs(programs) if len(programs) > 1 else programs[0]
    return ViewInputs(program, shape, paths, shape_spec)
