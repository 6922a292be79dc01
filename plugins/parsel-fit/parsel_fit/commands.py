"""``parsel fit SHAPE PROGRAM TARGET -o fitted.json`` (registered through ``parsel_register_commands``)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from parsel_core.cli import EVALUATE_BACKEND_HELP, bounded_int
from parsel_core.verbosity import add_verbosity_options


def cmd_fit(args: argparse.Namespace) -> int:
    """Fit PROGRAM's parameters so SHAPE edited by it comes closest to TARGET; write the fitted program."""
    from parsel_core.errors import ParselError
    from parsel_core.loading import load_program, load_shape, parse_assignments
    from parsel_core.outputs import to_stdout, write_single
    from parsel_core.verbosity import logger, shows_progress
    from parsel_fit.fit import fit_program, fitted_program
    from parsel_fit.targets import load_target

    stdout = to_stdout(args.output)
    output = Path(args.output or "-")
    if not stdout and output.suffix.lower() != ".json":
        raise ParselError(f"{output}: the fitted program is written as JSON (.json)")
    if not stdout and not output.parent.is_dir():
        raise ParselError(f"{output}: output directory {output.parent} does not exist")
    if stdout and args.json:
        raise ParselError("-o - prints the fitted program itself; --json prints a summary of a written file: use one")
    if args.rng_seed is not None and args.seed is not None:
        raise ParselError("--seed is the old spelling of --rng-seed: give one")
    seed = args.rng_seed if args.rng_seed is not None else args.seed if args.seed is not None else 0
    shape = load_shape(args.shape)
    program = load_program(args.program)
    target = load_target(args.target, count=args.points * 2, seed=seed + 1)
    result = fit_program(shape, program, target, starts=args.starts, samples=args.points, seed=seed,
                         fixed=parse_assignments(args.set), backend=args.backend, progress=shows_progress())
    write_single(None if stdout else output, fitted_program(program, result, args.target).to_json())
    if args.json:
        print(json.dumps({"output": str(output), "target": args.target, **result.to_dict(),
                          "relative_distance": result.distance_after / (shape.size or 1.0)}, indent=1))
        return 0
    say = logger.info if stdout else print  # stdout holds the program itself: the summary is a note
    size = shape.size or 1.0
    say(f"Chamfer distance: {result.distance_before:.5g} at the defaults -> {result.distance_after:.5g} fitted "
        f"({result.distance_after / size:.3%} of the diagonal); {result.evaluations} evaluations, "
        f"{result.cpu_s:.2f} s CPU")
    for p in program.parameters:
        say(f"  {p.name} = {result.values[p.name]:.6g}  (range [{p.lo:g}, {p.hi:g}], was "
            f"{result.start_values[p.name]:g})")
    if not stdout:
        print(output)
    return 0


def register(subparsers) -> None:
    p = subparsers.add_parser("fit", help="fit a program's parameters to a target mesh, point cloud or shape")
    p.add_argument("shape", help="shape file or example name")
    p.add_argument("program", help="program file (.json or text form)")
    p.add_argument("target", help="target: a mesh (.ply .obj .off .stl .glb), points (.xyz .pts .npy) or a shape")
    p.add_argument("-o", "--output", metavar="FILE", help="output file: the fitted program (.json), fitted values as "
                   "defaults; - (or no -o): standard output, the summary on stderr")
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="keep a parameter at this value")
    p.add_argument("--starts", type=bounded_int("--starts", 1, 100), default=4,
                   help="optimiser starts, 1 to 100 (default 4: the defaults + 3 spread)")
    p.add_argument("--points", type=bounded_int("--points", 16, 1_000_000), default=8192,
                   help="surface points sampled on the edited shape, 16 to 1000000 (default 8192)")
    p.add_argument("--rng-seed", type=bounded_int("--rng-seed", 0, 2**32 - 1), metavar="N",
                   help="seed of the random samples and starts (default 0)")
    # --seed is a seed edit on edit and demo; fit's old spelling still works, unlisted
    p.add_argument("--seed", type=bounded_int("--seed", 0, 2**32 - 1), help=argparse.SUPPRESS)
    p.add_argument("--json", action="store_true", help="print a machine-readable summary (distances, values, "
                   "starts) instead of text")
    p.add_argument("--backend", metavar="NAME", help=EVALUATE_BACKEND_HELP)
    add_verbosity_options(p, verbose_help="also print each optimiser start's end point and distance on stderr")
    p.set_defaults(func=cmd_fit)
