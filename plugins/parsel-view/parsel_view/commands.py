"""The ``parsel view`` and ``parsel render`` commands (registered through ``parsel_register_commands``)."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from parsel_core.cli import EVALUATE_BACKEND_HELP, bounded_int
from parsel_core.errors import ParselError
from parsel_core.progress import working
from parsel_core.verbosity import VERBOSE, add_verbosity_options, logger, shows_progress


def cmd_view(args: argparse.Namespace) -> int:
    """Serve the slider page of OUTDIR's program on 127.0.0.1, or write it as one file with -o."""
    from parsel_core.outputs import to_stdout, write_single
    from parsel_view.inputs import read_inputs
    from parsel_view.page import PageServer, check_html_path, check_port, render_html, write_html
    from parsel_view.scene import build_page_data

    if args.html is not None and args.output is not None:
        raise ParselError(f"view: the page goes to -o {args.output!r} or --html {args.html!r}, not both")
    output = args.output if args.output is not None else args.html  # --html: the old spelling of -o
    if output is None:
        check_port(args.port)  # before the page is built
    elif not to_stdout(output):
        check_html_path(output)
    with working("view", enabled=shows_progress()):
        inputs = read_inputs(args.outdir, args.shape)
        page = build_page_data(inputs.program, inputs.shape,
                               meta={"sources": [str(p) for p in inputs.sources], "shape": inputs.shape_spec})
    if output is not None and to_stdout(output):
        write_single(None, render_html(page, inline=True))
        return 0
    if output is not None:
        path = write_html(page, output)
        if args.json:
            print(json.dumps({"written": [str(path)], "parameters": [p.name for p in inputs.program.parameters]},
                             indent=1))
            return 0
        print(path)
        return 0
    server = PageServer(page, port=args.port, quiet=not logger.isEnabledFor(VERBOSE))
    url = server.start()
    print(f"serving {inputs.shape.name} with {len(inputs.program.parameters)} slider(s) at {url} (Ctrl-C stops)",
          flush=True)
    if not args.no_browser:
        import webbrowser

        webbrowser.open(url)
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        print("stopped", file=sys.stderr)
    finally:
        server.stop()
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    """Draw a filmstrip of SHAPE edited by PROGRAM across a parameter's range."""
    from parsel_core.loading import load_program, load_shape, parse_assignments
    from parsel_core.outputs import stdout_suffix, to_stdout, write_single, written_by
    from parsel_view.inputs import program_path
    from parsel_view.render import FILMSTRIP_FORMATS, draw_filmstrip, filmstrip_format

    # before loading anything: fail fast on a typo
    suffix = stdout_suffix("-o", args.output, args.format, FILMSTRIP_FORMATS)
    output = Path(args.output or "-")
    if not to_stdout(args.output):
        filmstrip_format(output)
        if not output.parent.is_dir():
            raise ParselError(f"{output}: output directory {output.parent} does not exist")
    path = program_path(args.program)
    program = load_program(path)
    shape = load_shape(args.shape)
    try:
        program.validate(shape)
    except ParselError as exc:
        raise ParselError(f"{path}: does not match shape {shape.name!r}: {exc}") from None
    options = {"resolution": args.resolution} if args.resolution is not None else {}

    values = parse_assignments(args.set)

    def draw(path: Path) -> None:
        # --remesh counts its frames (seconds each); drawing without it only says it is working
        with working("render", enabled=shows_progress() and not args.remesh):
            draw_filmstrip(shape, program, path, frames=args.frames, parameter=args.param, values=values,
                           remesh=args.remesh, remesh_options=options, backend=args.backend,
                           progress=shows_progress())

    if to_stdout(args.output):
        if args.json:
            raise ParselError("-o - writes the picture to stdout: --json needs a file name")
        write_single(None, written_by(suffix, draw))
        return 0
    draw(output)
    if args.json:
        swept = program.parameter(args.param) if args.param else program.parameters[0]
        print(json.dumps({"written": [str(output)], "parameter": swept.name, "frames": args.frames,
                          "values": {k: v for k, v in program.values(values).items() if k != swept.name}}, indent=1))
        return 0
    print(output)
    return 0


def port(text: str) -> int:
    """``--port``: an integer, 0 or 1024 to 65535, else one line (argparse type)."""
    from parsel_view.page import check_port

    try:
        value = int(text)
    except ValueError:
        value = text
    check_port(value)
    return int(value)


port.bounds = (0, 65535)  # type: ignore[attr-defined]


def register(subparsers) -> None:
    p = subparsers.add_parser("view", help="a page with one slider per parameter (served on 127.0.0.1, or -o "
                                           "page.html)")
    p.add_argument("outdir", nargs="+", metavar="OUTDIR",
                   help="what parsel edit wrote (or a program file); several are stacked, each with its own sliders")
    p.add_argument("--shape", help="shape file or example name (default: the program's metadata 'shape')")
    p.add_argument("--port", type=port, default=8765, help="port on 127.0.0.1, 1024 to 65535 (default 8765; 0: any "
                   "free port)")
    p.add_argument("--no-browser", action="store_true", help="do not open a browser")
    p.add_argument("-o", "--output", metavar="FILE", help="output file: the page as one self-contained .html file "
                   "(then exit); - for standard output (default: serve it on 127.0.0.1)")
    p.add_argument("--html", metavar="FILE", help=argparse.SUPPRESS)  # the old spelling of -o
    p.add_argument("--json", action="store_true", help="with -o FILE: print the written file as JSON")
    add_verbosity_options(p, verbose_help="also log every request the server answers")
    p.set_defaults(func=cmd_view)

    p = subparsers.add_parser("render", help="a filmstrip picture (or a .gif animation) of the edited shape across "
                                             "a parameter's range")
    p.add_argument("shape", help="shape file or example name")
    p.add_argument("program", help="program file (.json or text form) or an OUTDIR of parsel edit")
    p.add_argument("-o", "--output", metavar="FILE", help="output file: a picture (.png, .svg or .pdf) or an "
                   "animation (.gif); - (or no -o): standard output, with --format")
    p.add_argument("--format", metavar="EXT", help="picture format for -o -: png, svg, pdf or gif")
    p.add_argument("--frames", type=bounded_int("--frames", 1, 24), default=5,  # 24: render.MAX_FRAMES
                   help="number of parameter values, 1 to 24 (default 5)")
    p.add_argument("--param", metavar="NAME", help="parameter to sweep (default: the first)")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="value of another parameter (repeatable)")
    p.add_argument("--remesh", action="store_true", help="draw the watertight remesh (needs parsel-remesh)")
    p.add_argument("--resolution", type=bounded_int("--resolution", 8, 1024),
                   help="remesh grid cells along the longest side, 8 to 1024 (with --remesh)")
    p.add_argument("--json", action="store_true", help="print the written file and the values drawn as JSON")
    p.add_argument("--backend", metavar="NAME", help=EVALUATE_BACKEND_HELP)
    add_verbosity_options(p, verbose_help="also print the time each frame took to evaluate and draw")
    p.set_defaults(func=cmd_render)
