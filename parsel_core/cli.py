"""The ``parsel`` command line. Plugins add sub-commands through ``parsel_register_commands``."""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from parsel_core import __version__
from parsel_core.config import check_limit
from parsel_core.errors import ParselError
from parsel_core.io import write_all  # noqa: F401 - write_all: the commands' old home
from parsel_core.outputs import check_output_dir, to_stdout, write_outdir, write_single
from parsel_core.progress import working
from parsel_core.verbosity import add_verbosity_options, level_of, logger, shows_progress, verbosity


def bounded_int(option: str, lo: int, hi: int | None = None) -> Callable[[str], int]:
    """An argparse type: an integer in [lo, hi], else a one-line ``ParselError`` naming the option.

    Every numeric option of every verb (plugins' too) takes this or :func:`bounded_float`, so a
    typo or an out-of-range value is one line and exit status 2, never argparse's usage block
    or a traceback from deeper down (``tests/test_cli_help.py`` walks them all)."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < lo or (hi is not None and value > hi):
            bound = f"from {lo} to {hi}" if hi is not None else f">= {lo}"
            raise ParselError(f"{option} must be an integer {bound}, got {text!r}")
        return value

    parse.bounds = (lo, hi)  # type: ignore[attr-defined]
    return parse


def bounded_float(option: str, lo: float, hi: float | None = None) -> Callable[[str], float]:
    """An argparse type: a finite number in [lo, hi], else a one-line ``ParselError`` naming the option."""
    import math

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not math.isfinite(value) or value < lo or (hi is not None and value > hi):
            bound = f"from {lo:g} to {hi:g}" if hi is not None else f">= {lo:g}"
            raise ParselError(f"{option} must be a number {bound}, got {text!r}")
        return value

    parse.bounds = (lo, hi)  # type: ignore[attr-defined]
    return parse


#: ``--backend`` on verbs that only evaluate programs (check, apply, render): numpy unless named.
EVALUATE_BACKEND_HELP = ("evaluate the program compiled by this CAS backend (sympy, symengine, ...) instead of "
                         "the numpy reference evaluation")


def _add_backend(parser: argparse.ArgumentParser, help: str | None = None) -> None:
    parser.add_argument("--backend", metavar="NAME", help=help or "CAS backend (default: $PARSEL_CAS_BACKEND, "
                        "parsel.toml, else the fastest installed)")


def _add_force(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--force", action="store_true",
                        help="write into an OUTDIR holding other files (only parsel's own files are replaced)")


def cmd_plugins(args: argparse.Namespace) -> int:
    """List installed plugins with versions, hooks and what they provide."""
    from parsel_core import plugins

    pm = plugins.get_plugin_manager()
    records = pm.describe()
    provides = {
        "edit_operators": sorted(plugins.edit_operators()),
        "cas_backends": plugins.cas_backend_names(),
        "shape_loaders": [loader.name for loader in plugins.shape_loaders()],
        "relation_detectors": sorted(plugins.relation_detectors()),
        "llm_providers": sorted(plugins.llm_providers()),
        "deformers": sorted(plugins.deformers()),
        "exporters": sorted(plugins.exporters()),
        "solvers": sorted(plugins.solvers()),
        "example_shapes": sorted(plugins.example_shapes()),
    }
    per_plugin = {}
    for record in records:
        plugin = pm.get_plugin(record.name)
        items: dict[str, list[str]] = {}
        if plugin is not None:
            for hook_name in record.hooks:
                impl = getattr(plugin, hook_name, None)
                if hook_name == "parsel_register_commands" or impl is None:
                    continue
                result = impl()
                names = sorted(result) if isinstance(result, dict) else [getattr(i, "name", repr(i)) for i in result]
                items[hook_name.removeprefix("parsel_")] = names
        per_plugin[record.name] = items
    if args.json:
        data = {
            "parsel": __version__,
            "plugins": [
                {"name": r.name, "module": r.module, "version": r.version, "builtin": r.builtin,
                 "hooks": r.hooks, "provides": per_plugin[r.name], "error": r.error}
                for r in records
            ],
            "provides": provides,
        }
        print(json.dumps(data, indent=2))
        return 0
    print(f"parsel {__version__}")
    for r in records:
        status = f"FAILED: {r.error}" if r.error else ", ".join(r.hooks)
        print(f"  {r.name:<32} {r.version or '-':<10} {'(built-in) ' if r.builtin else ''}{status}")
        for hook, names in per_plugin[r.name].items():
            print(f"      {hook}: {', '.join(names)}")
    return 0


def _print_corners(evaluation, part_ids) -> None:
    import numpy as np

    for pid in part_ids:
        corners = np.asarray(evaluation.parts[pid])
        print(f"    {pid}:")
        for k, row in enumerate(corners):
            print(f"      {k}: ({row[0]: .4f}, {row[1]: .4f}, {row[2]: .4f})")


DEMO_REQUESTS = {"chair": "make the chair wider", "tiny_table": "make the table wider"}
DEMO_SEEDS = {"tiny_table": "scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount=x)",
              "chair": "scale_1d(seat, origin=(0, 0.43, 0), dir=(1, 0, 0), amount=x)"}


def cmd_demo(args: argparse.Namespace) -> int:
    """The whole job on a bundled asset: request -> seed -> program -> report -> outputs."""

    import numpy as np

    from parsel_core.loading import load_program, load_shape
    from parsel_core.plugins import example_shapes, get_plugin_manager, llm_providers
    from parsel_core.program import evaluate

    name = args.shape or ("chair" if "chair" in example_shapes() else "tiny_table")
    shape = load_shape(name)
    kinds: dict[str, int] = {}
    for relation in shape.relations.values():
        kinds[relation.kind] = kinds.get(relation.kind, 0) + 1
    print(f"shape: {shape.name}: {len(shape.parts)} parts; relations: "
          + ", ".join(f"{n} {k}" for k, n in sorted(kinds.items())))
    output = Path(args.output)
    request = args.request or DEMO_REQUESTS.get(name, "make it wider")
    if "offline" in llm_providers() and not args.seed:
        print(f'request: "{request}" (offline provider)')
        argv = ["edit", name, request, "-o", str(output)]
    else:
        seed = args.seed or DEMO_SEEDS.get(name)
        if seed is None:
            raise ParselError(f"no demo seed for {name!r}; give --seed")
        print(f"seed (expert mode): {seed}")
        argv = ["edit", name, "--seed", seed, "-o", str(output)]
    if args.backend:
        argv += ["--backend", args.backend]
    loudness = ["--quiet"] if args.quiet else ["--verbose"] if args.verbose else []
    status = main(argv + loudness)
    if status:
        return status
    program = load_program(output / "program.json")
    from parsel_core.textform import display_text

    print("\nprogram:\n  " + display_text(program.to_text()).strip().replace("\n", "\n  "))
    parameter = program.parameters[0]
    edited = [pid for pid in dict.fromkeys(op.operand for op in program.ops) if pid in shape.parts][:3]
    for value in np.linspace(parameter.lo, parameter.hi, 3):
        evaluation = evaluate(program, shape, {parameter.name: float(value)})
        print(f"\n{parameter.name} = {value:g}: corners of {', '.join(edited)}")
        _print_corners(evaluation, edited)
        for group, instances in evaluation.instances.items():
            print(f"    {group}: {len(instances)} instances")
    report = json.loads((output / "report.json").read_text())
    counts = report["counts"]
    print(f"\nrelations over [{parameter.lo:g}, {parameter.hi:g}]: {counts['kept']} kept, "
          f"{counts['broken_on_purpose']} broken on purpose, {counts['broken']} broken")
    commands: set[str] = set()
    get_plugin_manager().hook.parsel_register_commands(subparsers=_Recorder(commands))
    if "view" in commands:
        main(["view", str(output), "-o", str(output / "slider.html"), *loudness])
    if "render" in commands:
        main(["render", name, str(output / "program.json"), "-o", str(output / "strip.png"), *loudness])
    print(f"\nwritten: {', '.join(sorted(p.name for p in output.iterdir() if not p.name.startswith('.')))} "
          f"in {output}/")
    return 0


class _Recorder:
    """Collects the names of the sub-commands plugins register, without keeping their parsers."""

    def __init__(self, names: set[str]) -> None:
        self.names = names

    def add_parser(self, name: str, **kwargs):
        self.names.add(name)
        return argparse.ArgumentParser(prog=name, add_help=False)




def cmd_evaluate(args: argparse.Namespace) -> int:
    """Evaluate a program on a shape at parameter values and print (or dump) the corners."""
    import numpy as np

    from parsel_core.loading import load_program, load_shape, parse_assignments
    from parsel_core.plugins import get_cas_backend
    from parsel_core.program import compile_program

    values = parse_assignments(args.set)
    with working("evaluate", enabled=shows_progress()):
        shape = load_shape(args.shape)
        program = load_program(args.program)
        backend = get_cas_backend(args.backend)
        started = time.perf_counter()
        evaluation = compile_program(program, shape, backend)(values)
    logger.debug(f"compiled with {backend.name} and evaluated in {time.perf_counter() - started:.3f} s")
    if args.json:
        data = {
            "values": program.values(values),
            "parts": {pid: np.asarray(c).tolist() for pid, c in evaluation.parts.items() if pid in shape.parts},
            "instances": {g: c.tolist() for g, c in evaluation.instances.items()},
        }
        print(json.dumps(data, indent=1))
        return 0
    print(", ".join(f"{k} = {v:g}" for k, v in program.values(values).items()))
    _print_corners(evaluation, sorted(program.edited_parts & set(shape.parts)) or list(shape.parts))
    return 0


def inspect_data(shape) -> dict:
    """The ``parsel inspect --json`` document (schema in docs/formats.md)."""
    return {
        "format": "parsel.inspect",
        "version": 1,
        "shape": shape.name,
        "source": shape.source,
        "size": shape.size,
        "parts": [
            {"id": p.id, "name": p.name, "label": p.label, "corners": p.hexahedron.corners.tolist()}
            for p in shape.parts.values()
        ],
        "groups": [
            {"id": g.id, "members": list(shape.relations[g.id].members), "corners": g.hexahedron.corners.tolist()}
            for g in shape.virtual_parents.values()
        ],
        "relations": [r.to_dict() for r in shape.relations.values()],
    }


def cmd_inspect(args: argparse.Namespace) -> int:
    """A table of a shape's parts and relations (``--json`` for machines, ``--png`` for a picture)."""
    from parsel_core.drawing import save_shape_png
    from parsel_core.loading import load_shape

    with working("inspect", enabled=shows_progress()):
        started = time.perf_counter()
        shape = load_shape(args.shape, detect=not args.no_detect)
        logger.debug(f"loaded {shape.name} with {'its declared' if args.no_detect else 'detected'} relations in "
                     f"{time.perf_counter() - started:.3f} s")
        if args.png:
            save_shape_png(shape, args.png)
    if args.json:
        print(json.dumps(inspect_data(shape), indent=1))
        return 0
    print(f"{shape.name}: {len(shape.parts)} parts, {len(shape.relations)} relations"
          + (f" ({shape.source})" if shape.source else ""))
    print(f"\n{'part':<28}{'label':<16}{'size (x, y, z)':<26}centre")
    for part in shape.parts.values():
        corners = part.hexahedron.corners
        size = corners.max(axis=0) - corners.min(axis=0)
        centre = part.hexahedron.center
        print(f"{part.id:<28}{part.label:<16}{' '.join(f'{v:7.3f}' for v in size):<26}"
              f"{' '.join(f'{v:7.3f}' for v in centre)}")
    print(f"\n{'relation':<36}{'kind':<22}members")
    for relation in shape.relations.values():
        kind = relation.kind + (f" ({relation.contact})" if hasattr(relation, "contact") else "")
        print(f"{relation.id:<36}{kind:<22}{', '.join(relation.members)}")
    return 0


def _parse_hints(items: list[str] | None) -> dict[str, str]:
    hints = {}
    for item in items or []:
        part, sep, kind = item.partition("=")
        if not sep or not part or not kind:
            raise ParselError(f"--hint {item!r}: expected PART=translate|rotate|scale|keep")
        hints[part] = kind
    return hints


def _language_options(args: argparse.Namespace) -> dict:
    """The language-model options every request-taking command shares."""
    return {"provider": args.provider, "model": args.model, "samples": args.samples, "backend": args.backend,
            "api_base": args.api_base, "cache_dir": args.cache}


def check_tau(tau: float | None) -> None:
    """``--tau``: the parameter range [0, tau] must be a finite, positive span of sane size."""
    from parsel_core.config import limit

    if tau is not None and not 1e-6 <= tau <= limit("max_magnitude"):
        raise ParselError(f"--tau {tau!r}: the parameter range [0, tau] needs tau from 1e-06 to "
                          f"{limit('max_magnitude'):g} (max_magnitude)")


def cmd_edit(args: argparse.Namespace) -> int:
    """A request in words (language layer) or a seed edit (expert mode) -> a complete program."""
    from parsel_core import api
    from parsel_core.language import InferenceError
    from parsel_core.language.inference_io import keep_failed_record
    from parsel_core.loading import parse_options

    stdout = to_stdout(args.output)
    if stdout and args.json:
        raise ParselError("-o - prints the program itself; --json prints a summary of a written OUTDIR: use one")
    if not stdout:
        check_output_dir(args.output, args.force)
    check_tau(args.tau)
    options = {"tau": args.tau} if args.tau is not None else {}
    solver_options = parse_options(args.solver_option, "--solver-option")
    try:
        with working("edit", enabled=shows_progress()):
            result = api.edit(args.shape, args.request, args.seed, mode=args.mode, hints=_parse_hints(args.hint),
                              breaks=list(args.break_ or ()), solver=args.solver, nhbd=not args.no_nhbd,
                              breaking=not args.no_breaking, replay=args.replay, timeout=args.timeout,
                              retries=args.retries, with_image=args.with_image, on=args.on,
                              solver_options=solver_options, **_language_options(args), **options)
    except InferenceError as exc:
        # The record of what was asked and answered is the useful output of a failed inference;
        # a previous OUTDIR is never replaced by it.
        if stdout:
            raise
        raise keep_failed_record(exc, args.output, api.records_jsonl(exc.record)) from None
    program, report = result.program, result.report
    if stdout:  # the program on stdout, for pipes; the summary is a note on stderr
        write_single(None, program.to_json())
    else:
        write_outdir(args.output, result.files(), args.force)
    say = logger.info if stdout else print
    counts = report.counts()
    if args.json:
        print(json.dumps({"output": args.output, "files": sorted(result.files()), "ops": len(program.ops),
                          "parameters": [{"name": p.name, "lo": p.lo, "hi": p.hi} for p in program.parameters],
                          "relations": counts, "broken": [s.id for s in report.relations if s.state == "broken"],
                          "rejected": result.rejected, "accounting": result.accounting,
                          "timings": result.timings}, indent=1))
        return 0
    ranges = ", ".join(f"{p.name} in [{p.lo:g}, {p.hi:g}]" for p in program.parameters)
    joint = f" at {report.samples} joint samples ({report.box_corners} box corners)" if report.box_corners else ""
    say(f"{len(program.ops)} ops, {ranges}; relations{joint}: {counts['kept']} kept, "
        f"{counts['broken_on_purpose']} broken on purpose, {counts['broken']} broken -> "
        f"{'stdout' if stdout else args.output}")
    for state in report.relations:
        if state.state == "broken":
            say(f"  broken: {state.id} ({state.kind}: {', '.join(state.members)})")
    return 0


def cmd_proxydural(args: argparse.Namespace) -> int:
    """Proxydural modelling (paper 8.1): N requests, one program each, stacked with N sliders."""
    from parsel_core import api

    check_output_dir(args.output, args.force)
    result = api.proxydural(args.shape, args.count, progress=shows_progress(), **_language_options(args))
    write_outdir(args.output, result.files(), args.force)
    counts = result.report.counts()
    if args.json:
        print(json.dumps({"output": args.output, "sliders": result.used, "skipped": result.skipped,
                          "relations": counts, "joint_samples": result.report.samples,
                          "box_corners": result.report.box_corners, "per_slider": result.per_slider}, indent=1))
        return 0
    report = result.report
    joint = f" at {report.samples} joint samples ({report.box_corners} box corners)" if report.box_corners else ""
    print(f"{len(result.used)} sliders ({', '.join(u['parameter'] + ': ' + u['request'] for u in result.used)}); "
          f"relations{joint}: {counts['kept']} kept, {counts['broken_on_purpose']} broken on purpose, "
          f"{counts['broken']} broken -> {args.output}")
    for name, c in result.per_slider.items():
        print(f"  {name} alone: {c['kept']} kept, {c['broken_on_purpose']} broken on purpose, {c['broken']} broken")
    for item in result.skipped:
        print(f"  skipped: {item['request']}: {item['reason']}")
    return 0


def cmd_variations(args: argparse.Namespace) -> int:
    """Shape variation families (paper 8.2): variants of one request, one program each."""
    from parsel_core import api

    check_output_dir(args.output, args.force)
    result = api.variations(args.shape, args.request, args.count, progress=shows_progress(),
                            **_language_options(args))
    files = result.files()
    write_outdir(args.output, files, args.force)
    if args.json:
        print(json.dumps({"output": args.output, **json.loads(files["variations.json"])}, indent=1))
        return 0
    for i, variant in enumerate(result.variants, start=1):
        if variant.report is not None:
            c = variant.report.counts()
            print(f"variation_{i:02d}.program.json: {variant.request} ({c['kept']} kept, {c['broken']} broken)")
        else:
            print(f"skipped: {variant.request}: {variant.skipped}")
    return 0


def cmd_check(args: argparse.Namespace) -> int:
    """Recompute the relation report of any program on a shape."""
    from parsel_core import api

    with working("check", enabled=shows_progress()):
        shape = api.as_shape(args.shape)
        report = api.check(shape, args.program, args.break_ or (), samples=args.samples, backend=args.backend)
    counts = report.counts()
    status = 1 if args.strict and counts["broken"] else 0  # --strict: broken relations fail CI
    if args.json:
        print(json.dumps(report.to_dict(), indent=1))
        return status
    corners = f", {report.box_corners} of them corners of the parameter box" if report.box_corners else ""
    print(f"{shape.name}: {counts['kept']} kept, {counts['broken_on_purpose']} broken on purpose, "
          f"{counts['broken']} broken (tolerance {report.tolerance:.2e}, {report.samples} samples{corners})")
    for state in report.relations:
        worst = ""
        if state.worst_at is not None and state.state != "kept":
            worst = " at " + ", ".join(f"{k}={v:.4g}" for k, v in state.worst_at.items())
        print(f"  {state.state:<18} {state.id:<36} {state.kind:<12} max error {state.max_error:.2e}{worst}")
    return status


def cmd_apply(args: argparse.Namespace) -> int:
    """Evaluate a program at parameter values and export the edited shape."""
    from parsel_core import api
    from parsel_core.loading import parse_assignments
    from parsel_core.outputs import stdout_suffix, written_by
    from parsel_core.plugins import exporters

    if args.sweep is not None:
        check_limit("max_sweep", "--sweep", args.sweep)
    options = {"sweep": args.sweep, "progress": shows_progress(), "backend": args.backend}
    suffix = stdout_suffix("-o", args.output, args.format, {x for e in exporters().values() for x in e.extensions})
    values = parse_assignments(args.set)

    def export(path: str | Path) -> list[Path]:
        # a sweep counts its files; one file (a watertight remesh takes seconds) says it is working
        with working("apply", enabled=shows_progress() and args.sweep is None):
            return api.export(args.shape, args.program, path, values, **options)

    if to_stdout(args.output):
        if args.sweep is not None or args.json:
            raise ParselError("-o - writes one file to stdout: --sweep and --json need a file name")
        write_single(None, written_by(suffix, export))
        return 0
    paths = export(args.output)
    if args.json:
        print(json.dumps({"written": [str(p) for p in paths], "values": values}, indent=1))
        return 0
    for path in paths:
        print(path)
    return 0


def cmd_convert(args: argparse.Namespace) -> int:
    """Convert a program between its JSON and text forms (by the output suffix)."""

    from parsel_core.io import atomic_write_text
    from parsel_core.loading import load_program

    if args.old_output is not None and args.output is not None:
        raise ParselError(f"convert: the output is {args.old_output!r} or -o {args.output!r}, not both")
    output = args.output if args.output is not None else args.old_output
    if args.format and not to_stdout(output):
        raise ParselError(f"-o {output}: --format is for -o - (standard output); a file's suffix names its form")
    program = load_program(args.program)
    if to_stdout(output):
        as_json = args.format == "json" if args.format else Path(args.program).suffix.lower() != ".json"
        write_single(None, program.to_json() if as_json else program.to_text())
        return 0
    out = Path(output)
    atomic_write_text(out, program.to_json() if out.suffix.lower() == ".json" else program.to_text())
    return 0


def cmd_new_plugin(args: argparse.Namespace) -> int:
    """Write a plugin package to start from: one operator, its tests, the conformance kit and CI."""
    from parsel_core.scaffold import write_plugin

    target = args.output or f"parsel-{args.name.replace('_', '-')}"
    paths = write_plugin(args.name, target)
    if args.json:
        print(json.dumps({"output": str(target), "written": [str(path) for path in paths]}, indent=1))
        return 0
    for path in paths:
        print(path)
    return 0


#: ``parsel --help``'s examples.
TOP_EXAMPLES = ['parsel edit chair "make the chair wider" -o out/ && parsel view out/',
                "parsel check chair out/program.json --strict",
                "parsel apply chair out/program.json --set x=0.3 -o wide.glb",
                "parsel demo"]


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The command line; ``argv`` (when given) lets it skip plugins the command does not need."""
    from parsel_core import api
    from parsel_core.cli_help import examples_epilog

    parser = argparse.ArgumentParser(prog="parsel", description="Parameterized shape editing with language. "
                                     "`parsel COMMAND --help` describes each command, with examples.",
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog=examples_epilog(TOP_EXAMPLES))
    parser.add_argument("--version", action="version", version=f"parsel {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("plugins", help="list installed plugins, their versions and hooks")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=cmd_plugins)

    p = sub.add_parser("demo", help="the whole job on a bundled asset: request to program, report and pages")
    p.add_argument("--shape", help="example name or shape file (default: chair, else tiny_table)")
    p.add_argument("--request", help="the edit request (default: make the chair wider)")
    p.add_argument("--seed", metavar="OP", help="a seed op in the program text form instead of a request (expert "
                   "mode)")
    p.add_argument("-o", "--output", default="demo-output", metavar="OUTDIR",
                   help="output folder (default: demo-output)")
    _add_backend(p)
    add_verbosity_options(p, verbose_help="also print the solver's statistics and how long each step took, on "
                          "stderr")
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("evaluate", help="evaluate a program on a shape at parameter values")
    p.add_argument("shape", help="shape file or example name")
    p.add_argument("program", help="program file (.json or text form)")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="parameter value (repeatable)")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    _add_backend(p)
    add_verbosity_options(p, verbose_help="also print which backend compiled the program and how long it took")
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser("edit", help="a request in words (or an expert seed edit) -> a complete editing program")
    p.add_argument("shape", help="shape file or example name")
    p.add_argument("request", nargs="?", help="an edit request in words (needs a language-model provider)")
    p.add_argument("--seed", metavar="OP", help='seed op(s) in the program text form, e.g. '
                   '"scale_1d(seat, origin=(0, 0.45, 0), dir=(1, 0, 0), amount=x)"')
    p.add_argument("--hint", action="append", metavar="PART=TYPE", help="type hint: translate, rotate, scale or keep")
    p.add_argument("--break", dest="break_", action="append", metavar="RELATION_ID",
                   help="a relation the edit may break (repeatable)")
    p.add_argument("--provider", default="offline", help="language-model provider: offline (default), litellm, "
                   "replay or any installed")
    p.add_argument("--model", help="model name for the provider (litellm: any model litellm supports)")
    p.add_argument("--api-base", help="base URL of an OpenAI-compatible server (litellm)")
    p.add_argument("--mode", default="full", choices=("full", "seed-only", "one-shot"),
                   help="full: seed + hints + validity; seed-only; one-shot: the model writes the program")
    p.add_argument("--samples", type=bounded_int("--samples", 1, 100), default=5,
                   help="samples per prompt for majority voting (default 5)")
    p.add_argument("--replay", metavar="FILE", help="recorded replies for the replay provider")
    p.add_argument("--cache", metavar="DIR", help="reply cache directory (off by default)")
    p.add_argument("--timeout", type=bounded_float("--timeout", 0.001, 86400), metavar="S",
                   help="seconds per model call, 0.001 to 86400 (litellm; default 60)")
    p.add_argument("--retries", type=bounded_int("--retries", 0, 100), metavar="N", help="retries of a call after a "
                   "rate limit, server error or timeout, 0 to 100 (litellm; default 3)")
    p.add_argument("--with-image", action="store_true", help="send a picture of the shape with part ids along "
                   "with the prompts (models that take images; offline and replay ignore it)")
    p.add_argument("--solver", default="aep", help="solver plugin (default: aep)")
    p.add_argument("--tau", type=bounded_float("--tau", 1e-6), help="parameter range [0, tau], tau from 1e-06 to "
                   "max_magnitude (default: chosen automatically)")
    p.add_argument("--no-nhbd", action="store_true", help="ablation: no candidates from edited neighbours")
    p.add_argument("--no-breaking", action="store_true", help="ablation: no breaking-edits")
    p.add_argument("--solver-option", action="append", metavar="NAME=VALUE",
                   help="a solver option, repeatable, over the flags above (aep: joint=0 turns the joint pass "
                        "off, faster but fewer relations kept; docs/aep.md lists them)")
    p.add_argument("--on", metavar="PROGRAM", help="grow this program (program.json of an earlier edit or "
                   "proxydural, or its OUTDIR): the request becomes one more parameter, checked jointly")
    p.add_argument("-o", "--output", metavar="OUTDIR", help="output folder: program.json, report.json and "
                   "record.jsonl; - (or no -o): program.json on standard output, the summary on stderr")
    p.add_argument("--json", action="store_true", help="print a machine-readable summary instead of text")
    _add_force(p)
    _add_backend(p)
    add_verbosity_options(p, verbose_help="also print the solver's statistics, its time per stage and why each "
                          "lost relation was lost, on stderr")
    p.set_defaults(func=cmd_edit)

    for name, func, text in (("proxydural", cmd_proxydural, "N requests for a shape, stacked into one program with "
                                                           "N sliders (a proxydural model)"),
                             ("variations", cmd_variations, "a family of variants of one request, one program "
                                                            "each")):
        p = sub.add_parser(name, help=text)
        p.add_argument("shape", help="shape file or example name")
        if name == "variations":
            p.add_argument("request", help="the edit request the variants keep")
        p.add_argument("-n", "--count", type=bounded_int("-n", 1, api.MAX_REQUESTS),
                       default=5 if name == "proxydural" else 3,
                       help=f"number of {'requests (sliders)' if name == 'proxydural' else 'variants'}, 1 to "
                            f"{api.MAX_REQUESTS} (default {5 if name == 'proxydural' else 3})")
        p.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output folder (written whole)")
        p.add_argument("--provider", default="offline", help="language-model provider (default: offline)")
        p.add_argument("--model", help="model name for the provider")
        p.add_argument("--api-base", help="base URL of an OpenAI-compatible server (litellm)")
        p.add_argument("--samples", type=bounded_int("--samples", 1, 100), default=5,
                       help="samples per prompt for majority voting (default 5)")
        p.add_argument("--cache", metavar="DIR", help="reply cache directory (off by default)")
        p.add_argument("--json", action="store_true", help="print a machine-readable summary instead of text")
        _add_force(p)
        _add_backend(p)
        add_verbosity_options(p, verbose_help="also print each request's solver statistics and lost relations "
                              "on stderr")
        p.set_defaults(func=func)

    p = sub.add_parser("check", help="the relation report of a program on a shape")
    p.add_argument("shape", help="shape file or example name")
    p.add_argument("program", help="program file (.json or text form)")
    p.add_argument("--break", dest="break_", action="append", metavar="RELATION_ID",
                   help="a relation the program breaks on purpose (repeatable)")
    p.add_argument("--steps", dest="samples", type=bounded_int("--steps", 2, 100_000), default=50,
                   help="parameter values checked across the range, ends included (default 50)")
    # --samples means model votes elsewhere; the old spelling here still works, unlisted
    p.add_argument("--samples", dest="samples", type=bounded_int("--samples", 2, 100_000), help=argparse.SUPPRESS)
    p.add_argument("--strict", action="store_true", help="exit with status 1 when a relation is broken")
    p.add_argument("--json", action="store_true", help="the report as JSON (schema: docs/formats.md)")
    _add_backend(p, EVALUATE_BACKEND_HELP)
    add_verbosity_options(p, verbose_help="also print how the program was evaluated and how long it took")
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("apply", help="export the edited shape at parameter values")
    p.add_argument("shape", help="shape file or example name")
    p.add_argument("program", help="program file (.json or text form)")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="parameter value (repeatable; default: "
                   "the parameter's default)")
    p.add_argument("--sweep", type=bounded_int("--sweep", 2), metavar="N",
                   help="write N files (2 to max_sweep) across the first parameter's range")
    p.add_argument("-o", "--output", metavar="FILE", help="output file; its suffix picks the exporter; - (or no -o): "
                   "standard output, with --format")
    p.add_argument("--format", metavar="EXT", help="the exporter's format for -o - (glb, obj, ply, sa.txt, ...)")
    p.add_argument("--json", action="store_true", help="print the written paths as JSON")
    _add_backend(p, EVALUATE_BACKEND_HELP)
    add_verbosity_options(p, verbose_help="also print each file's exporter and time on stderr")
    p.set_defaults(func=cmd_apply)

    p = sub.add_parser("inspect", help="list a shape's parts and relations")
    p.add_argument("shape", help="shape file or example name")
    p.add_argument("--json", action="store_true", help="machine-readable output (schema: docs/formats.md)")
    p.add_argument("--png", metavar="FILE",
                   help="also draw the hexahedra, coloured by label, to FILE (.png, .svg or .pdf)")
    p.add_argument("--no-detect", action="store_true", help="do not run relation detectors")
    add_verbosity_options(p, verbose_help="also print how long loading and detecting relations took")
    p.set_defaults(func=cmd_inspect)

    p = sub.add_parser("new-plugin", help="write a plugin package (an edit operator, tests, the conformance kit, "
                                          "CI) to start from")
    p.add_argument("name", help="the operator's and the entry point's name, a lower-case identifier (e.g. taper)")
    p.add_argument("-o", "--output", metavar="DIR", help="output folder for the package, a new one (default: "
                   "parsel-NAME)")
    p.add_argument("--json", action="store_true", help="print the written files as JSON")
    p.set_defaults(func=cmd_new_plugin)

    p = sub.add_parser("convert", help="convert a program between JSON (.json) and text form")
    p.add_argument("program", help="program file (.json or text form)")
    p.add_argument("old_output", nargs="?", metavar="OUTPUT", help=argparse.SUPPRESS)  # before -o; still works
    p.add_argument("-o", "--output", metavar="FILE", help="output file: .json for JSON, anything else for the text "
                   "form; - (or no -o): standard output, in the other form than the input's unless --format")
    p.add_argument("--format", choices=("json", "text"), help="the form for -o - (standard output): json or text")
    p.set_defaults(func=cmd_convert)

    _add_plugin_commands(sub, argv)
    from parsel_core.cli_help import document

    document(sub)
    return parser


def _add_plugin_commands(sub, argv: Sequence[str] | None) -> None:
    """Plugins' sub-commands, loading plugins only when the command line may name one.

    A built-in command needs none; with no command (``parsel --help``) the listing comes
    from the plugins' metadata (:func:`parsel_core.plugins.declared_commands`), so no
    plugin is imported; ``argv=None`` means every command (the whole parser).
    """
    from parsel_core import plugins

    command = next((word for word in argv if not word.startswith("-")), None) if argv is not None else ""
    if command is None:
        from parsel_core.cli_help import plugin_summary

        for name, text in plugins.declared_commands().items():
            if name not in sub.choices:
                sub.add_parser(name, help=plugin_summary(name, text), add_help=False)
    elif command not in sub.choices:
        plugins.get_plugin_manager().hook.parsel_register_commands(subparsers=sub)


def _one_line_warning(message, category, filename, lineno, line=None) -> str:
    return f"parsel: warning: {message}\n"


def main(argv: Sequence[str] | None = None) -> int:
    import warnings

    argv = list(sys.argv[1:] if argv is None else argv)
    previous = warnings.formatwarning
    warnings.formatwarning = _one_line_warning  # the command line shows warnings as one line each
    try:
        parser = build_parser(argv)
        args = parser.parse_args(argv)
        if not getattr(args, "func", None):
            parser.print_help()
            return 0
        with verbosity(level_of(args)):
            return int(args.func(args) or 0)
    except ParselError as exc:
        print(f"parsel: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except BrokenPipeError:
        return 1
    finally:
        warnings.formatwarning = previous  # callers of main() in-process keep their own format


def console() -> None:
    """The ``parsel`` program: :func:`main` in a process of its own, BLAS on one thread
    unless the user chose a size (:func:`parsel_core.blas.start_on_one_thread`; set
    before any plugin loads numpy). Callers of :func:`main` in-process keep theirs."""
    import os

    from parsel_core.blas import start_on_one_thread

    start_on_one_thread(os.environ)
    sys.exit(main())


if __name__ == "__main__":
    console()
