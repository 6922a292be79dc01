"""Hostile and broken input: run the ``parsel`` command on a generated corpus of bad input.

Every case is a command line plus the files it reads, generated from a seed (so a run is
reproducible) in families: numbers at the edge of floating point, amount expressions that
overflow or nest deeply, broken structure (GLB node cycles, indices out of range, wrong
JSON types), hostile names, bad arguments, output folders holding other files, batch
files. Each case runs in a fresh folder, in a process forked from this one (plugins are
loaded once), under a wall-clock and a memory limit. A case passes when:

* the command exits 0, or exits 2 with its error as one line (``parsel: error: ...`` or
  argparse's usage error), and prints no Python traceback;
* it ends within the time limit (no hang) and within the memory limit;
* when it fails, the folder is exactly as before (no partial output), apart from a
  ``*.failed-record.jsonl`` record; whatever the outcome, files parsel did not write
  are untouched and no staging folder is left behind.

Run: ``python benchmarks/fuzz.py --cases 3000`` (prints a table per family and the peak
memory of a run); ``tests/test_fuzz.py`` runs a fast subset in ``make test``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import random
import resource
import shutil
import signal
import struct
import sys
import tempfile
import time
from collections import Counter, defaultdict
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

# -- cases -------------------------------------------------------------------------------------


@dataclass
class Case:
    """One command line, the files it reads (name -> bytes) and those that belong to the user."""

    family: str
    argv: list[str]
    files: dict[str, bytes] = field(default_factory=dict)
    #: a cheap case (well under a second): the test subset draws from these
    cheap: bool = True


#: Numbers at the edge of floating point, as they would be typed in a file or a flag.
EDGE_NUMBERS = ["1e308", "-1e308", "1e-320", "nan", "inf", "-inf", "1" * 25, "9" * 400, "7" * 5000, "1e999",
                "-0.0", "0", "2.5e-308", "1e30", "NaN", "Infinity"]
#: Amount expressions that overflow, divide by zero, nest deeply or are not arithmetic.
BAD_AMOUNTS = ["2**99999", "9**9**9**9", "x**x**x**x**x**99", "1/0", "x/0", "1/(x-x)", "log(0*x)", "sqrt(-1-x)",
               "(" * 300 + "x" + ")" * 300, "-" * 1500 + "x", "+".join(["x"] * 999), "*".join(["x"] * 999),
               "x # <!--<script>", "x\nscale_1d(seat)", "exp(exp(exp(x+10)))", "1e308*1e308*x",
               "__import__('os')", "x.real", "[x]", "lambda: x", "x if x else x", "'x'", "1" * 5000 + "*x",
               "1e999*x", "atan2(x)", "sin(x, x)", "min(x)", "x" * 3000, "tan(pi/2+0*x)", "0**(-1+0*x)"]
#: Part names and labels that break careless code: newlines, markup, JavaScript object keys.
BAD_NAMES = ["constructor", "__proto__", "toString", "hasOwnProperty", "valueOf", "seat\nignore previous",
             "</script><script>alert(1)</script>", "leg # comment", "ü🪑", "a\tb", "x" * 300, "..", "a/b",
             "'quoted'", "\\u2028", "seat\rback"]


def _obj(parts: dict[str, list[tuple[float, float, float]]], faces_of: Callable[[int], list[str]] | None = None,
         extra: str = "") -> bytes:
    lines, base = [], 0
    for name, box in parts.items():
        lines.append(f"o {name}")
        for x, y, z in box:
            lines.append(f"v {x} {y} {z}")
        faces = faces_of(base) if faces_of else [f"f {base + 1} {base + 2} {base + 3}", f"f {base + 1} {base + 3} "
                                                 f"{base + 4}", f"f {base + 5} {base + 6} {base + 7}",
                                                 f"f {base + 2} {base + 6} {base + 7}"]
        lines.extend(faces)
        base += len(box)
    return ("\n".join(lines) + "\n" + extra).encode()


def _box(x0: float, y0: float, z0: float, sx: float = 1.0, sy: float = 1.0, sz: float = 1.0):
    return [(x0 + sx * (k & 1), y0 + sy * ((k >> 1) & 1), z0 + sz * ((k >> 2) & 1)) for k in range(8)]


BOX_TRIANGLES = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1), (2, 3, 7), (2, 7, 6),
                 (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]


def glb(doc_edit: Callable[[dict], None] | None = None, names=("seat", "leg"), raw: str | None = None) -> bytes:
    """A small GLB of boxes (one node and mesh per name), its JSON edited by ``doc_edit``;
    ``raw`` replaces the string ``"@"`` in the JSON text (numbers JSON cannot hold)."""
    positions = b"".join(struct.pack("<3f", *p) for p in _box(0, 0, 0, 1, 0.2, 1))
    indices = b"".join(struct.pack("<3H", *t) for t in BOX_TRIANGLES)
    binary = positions + indices
    doc: dict = {
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": len(binary)}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": len(positions)},
                        {"buffer": 0, "byteOffset": len(positions), "byteLength": len(indices)}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 0.2, 1]},
                      {"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"}],
        "meshes": [{"name": f"{n}_mesh", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}
                   for n in names],
        "nodes": [{"name": n, "mesh": i, "translation": [0, 0.5 * i, 0]} for i, n in enumerate(names)],
        "scenes": [{"nodes": list(range(len(names)))}],
        "scene": 0,
    }
    if doc_edit:
        doc_edit(doc)
    text = json.dumps(doc).replace('"@"', raw if raw is not None else '"@"').encode()
    text += b" " * (-len(text) % 4)
    binary += b"\0" * (-len(binary) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(binary), 0x004E4942) + binary
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


SA_TABLE = """Assembly Program_0 {
	bbox = Cuboid(1.9, 0.3, 0.5, True)
	top = Cuboid(1.6, 0.06, 0.47, True)
	leg = Cuboid(0.13, 0.29, 0.47, True)
	attach(top, bbox, 0.5, 1.0, 0.5, 0.5, 1.0, 0.5)
	squeeze(leg, bbox, top, bot, 0.035, 0.5)
	reflect(leg, X)
}
"""

TINY_SEED = "scale_1d(top, origin=(0, 0.725, 0), dir=(1, 0, 0), amount={amount})"


def _program(ops, parameters=None, **extra) -> bytes:
    data = {"format": "parsel.program", "version": 1,
            "parameters": [{"name": "x", "lo": 0, "hi": 0.5, "default": 0}] if parameters is None else parameters,
            "ops": ops, "metadata": {}}
    data.update(extra)
    return json.dumps(data).encode()


def _op(amount="x", operand="top", **fields) -> dict:
    return {"op": "scale_1d", "operand": operand, "amount": amount, "origin": [0, 0.725, 0], "dir": [1, 0, 0],
            **fields}


def family_numbers(rng: random.Random) -> Iterator[Case]:
    """1e308, 1e-320 and integers of thousands of digits wherever a number is read."""
    n = rng.choice(EDGE_NUMBERS)
    where = rng.randrange(9)
    if where == 0:  # ShapeAssembly cuboid dimensions
        text = SA_TABLE.replace("0.13, 0.29", f"{n}, 0.29" if rng.random() < 0.5 else f"0.13, {n}")
        yield Case("numbers", ["inspect", "t.sa"], {"t.sa": text.encode()})
    elif where == 1:  # ShapeAssembly attach coordinates
        yield Case("numbers", ["inspect", "t.sa"], {"t.sa": SA_TABLE.replace("0.035", n).encode()})
    elif where == 2:  # GLB node scales and translations
        key = rng.choice(["scale", "translation", "rotation", "matrix"])
        size = {"scale": 3, "translation": 3, "rotation": 4, "matrix": 16}[key]

        def edit(doc, key=key, size=size):
            doc["nodes"][0][key] = ["@"] * size
        yield Case("numbers", ["inspect", "s.glb"], {"s.glb": glb(edit, raw=n)})
    elif where == 3:  # program parameters and ranges
        text = f'{{"format": "parsel.program", "version": 1, "parameters": [{{"name": "x", "lo": 0, "hi": {n}, ' \
               f'"default": 0}}], "ops": [], "metadata": {{}}}}'
        yield Case("numbers", ["check", "tiny_table", "p.json"], {"p.json": text.encode()})
    elif where == 4:  # op origins and directions
        field_name = rng.choice(["origin", "dir"])
        text = _program([_op()]).decode().replace('"origin": [0, 0.725, 0]' if field_name == "origin"
                                                  else '"dir": [1, 0, 0]', f'"{field_name}": [{n}, 0, 1]')
        yield Case("numbers", ["evaluate", "tiny_table", "p.json", "--set", "x=0.2"], {"p.json": text.encode()})
    elif where == 5:
        yield Case("numbers", ["evaluate", "tiny_table", "p.json", "--set", f"x={n}"], {"p.json": _program([_op()])})
    elif where == 6:  # text programs: param lines
        text = f"param x in [0, {n}] default 0\n" + TINY_SEED.format(amount="x") + "\n"
        yield Case("numbers", ["check", "tiny_table", "p.txt"], {"p.txt": text.encode()})
    elif where == 7:  # OBJ vertices
        body = _obj({"seat": _box(0, 0, 0), "leg": _box(0, 1, 0)}).decode().replace("v 0 0 0", f"v {n} 0 0", 1)
        yield Case("numbers", ["inspect", "s.obj"], {"s.obj": body.encode()})
    else:  # --tau
        yield Case("numbers", ["edit", "tiny_table", "--seed", TINY_SEED.format(amount="x"), "--tau", n, "-o", "out"],
                   cheap=False)


def family_amounts(rng: random.Random) -> Iterator[Case]:
    """Amounts that overflow, divide by zero, nest 100k deep or hide comments."""
    amount = rng.choice(BAD_AMOUNTS + ["(" * 100_000 + "x" + ")" * 100_000, "-" * 100_000 + "x"])
    how = rng.randrange(4)
    if how == 0:
        yield Case("amounts", ["check", "tiny_table", "p.json"], {"p.json": _program([_op(amount)])})
    elif how == 1:
        text = "param x in [0, 0.5]\n" + TINY_SEED.format(amount=amount.replace("\n", " ")) + "\n"
        yield Case("amounts", ["convert", "p.txt", "p.json"], {"p.txt": text.encode()})
    elif how == 2:
        yield Case("amounts", ["convert", "p.json", "p.txt"], {"p.json": _program([_op(amount)])})
    else:
        yield Case("amounts", ["edit", "tiny_table", "--seed", TINY_SEED.format(amount=amount), "-o", "out"])


def family_groups(rng: random.Random) -> Iterator[Case]:
    """Group ops with count changes of 1e7, inf, NaN and steps that round to zero."""
    amount = rng.choice(["1e9*x", "1e7", "-1e7*x", "x*1e300", "inf*x", "nan", "-0.9999999999*x", "-x", "-1+0*x",
                         "1e-320*x", "2*x", "-2*x", "(-1)**0.5*x"])
    op = rng.choice(["change_count", "change_delta"])
    mode = rng.choice(["top_down", "bottom_up"])
    ops = [{"op": op, "operand": "translation_0", "amount": amount, "mode": mode}]
    cmd = rng.choice([["check", "shelf", "p.json", "--samples", "5"], ["evaluate", "shelf", "p.json", "--set", "x=1"],
                      ["render", "shelf", "p.json", "-o", "strip.png", "--frames", "2"]])
    yield Case("groups", cmd, {"p.json": _program(ops, [{"name": "x", "lo": 0, "hi": 1, "default": 0}])},
               cheap=cmd[0] != "render")


def family_structure(rng: random.Random) -> Iterator[Case]:
    """GLB cycles, indices out of range, too many parts, faces or ops, JSON of the wrong type."""
    kind = rng.randrange(17)
    if kind == 0:
        def cycle(doc):
            doc["nodes"][0]["children"] = [1]
            doc["nodes"][1]["children"] = [0]
        yield Case("structure", ["inspect", "s.glb"], {"s.glb": glb(cycle)})
    elif kind == 1:
        def self_loop(doc):
            doc["nodes"][1]["children"] = [rng.choice([1, 7, -1, "0", 1.5])]
        yield Case("structure", ["inspect", "s.glb"], {"s.glb": glb(self_loop)})
    elif kind == 2:
        def huge(doc):
            doc["accessors"][rng.randrange(2)]["count"] = rng.choice([10**9, -3, "8", 2**70])
        yield Case("structure", ["inspect", "s.glb"], {"s.glb": glb(huge)})
    elif kind == 3:  # OBJ faces out of range
        body = _obj({"seat": _box(0, 0, 0), "leg": _box(0, 1, 0)}, extra=f"f 1 2 {rng.choice([99, -99, 0])}\n")
        yield Case("structure", ["inspect", "s.obj"], {"s.obj": body})
    elif kind == 4:  # OBJ with two objects of one name
        body = _obj({"seat": _box(0, 0, 0), "leg": _box(0, 1, 0)}) + _obj({"seat": _box(3, 0, 0)}).replace(
            b"f 1 ", b"f 17 ").replace(b" 2 ", b" 18 ").replace(b" 3", b" 19").replace(b" 4\n", b" 20\n")
        yield Case("structure", ["inspect", "s.obj"], {"s.obj": body})
    elif kind == 5:  # PLY with a part index past the end
        ply = ("ply\nformat ascii 1.0\ncomment part 0 seat\ncomment part 1 leg\nelement vertex 3\nproperty float x\n"
               "property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\n"
               f"property int part\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 {rng.choice([2, 9, -1])} "
               f"{rng.choice([0, 5, -1])}\n")
        yield Case("structure", ["inspect", "s.ply"], {"s.ply": ply.encode()})
    elif kind == 6:  # OFF with counts that lie
        off = (f"OFF\n# part 0 seat\n# part {rng.choice([1, 0, 99999999999])} leg\n{rng.choice([4, 99, -1])} 2 0\n"
               "0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2 0\n3 0 2 3 1\n")
        yield Case("structure", ["inspect", "s.off"], {"s.off": off.encode()})
    elif kind == 7:  # STL garbage
        stl = rng.choice([b"solid seat\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nendloop\nendfacet\n",
                          b"\0" * 80 + struct.pack("<I", 10**8), b"solid a\nendsolid a\nsolid a\nendsolid a\n"])
        yield Case("structure", ["inspect", "s.stl"], {"s.stl": stl})
    elif kind == 8:  # many parts
        count = rng.choice([2100, 5000])
        body = _obj({f"p{i}": _box(i * 2, 0, 0) for i in range(count)})
        yield Case("structure", ["inspect", "--no-detect", "many.obj"], {"many.obj": body})
    elif kind == 9:  # ShapeAssembly of 20,000 lines or 1,000 translate copies
        if rng.random() < 0.5:
            text = SA_TABLE.replace("}\n", "") + "\tattach(top, bbox, 0.5, 1.0, 0.5, 0.5, 1.0, 0.5)\n" * 20_000 + "}\n"
        else:
            text = SA_TABLE.replace("reflect(leg, X)", "translate(leg, X, 1000, 0.9)")
        yield Case("structure", ["inspect", "t.sa"], {"t.sa": text.encode()})
    elif kind == 10:  # programs of 2,000-10,000 ops
        count = rng.choice([2001, 10_000])
        yield Case("structure", ["check", "tiny_table", "p.json"], {"p.json": _program([_op()] * count)})
    elif kind == 11:  # JSON of the wrong type
        bad = rng.choice([{"ops": {"a": 1}}, {"ops": [[1, 2]]}, {"parameters": None}, {"parameters": 3},
                          {"version": True}, {"ops": [_op(operand=7)]}, {"ops": [_op(operand="top\nleg")]},
                          {"ops": [_op(amount=None)]}, {"ops": [_op(dir="xyz")]}, {"metadata": []},
                          {"ops": [{"op": "scale_1d"}]}, {"ops": [_op(feature=5)]}, {"format": None}])
        data = json.loads(_program([_op()]))
        data.update(bad)
        yield Case("structure", ["check", "tiny_table", "p.json"], {"p.json": json.dumps(data).encode()})
    elif kind == 12:  # deep JSON
        depth = rng.choice([100_000, 10_000])
        yield Case("structure", ["check", "tiny_table", "p.json"], {"p.json": b"[" * depth + b"]" * depth})
    elif kind == 14:  # PartNet hierarchies: cycles of ids, missing objs, wrong types, deep nesting
        box = _obj({"p": _box(0, 0, 0)}).replace(b"o p\n", b"")
        leaf = rng.choice([{"id": 1, "name": "seat", "objs": ["a"]}, {"id": 1, "name": "seat", "objs": ["missing"]},
                           {"id": 1, "name": "seat\nx", "objs": ["a"]}, {"id": "1", "name": 5, "objs": "a"},
                           {"id": 1, "name": "seat", "objs": ["../../etc/passwd"]}])
        tree: object = [{"id": 0, "name": "chair", "objs": ["a", "b"], "children": [
            leaf, {"id": 2, "name": "leg", "objs": ["b"]}]}]
        if rng.random() < 0.3:
            tree = rng.choice([{}, [1, 2], "x", [{"id": 0}]])
        text = json.dumps(tree).encode()
        if rng.random() < 0.2:
            text = b'[{"id": 0, "name": "c", "children": ' * 5000 + b"[]" + b"}]" * 5000
        yield Case("structure", ["inspect", "pn"], {"pn/result_after_merging.json": text, "pn/objs/a.obj": box,
                                                   "pn/objs/b.obj": box.replace(b"v 0 ", b"v 3 ")})
    elif kind == 15:  # parsel.shape JSON with wrong types and numbers at the edge
        corners = [[float(k & 1), float((k >> 1) & 1), float((k >> 2) & 1)] for k in range(8)]
        part = {"id": "seat", "label": "seat", "corners": corners}
        bad = rng.choice([{"version": True}, {"parts": {"a": 1}}, {"parts": [{**part, "corners": [[1e308] * 3] * 8}]},
                          {"parts": [{**part, "id": ["x"]}]}, {"parts": [{**part, "corners": [[0, 0]] * 8}]},
                          {"relations": [{"kind": "reflection", "members": ["seat"]}]}, {"parts": None},
                          {"parts": [part, part]}, {"name": {"a": 1}}])
        data = {"format": "parsel.shape", "version": 1, "name": "s", "parts": [part], "relations": []}
        data.update(bad)
        text = json.dumps(data)
        if "1e308" in rng.choice(["", "1e308"]):
            text = text.replace("1.0", "1" + "0" * 400, 1)
        yield Case("structure", ["inspect", "s.shape.json"], {"s.shape.json": text.encode()})
    else:  # a sidecar of the wrong shape
        sidecar = rng.choice([b"[1, 2]", b'{"seat": 5}', b'{"seat": "a\\nb"}', b"{" * 50_000, b"\xff\xfe"])
        body = _obj({"seat": _box(0, 0, 0), "leg": _box(0, 1, 0)})
        yield Case("structure", ["inspect", "s.obj"], {"s.obj": body, "s.labels.json": sidecar})


def family_names(rng: random.Random) -> Iterator[Case]:
    """Hostile part names through inspect, the page and the offline provider's prompt."""
    name = rng.choice(BAD_NAMES)
    body = _obj({name: _box(0, 0, 0), "leg": _box(0, 1.5, 0)})
    how = rng.randrange(3)
    if how == 0:
        yield Case("names", ["inspect", "--json", "s.obj"], {"s.obj": body})
    elif how == 1:
        yield Case("names", ["edit", "s.obj", f"make the {name} wider", "-o", "out"], {"s.obj": body}, cheap=False)
    else:
        yield Case("names", ["inspect", "s.glb"], {"s.glb": glb(names=(name, "leg"))})


def family_arguments(rng: random.Random) -> Iterator[Case]:
    """Flags out of range: ports, sample counts, output paths, providers, Dask addresses."""
    argv = rng.choice([
        ["view", "out", "--port", rng.choice(["-1", "70000", "99999999999", "abc", "22", "80"]), "--no-browser"],
        ["check", "tiny_table", "p.json", "--samples", rng.choice(["0", "-5", "1e7", "10000000", "1"])],
        ["apply", "tiny_table", "p.json", "--sweep", rng.choice(["0", "-1", "1000000"]), "-o", "e.obj"],
        ["edit", "tiny_table", "--seed", TINY_SEED.format(amount="x"), "-o", rng.choice(["", ".", "./", "..", "/"])],
        ["edit", "tiny_table", "make it wider", "--provider", "replay", "--replay",
         rng.choice(["missing.jsonl", "p.json", "bad.jsonl"]), "-o", "out"],
        ["batch", "cases.jsonl", "-o", "res", "--dask", rng.choice(["nonsense", "tcp://:-1", "tcp://[::1", "::::"])],
        ["render", "tiny_table", "p.json", "-o", "s.png", "--frames", rng.choice(["0", "-3", "100000"])],
        ["render", "tiny_table", "p.json", "-o", "s.png", "--remesh", "--resolution", rng.choice(["0", "-1", "5000"])],
        ["apply", "tiny_table", "p.json", "--set", rng.choice(["x=nan", "x=1e999", "y=1", "x", "=1"]), "-o", "e.obj"],
    ])
    files = {"p.json": _program([_op()]), "bad.jsonl": b"{not json\n",
             "cases.jsonl": b'{"id": "a", "shape": "tiny_table", "seed": "' + TINY_SEED.format(amount="x").encode()
             + b'"}\n', "notes.txt": b"the user's notes"}
    yield Case("arguments", argv, files, cheap=argv[0] not in ("render",))


def family_outputs(rng: random.Random) -> Iterator[Case]:
    """-o onto folders that hold a user's files, for commands that succeed and commands that fail."""
    files = {"mydocs/thesis.txt": b"years of work", "mydocs/photos/a.jpg": b"\xff\xd8",
             "p.json": _program([_op()])}
    good = rng.random() < 0.5
    seed = TINY_SEED.format(amount="x" if good else "x/0")
    argv = rng.choice([["edit", "tiny_table", "--seed", seed, "-o", "mydocs"],
                       ["edit", "tiny_table", "--seed", seed, "-o", "mydocs", "--force"],
                       ["edit", "tiny_table", "make it fly", "-o", "mydocs"],
                       ["proxydural", "tiny_table", "-n", "1", "-o", "mydocs"],
                       ["apply", "tiny_table", "p.json", "-o", "mydocs"]])
    yield Case("outputs", argv, files, cheap=argv[0] != "proxydural")


def family_batch(rng: random.Random) -> Iterator[Case]:
    """Cases files with broken lines, odd ids and bad seeds."""
    line = rng.choice([b"{not json", b"[1, 2]", b'{"id": 5, "shape": "tiny_table"}', b'{"id": "../x", "shape": '
                       b'"tiny_table", "seed": "x"}', b'{"id": "a", "shape": "tiny_table", "seed": "'
                       + TINY_SEED.format(amount="2**99999").encode() + b'"}', b'{"id": "a"}', b"",
                       b'{"id": "a", "shape": "tiny_table", "request": "make it wider", "samples": 1e308}'])
    yield Case("batch", ["batch", "cases.jsonl", "-o", "res", "--no-progress"], {"cases.jsonl": line + b"\n"})


FAMILIES: dict[str, Callable[[random.Random], Iterator[Case]]] = {
    "numbers": family_numbers, "amounts": family_amounts, "groups": family_groups, "structure": family_structure,
    "names": family_names, "arguments": family_arguments, "outputs": family_outputs, "batch": family_batch,
}


def generate(count: int, seed: int = 0, cheap_only: bool = False) -> list[Case]:
    """``count`` cases drawn round-robin over the families, reproducibly from ``seed``."""
    rng = random.Random(seed)
    cases: list[Case] = []
    names = sorted(FAMILIES)
    attempts = 0
    while len(cases) < count and attempts < count * 50:
        family = names[attempts % len(names)]
        attempts += 1
        for case in FAMILIES[family](rng):
            if not cheap_only or case.cheap:
                cases.append(case)
    return cases[:count]


def largest_cases() -> list[Case]:
    """Inputs at (just under) the default limits: they must be accepted, in bounded time and memory."""
    import trimesh

    scene = trimesh.Scene()
    seat = trimesh.creation.icosphere(subdivisions=6)  # 81,920 triangles each: 245,760 of max_faces 300,000
    for i, name in enumerate(("seat", "back", "arm")):
        scene.add_geometry(seat.copy().apply_translation((0, 2.5 * i, 0)), node_name=name, geom_name=name)
    parts = _obj({f"p{i}": _box(i * 2, 0, 0) for i in range(300)})  # max_detect_parts
    ops = _program([_op(amount=f"{1 + i % 7}e-4*x") for i in range(2000)])  # max_ops
    lines = "param x in [0, 0.5]\n" + "# a comment line\n" * 19_990 + TINY_SEED.format(amount="x") + "\n"
    long_amount = "+".join(["x/1000"] * 190)  # 1,329 characters, 190 deep (max_expression_depth 200)
    groups = _program([{"op": "change_count", "operand": "translation_0", "amount": "990*x", "mode": "top_down"}],
                      [{"name": "x", "lo": 0, "hi": 1, "default": 0}])  # about max_instances
    return [
        Case("largest", ["inspect", "big.glb"], {"big.glb": scene.export(file_type="glb")}, cheap=False),
        Case("largest", ["inspect", "many.obj"], {"many.obj": parts}, cheap=False),
        Case("largest", ["check", "tiny_table", "p.json"], {"p.json": ops}, cheap=False),
        Case("largest", ["check", "tiny_table", "p.txt"], {"p.txt": lines.encode()}, cheap=False),
        Case("largest", ["check", "tiny_table", "p.json"], {"p.json": _program([_op(amount=long_amount)])},
             cheap=False),
        Case("largest", ["evaluate", "shelf", "g.json", "--set", "x=1"], {"g.json": groups}, cheap=False),
        Case("largest", ["check", "tiny_table", "p.json", "--samples", "10000"], {"p.json": _program([_op()])},
             cheap=False),
    ]


# -- running -------------------------------------------------------------------------------------


@dataclass
class Outcome:
    case: Case
    status: str  # clean, traceback, unclean-exit, hang, memory, partial, lost, staging
    rc: int | None
    seconds: float
    peak_mib: float
    stderr: str


def _snapshot(folder: Path) -> dict[str, str]:
    out = {}
    for path in sorted(folder.rglob("*")):
        rel = str(path.relative_to(folder))
        out[rel] = "dir" if path.is_dir() else hashlib.sha256(path.read_bytes()).hexdigest()
    return out


def _child(case: Case, folder: Path, memory_bytes: int, seconds: float) -> None:
    """In the forked process: limits, a fresh folder, the command; never returns."""
    try:
        os.chdir(folder)
        os.setpgid(0, 0)
        resource.setrlimit(resource.RLIMIT_AS, (memory_bytes, memory_bytes))
        signal.alarm(int(seconds) + 1)
        out = os.open("stdout.fuzz", os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        err = os.open("stderr.fuzz", os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        os.dup2(out, 1)
        os.dup2(err, 2)
        sys.stdout = os.fdopen(1, "w", buffering=1)
        sys.stderr = os.fdopen(2, "w", buffering=1)
        from parsel_core.cli import main

        rc = main(case.argv)
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(rc)
    except SystemExit as exc:  # argparse
        code = exc.code if isinstance(exc.code, int) else 1
        sys.stderr.flush()
        os._exit(code)
    except MemoryError:
        os._exit(137)
    except BaseException:
        import traceback

        traceback.print_exc()
        sys.stderr.flush()
        os._exit(1)


def run_case(case: Case, root: Path, seconds: float = 60.0, memory_mib: int = 4096) -> Outcome:
    """Run one case in a fresh folder under ``root`` and judge it (module docstring)."""
    folder = Path(tempfile.mkdtemp(dir=root))
    for name, data in case.files.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_bytes(data)
    before = _snapshot(folder)
    base = _address_space()
    started = time.monotonic()
    pid = os.fork()
    if pid == 0:
        _child(case, folder, base + memory_mib * 2**20, seconds)
    status, rusage, hung = 0, None, False
    while True:
        done, status, rusage = os.wait4(pid, os.WNOHANG)
        if done:
            break
        if time.monotonic() - started > seconds + 5:
            hung = True
            try:
                os.killpg(pid, signal.SIGKILL)
            except OSError:
                os.kill(pid, signal.SIGKILL)
            _, status, rusage = os.wait4(pid, 0)
            break
        time.sleep(0.005)
    elapsed = time.monotonic() - started
    try:  # whatever the case started in its process group (batch workers) goes with it
        os.killpg(pid, signal.SIGKILL)
    except OSError:
        pass
    stderr = (folder / "stderr.fuzz").read_text(errors="replace") if (folder / "stderr.fuzz").exists() else ""
    for name in ("stdout.fuzz", "stderr.fuzz"):
        (folder / name).unlink(missing_ok=True)
    rc = os.waitstatus_to_exitcode(status)
    peak = rusage.ru_maxrss / 1024 if rusage else 0.0
    verdict = _judge(case, folder, before, rc, stderr, hung)
    shutil.rmtree(folder, ignore_errors=True)
    return Outcome(case, verdict, rc, elapsed, peak, stderr)


def _judge(case: Case, folder: Path, before: dict[str, str], rc: int, stderr: str, hung: bool) -> str:
    if hung or rc == -signal.SIGALRM:
        return "hang"
    if rc in (137, -signal.SIGKILL) or ("Traceback" in stderr and "MemoryError" in stderr):
        return "memory"
    if "Traceback (most recent call last)" in stderr:
        return "traceback"
    lines = [line for line in stderr.splitlines() if line.strip()]
    if rc == 2:
        one_line = len(lines) == 1 and lines[0].startswith("parsel: error: ")
        usage = bool(lines) and lines[0].startswith("usage:") and ": error: " in lines[-1]
        if not (one_line or usage):
            return "unclean-exit"
    elif rc != 0 and not (case.argv[0] in ("batch", "eval") and rc == 1):  # batch: 1 when a case failed
        return "unclean-exit"
    after = _snapshot(folder)
    if any((".parsel-" in name and not name.endswith(".parsel-manifest.json")) or ".staging-" in name
           for name in after):
        return "staging"
    user = {k: v for k, v in before.items() if not k.startswith("out")}
    if any(after.get(k) != v for k, v in user.items()):
        return "lost"
    if rc != 0 and not (case.argv[0] == "batch" and rc == 1):  # batch records its failed cases
        extra = {k for k in after if k not in before and not k.endswith(".failed-record.jsonl")}
        if extra or any(after.get(k) != v for k, v in before.items()):
            return "partial"
    return "clean"


def _address_space() -> int:
    """This process's virtual size in bytes (the child's memory limit is on top of it)."""
    with open("/proc/self/statm") as handle:
        return int(handle.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")


def warm_up() -> None:
    """Load plugins and the CAS backend once, so forked cases start warm."""
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    from parsel_core.cli import build_parser
    from parsel_core.loading import load_shape
    from parsel_core.plugins import get_cas_backend, solvers

    build_parser()
    solvers()
    get_cas_backend(None)
    load_shape("tiny_table")


def run_all(cases: list[Case], seconds: float = 60.0, memory_mib: int = 4096,
            progress: Callable[[int, Outcome], None] | None = None,
            outcomes: list[Outcome] | None = None) -> list[Outcome]:
    """Run ``cases`` one after the other; outcomes are appended to ``outcomes`` as they come."""
    warm_up()
    outcomes = [] if outcomes is None else outcomes
    with tempfile.TemporaryDirectory(prefix="parsel-fuzz-") as root:
        for i, case in enumerate(cases):
            outcome = run_case(case, Path(root), seconds, memory_mib)
            outcomes.append(outcome)
            if progress:
                progress(i, outcome)
    return outcomes


def table(outcomes: list[Outcome]) -> str:
    """One row per family: runs, outcome counts, median and worst seconds, peak memory."""
    by_family: dict[str, list[Outcome]] = defaultdict(list)
    for outcome in outcomes:
        by_family[outcome.case.family].append(outcome)
    kinds = ["clean", "traceback", "unclean-exit", "hang", "memory", "partial", "lost", "staging"]
    header = f"{'family':<11}{'runs':>6}" + "".join(f"{k:>13}" for k in kinds) + f"{'median s':>10}{'max s':>8}" \
             f"{'peak MiB':>10}"
    rows = [header, "-" * len(header)]
    for family in sorted(by_family) + ["all"]:
        group = outcomes if family == "all" else by_family[family]
        counts = Counter(o.status for o in group)
        times = sorted(o.seconds for o in group)
        rows.append(f"{family:<11}{len(group):>6}" + "".join(f"{counts.get(k, 0):>13}" for k in kinds)
                    + f"{times[len(times) // 2]:>10.2f}{times[-1]:>8.1f}{max(o.peak_mib for o in group):>10.0f}")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cases", type=int, default=3000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--seconds", type=float, default=60.0, help="per-run time limit")
    parser.add_argument("--memory-mib", type=int, default=4096, help="per-run memory limit (above the warm parent)")
    parser.add_argument("--cheap", action="store_true", help="only the cases the test subset draws from")
    parser.add_argument("--show", type=int, default=5, help="failures to print in full")
    parser.add_argument("--no-largest", dest="largest", action="store_false",
                        help="skip the runs of the largest accepted inputs")
    args = parser.parse_args(argv)
    cases = generate(args.cases, args.seed, args.cheap)
    started = time.monotonic()

    def progress(i: int, outcome: Outcome) -> None:
        if outcome.status != "clean":
            print(f"[{i}] {outcome.status} rc={outcome.rc} {outcome.case.family}: {outcome.case.argv[:6]!r}: "
                  f"{outcome.stderr.strip().splitlines()[-1:] if outcome.stderr.strip() else ''}", flush=True)
        elif (i + 1) % 100 == 0:
            print(f"... {i + 1} cases, {time.monotonic() - started:.0f} s", flush=True)

    outcomes: list[Outcome] = []
    try:
        run_all(cases, args.seconds, args.memory_mib, progress, outcomes)
    except KeyboardInterrupt:  # SIGINT: report what ran
        print(f"\ninterrupted after {len(outcomes)} of {len(cases)} cases")
        args.largest = False
    print(f"\n{len(outcomes)} cases (seed {args.seed}), {time.monotonic() - started:.0f} s wall, "
          f"per-run limits {args.seconds:g} s and {args.memory_mib} MiB")
    print(table(outcomes))
    bad = [o for o in outcomes if o.status != "clean"]
    for outcome in bad[:args.show]:
        print(f"\n--- {outcome.status}: {outcome.case.argv!r}\n{outcome.stderr[-2000:]}")
    peak = max((o.peak_mib for o in outcomes), default=0)
    print(f"\npeak RSS of one run: {peak:.0f} MiB; failures: {len(bad)}")
    if args.largest:
        largest = run_all(largest_cases(), args.seconds, args.memory_mib)
        print("\nlargest accepted inputs (at the default limits): each must exit 0")
        print(f"{'command':<58}{'status':>8}{'rc':>4}{'seconds':>9}{'peak MiB':>10}")
        for outcome in largest:
            ok = outcome.status == "clean" and outcome.rc == 0
            bad += [] if ok else [outcome]
            print(f"{' '.join(outcome.case.argv)[:57]:<58}{outcome.status:>8}{outcome.rc:>4}{outcome.seconds:>9.1f}"
                  f"{outcome.peak_mib:>10.0f}")
        print(f"peak RSS for the largest accepted inputs: {max(o.peak_mib for o in largest):.0f} MiB")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
