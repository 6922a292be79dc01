"""Descriptions and examples for the ``--help`` of every core verb.

Kept apart from the parser definitions so each verb's help reads as one block:
:func:`document` gives every sub-parser that has none a description and an
``examples:`` epilog, shown verbatim. Plugins give their verbs' own (``description=``,
``epilog=`` in ``add_parser``); :data:`PLUGIN_VERBS` fills in for the bundled ones that
do not.
"""

from __future__ import annotations

import argparse

#: verb -> (description, example lines)
VERBS: dict[str, tuple[str, list[str]]] = {
    "plugins": ("List the installed plugins with their versions, the hooks each implements and what each "
                "provides (operators, backends, loaders, ...). Plugins that failed to load are shown with "
                "their error.",
                ["parsel plugins", "parsel plugins --json | jq '.provides.edit_operators'"]),
    "demo": ("The whole job on a bundled asset: detect relations, ask the offline provider for a seed "
             "edit, propagate it into a complete program, check every relation and write the program, "
             "report, prompts, a slider page and a filmstrip.",
             ["parsel demo", "parsel demo --shape tiny_table -o demo-table/", "parsel demo --quiet"]),
    "evaluate": ("Evaluate a program on a shape at parameter values and print the corners of the edited "
                 "parts (the CAS-compiled path; `parsel apply` writes files instead).",
                 ["parsel evaluate tiny_table widen.parsel --set x=0.5",
                  "parsel evaluate chair out/program.json --json",
                  "parsel evaluate chair out/program.json --backend sympy --verbose"]),
    "edit": ("Turn an edit request in words (through a language model: offline by default) or a seed "
             "edit (expert mode, --seed) into a complete editing program with Analytical Edit "
             "Propagation, and write OUTDIR/program.json, report.json and record.jsonl (prompts and "
             "replies).",
             ['parsel edit chair "make the chair wider" -o out/',
              'parsel edit chair "make the legs longer" --provider litellm --model gpt-4o -o out/',
              "parsel edit chair --seed \"scale_1d(seat, origin=(0, 0.43, 0), dir=(1, 0, 0), amount=x)\" -o out/",
              'parsel edit chair "make the chair wider" -o - --quiet | jq .ops',
              'parsel edit chair "make the legs longer" -o out/ --verbose']),
    "proxydural": ("Proxydural modelling (paper 8.1): ask for N edit requests that suit the shape, turn each "
                   "into a program and stack them into one program with one slider per request.",
                   ["parsel proxydural chair -n 4 -o proxy/", "parsel view proxy/",
                    "parsel proxydural chair -n 2 -o proxy/ --verbose"]),
    "variations": ("Shape variation families (paper 8.2): variants of one request with different secondary "
                   "effects, one program each (OUTDIR/variation_NN.program.json).",
                   ['parsel variations chair "make the chair wider" -n 3 -o family/',
                    'parsel variations chair "make the chair wider" -o family/ --quiet']),
    "check": ("Recompute the relation report of any program on a shape: each relation kept, broken on "
              "purpose or broken over the parameter range. Exit status 1 with --strict when a relation "
              "is broken.",
              ["parsel check chair out/program.json", "parsel check chair out/program.json --strict --json",
               "parsel check chair out/program.json --backend sympy --verbose"]),
    "apply": ("Evaluate a program at parameter values and export the edited shape; the output suffix "
              "picks the exporter (.glb, .obj, .ply, .hex.json, .watertight.obj ...).",
              ["parsel apply chair out/program.json --set x=0.3 -o edited.glb",
               "parsel apply chair out/program.json --sweep 5 -o frames.obj --quiet",
               "parsel apply chair out/program.json --set x=0.3 -o - --format obj --backend symengine | head"]),
    "inspect": ("List a shape's parts (label, size, centre) and its relations, as detected or declared.",
                ["parsel inspect chair", "parsel inspect chair.glb --json", "parsel inspect chair --png chair.png",
                 "parsel inspect scene.glb --verbose"]),
    "new-plugin": ("Write a plugin package to start from: an edit operator named NAME, its entry point, a "
                   "hand-computed test, the conformance kit and a CI workflow (docs/plugins.md).",
                   ["parsel new-plugin taper", "pip install -e parsel-taper && parsel plugins",
                    "parsel new-plugin bend -o plugins/parsel-bend --json"]),
    "convert": ("Convert a program between its JSON form (.json) and its text form (any other suffix). With "
                "-o - or no -o it is printed on standard output, in the other form than the input's unless "
                "--format says which.",
                ["parsel convert out/program.json -o program.parsel", "parsel convert out/program.json | less",
                 "parsel convert widen.parsel --format json | jq .ops"]),
}

#: The bundled plugins' verbs, for those whose parsers carry no description or examples.
PLUGIN_VERBS: dict[str, tuple[str, list[str]]] = {
    "view": ("Show a program on a page with one slider per parameter, served on 127.0.0.1 or written as "
             "one self-contained HTML file with -o FILE. Several OUTDIRs are stacked.",
             ["parsel view out/", "parsel view out/ -o page.html", "parsel view a/ b/ --shape chair",
              "parsel view out/ -o - | gzip > page.html.gz"]),
    "render": ("Draw a filmstrip of the edited shape across a parameter's range (.png, .svg or .pdf), or "
               "an animation of it (.gif).",
               ["parsel render chair out/program.json -o strip.png",
                "parsel render chair out/ -o strip.png --frames 7 --remesh",
                "parsel render chair out/program.json -o strip.gif --json",
                "parsel render chair out/program.json -o - --format png --backend sympy --quiet | display"]),
    "fit": ("Find the parameter values that bring the edited shape closest to a target (a mesh, a point "
            "cloud or another shape of the same parts) by Chamfer distance, and write the program with "
            "them as defaults (docs/fitting.md).",
            ["parsel fit chair out/program.json scan.ply -o fitted.json",
             "parsel fit chair out/program.json target.shape.json -o fitted.json --starts 8 --points 4096 "
             "--rng-seed 1",
             "parsel fit chair out/program.json scan.ply -o fitted.json --json | jq .values",
             "parsel fit chair out/program.json scan.ply -o - --verbose | jq .metadata.fit"]),
    "eval": ("Score programs against ground truth for the cases of CASES.jsonl (docs/evaluation.md).",
             ["parsel eval cases.jsonl", "parsel eval cases.jsonl --json --workers 2",
              "parsel eval cases.jsonl --verbose"]),
    "batch": ("Run many cases resumably on local processes or a Dask cluster (docs/evaluation.md).",
              ["parsel batch cases.jsonl -o results/", "parsel batch cases.jsonl -o results/ --dask tcp://host:8786",
               "parsel batch cases.jsonl -o results/ --quiet"]),
}


#: One line for ``parsel --help`` about the bundled plugins' verbs, listed there without importing them.
PLUGIN_SUMMARIES: dict[str, str] = {
    "view": "a page with one slider per parameter (served on 127.0.0.1, or -o page.html)",
    "render": "a filmstrip picture (or a .gif) of the edited shape across a parameter's range",
    "fit": "fit a program's parameters to a target mesh, point cloud or shape",
    "eval": "score inferred programs against ground truth (J, D, %%Rel, LLM accuracy)",
    "batch": "run many cases, resumably, on local processes or a Dask cluster",
}


def plugin_summary(name: str, declared: str) -> str:
    """The ``parsel --help`` line of plugin verb ``name``: its summary when bundled, else what its
    metadata declares (``from <distribution> ...``)."""
    summary = PLUGIN_SUMMARIES.get(name)
    if summary is None:
        return declared
    where = declared.removeprefix("from ").split(" (", 1)[0]
    return f"{summary} ({where})"


def examples_epilog(lines: list[str]) -> str:
    return "examples:\n" + "\n".join(f"  {line}" for line in lines)


def document(subparsers: argparse._SubParsersAction) -> None:
    """Give each verb without them a description and an examples epilog (shown as written)."""
    for name, parser in subparsers.choices.items():
        description, examples = VERBS.get(name) or PLUGIN_VERBS.get(name) or (None, [])
        if not parser.description and description:
            parser.description = description
        if not parser.epilog and examples:
            parser.epilog = examples_epilog(examples)
            parser.formatter_class = argparse.RawDescriptionHelpFormatter
