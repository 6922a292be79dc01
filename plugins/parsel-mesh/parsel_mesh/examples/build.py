"""Generate the bundled example assets (chair, table, cabinet, shelf) as GLB scenes.

Each asset is a scene of named parts, one mesh per part, where the node name, the
geometry name and the part name are the same string: ``label`` for unique parts and
``label.NNN`` for repeated ones.  Vertices are stored in world coordinates under
identity node transforms so that consumers which ignore the scene graph still see
the assembled object.

Conventions the relation detectors rely on: metres, +y up, floor at y = 0 (parts that
stand on the floor have min y exactly 0), +x right, +z front, every asset centred on
x = 0.  Attached parts overlap by a few millimetres instead of leaving gaps, mirrored
parts are built by reflecting a partner's vertices, and repeated parts are translated
copies of the first one.

The output is byte-deterministic: all trigonometry goes through :mod:`math` and the
mesh topology is built in a fixed order, so regenerating must reproduce the
committed files exactly.

Run as ``python -m parsel_mesh.examples.build`` (with the plugin directory on
``sys.path``) or as ``python build.py``; files are written next to this module unless
``--out`` is given.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from trimesh.visual import TextureVisuals
from trimesh.visual.material import PBRMaterial

EXAMPLES_DIR = Path(__file__).resolve().parent

Vec3 = tuple[float, float, float]

ARC_SEGMENTS = 3
"""Segments per 45 degrees of a rounded edge (six per quarter round)."""

MAX_STEP = 0.1
"""Longest flat span (m) left undivided, so that deformations have vertices to move."""

CYLINDER_SEGMENTS = 32
CYLINDER_RING_STEP = 0.05


@dataclass(frozen=True)
class Material:
    """PBR parameters for one part label."""

    rgba: tuple[int, int, int, int]
    metallic: float = 0.0
    roughness: float = 0.7


MATERIALS: dict[str, Material] = {
    "seat": Material((196, 150, 104, 255)),
    "leg": Material((120, 84, 52, 255)),
    "back_upright": Material((120, 84, 52, 255)),
    "back_rail": Material((150, 108, 70, 255)),
    "back_slat": Material((176, 132, 88, 255)),
    "top": Material((205, 170, 125, 255)),
    "apron": Material((150, 108, 70, 255)),
    "body": Material((232, 228, 218, 255)),
    "door": Material((170, 186, 196, 255)),
    "handle": Material((190, 190, 196, 255), metallic=1.0, roughness=0.3),
    "plinth": Material((70, 70, 74, 255)),
    "side_panel": Material((186, 146, 102, 255)),
    "board": Material((210, 176, 130, 255)),
    "back_panel": Material((236, 226, 206, 255)),
}


@dataclass(frozen=True)
class Part:
    """A named part mesh in world coordinates."""

    name: str
    mesh: trimesh.Trimesh

    @property
    def label(self) -> str:
        """The part name without its repeat index."""
        return self.name.split(".", 1)[0]


def part_name(label: str, index: int | None = None) -> str:
    """Name a part: plain label when unique, ``label.NNN`` when repeated."""
    return label if index is None else f"{label}.{index:03d}"


# --------------------------------------------------------------------------- meshes


def _mesh(vertices: np.ndarray, faces: np.ndarray) -> trimesh.Trimesh:
    """Wrap arrays without trimesh's processing, which could reorder vertices."""
    return trimesh.Trimesh(
        vertices=np.ascontiguousarray(vertices, dtype=np.float64),
        faces=np.ascontiguousarray(faces, dtype=np.int64),
        process=False,
    )


def _axis_samples(lo: float, hi: float, radius: float) -> list[float]:
    """Grid coordinates along one box axis: tangent-spaced in the rounded ends.

    Offsets ``r*tan(theta)`` make the projected rounded edge uniform in angle; the
    ends are pinned to ``lo``/``hi`` exactly so flat faces land on their planes.
    """
    offsets = [
        radius * math.tan(j * math.pi / (4 * ARC_SEGMENTS))
        for j in range(1, ARC_SEGMENTS)
    ]
    inner_lo, inner_hi = lo + radius, hi - radius
    span = inner_hi - inner_lo
    divisions = max(1, math.ceil(span / MAX_STEP - 1e-9))
    flat = [inner_lo + span * i / divisions for i in range(divisions)] + [inner_hi]
    return (
        [lo]
        + [inner_lo - e for e in reversed(offsets)]
        + flat
        + [inner_hi + e for e in offsets]
        + [hi]
    )


def _grid_surface(shape: tuple[int, int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Quad-triangulate the boundary of an index grid, outward facing and watertight.

    Returns the integer grid coordinates of each surface vertex and the faces.
    Vertices are keyed by their grid index so shared edges are merged exactly.
    """
    index: dict[tuple[int, int, int], int] = {}
    faces: list[tuple[int, int, int]] = []

    def vertex(ijk: tuple[int, int, int]) -> int:
        return index.setdefault(ijk, len(index))

    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3
        for side in (0, shape[a] - 1):
            for u in range(shape[b] - 1):
                for v in range(shape[c] - 1):
                    quad = []
                    for du, dv in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        ijk = [0, 0, 0]
                        ijk[a], ijk[b], ijk[c] = side, u + du, v + dv
                        quad.append(vertex((ijk[0], ijk[1], ijk[2])))
                    if side == 0:
                        quad.reverse()
                    faces.append((quad[0], quad[1], quad[2]))
                    faces.append((quad[0], quad[2], quad[3]))
    return np.array(list(index), dtype=np.int64), np.array(faces, dtype=np.int64)


def rounded_box(lo: Vec3, hi: Vec3, radius: float) -> trimesh.Trimesh:
    """Axis-aligned box from ``lo`` to ``hi`` with edges rounded by ``radius``.

    Built as a subdivided cube whose grid points are pushed onto the rounded
    surface (clamp to the inner box, then step ``radius`` along the offset), which
    keeps it watertight and lets a face sitting on ``lo`` stay exactly on that plane.
    """
    extents = [h - low for low, h in zip(lo, hi, strict=True)]
    if not 0.0 < radius < min(extents) / 2:
        raise ValueError(
            f"radius {radius} must be positive and below half of {extents}"
        )
    samples = [np.array(_axis_samples(lo[k], hi[k], radius)) for k in range(3)]
    grid, faces = _grid_surface((len(samples[0]), len(samples[1]), len(samples[2])))
    pos = np.column_stack([samples[k][grid[:, k]] for k in range(3)])
    inner = np.clip(pos, np.array(lo) + radius, np.array(hi) - radius)
    offset = pos - inner
    length = np.sqrt(
        offset[:, 0] * offset[:, 0]
        + offset[:, 1] * offset[:, 1]
        + offset[:, 2] * offset[:, 2]
    )
    vertices = inner + offset * (radius / length)[:, None]
    return _mesh(vertices, faces)


_AXES = {"x": (1, 2, 0), "y": (0, 1, 2), "z": (2, 0, 1)}
"""Cyclic (orientation-preserving) maps from a y-aligned local frame to world axes."""


def frustum(
    base: Vec3, axis: str, length: float, radius_start: float, radius_end: float
) -> trimesh.Trimesh:
    """Capped, possibly tapered cylinder from ``base`` along +``axis``.

    Intermediate rings every few centimetres give deformations vertices to move.
    """
    n = CYLINDER_SEGMENTS
    rings = max(1, math.ceil(length / CYLINDER_RING_STEP - 1e-9))
    circle = [
        (math.cos(2 * math.pi * i / n), math.sin(2 * math.pi * i / n)) for i in range(n)
    ]
    local: list[tuple[float, float, float]] = []
    for k in range(rings + 1):
        t = k / rings
        r = radius_start + (radius_end - radius_start) * t
        local.extend((r * c, length * t, r * s) for c, s in circle)
    local.append((0.0, 0.0, 0.0))
    local.append((0.0, length, 0.0))
    bottom, top = len(local) - 2, len(local) - 1

    faces: list[tuple[int, int, int]] = []
    for k in range(rings):
        for i in range(n):
            j = (i + 1) % n
            a, b, c, d = k * n + i, (k + 1) * n + i, (k + 1) * n + j, k * n + j
            faces.append((a, b, c))
            faces.append((a, c, d))
    for i in range(n):
        j = (i + 1) % n
        faces.append((bottom, i, j))
        faces.append((top, rings * n + j, rings * n + i))

    vertices = np.array(local)[:, list(_AXES[axis])] + np.array(base)
    return _mesh(vertices, np.array(faces))


def mirrored(mesh: trimesh.Trimesh, axis: int) -> trimesh.Trimesh:
    """Exact mirror image about the plane ``coordinate[axis] = 0``.

    Negation is exact in floating point, and reversing each face restores outward
    winding, so the partner is a true reflection rather than a rebuilt look-alike.
    """
    vertices = mesh.vertices.copy()
    vertices[:, axis] = -vertices[:, axis]
    return _mesh(vertices, mesh.faces[:, ::-1])


def translated(mesh: trimesh.Trimesh, offset: Vec3) -> trimesh.Trimesh:
    """Copy of ``mesh`` moved by ``offset`` with identical topology."""
    return _mesh(mesh.vertices + np.array(offset), mesh.faces.copy())


def _mirror_pair(
    label: str, first: trimesh.Trimesh, axis: int, start: int = 0
) -> list[Part]:
    """Return a part and its mirror across ``axis`` as ``start`` and ``start + 1``."""
    return [
        Part(part_name(label, start), first),
        Part(part_name(label, start + 1), mirrored(first, axis)),
    ]


def _row(label: str, first: trimesh.Trimesh, step: Vec3, count: int) -> list[Part]:
    """``count`` evenly spaced translated copies of ``first``."""
    return [
        Part(
            part_name(label, k),
            first if k == 0 else translated(first, tuple(k * s for s in step)),
        )
        for k in range(count)
    ]


# --------------------------------------------------------------------------- assets

X, Y, Z = 0, 1, 2


def build_chair() -> list[Part]:
    """Dining chair: seat top at 0.45 m, four tapered legs, slatted back to 0.90 m.

    Legs sit 5 mm inside the seat; uprights and slats enter the seat top by 5 mm;
    slats enter the back rail by 5 mm and the rail enters both uprights by 7.5 mm.
    """
    seat_top, seat_thickness = 0.45, 0.04
    seat_bottom = seat_top - seat_thickness
    leg_x, leg_z = 0.19, 0.18
    back_z = -0.19

    seat = rounded_box((-0.23, seat_bottom, -0.22), (0.23, seat_top, 0.22), 0.01)
    leg = frustum((-leg_x, 0.0, leg_z), "y", seat_bottom + 0.005, 0.014, 0.018)
    front_legs = _mirror_pair("leg", leg, X)
    back_left = mirrored(leg, Z)
    back_legs = _mirror_pair("leg", back_left, X, start=2)

    upright = rounded_box(
        (-leg_x - 0.0175, seat_top - 0.005, back_z - 0.015),
        (-leg_x + 0.0175, 0.90, back_z + 0.015),
        0.005,
    )
    rail = rounded_box((-0.18, 0.80, back_z - 0.01), (0.18, 0.86, back_z + 0.01), 0.004)
    slat = rounded_box(
        (-0.14, seat_top - 0.005, back_z - 0.005), (-0.10, 0.805, back_z + 0.005), 0.003
    )
    return [
        Part("seat", seat),
        *front_legs,
        *back_legs,
        *_mirror_pair("back_upright", upright, X),
        Part("back_rail", rail),
        *_row("back_slat", slat, (0.06, 0.0, 0.0), 5),
    ]


def build_table() -> list[Part]:
    """Dining table 1.2 x 0.75 m, top surface at 0.75 m, legs joined by four aprons.

    Legs and aprons enter the top by 5 mm; each apron enters its two legs by 5 mm.
    """
    top_y, top_thickness = 0.75, 0.04
    joint_y = top_y - top_thickness + 0.005
    top = rounded_box((-0.6, top_y - top_thickness, -0.375), (0.6, top_y, 0.375), 0.01)

    leg = rounded_box((-0.555, 0.0, 0.28), (-0.505, joint_y, 0.33), 0.006)
    legs = _mirror_pair("leg", leg, X) + _mirror_pair(
        "leg", mirrored(leg, Z), X, start=2
    )

    front_apron = rounded_box(
        (-0.51, joint_y - 0.08, 0.30), (0.51, joint_y, 0.32), 0.003
    )
    left_apron = rounded_box(
        (-0.545, joint_y - 0.08, -0.285), (-0.525, joint_y, 0.285), 0.003
    )
    aprons = _mirror_pair("apron", front_apron, Z) + _mirror_pair(
        "apron", left_apron, X, start=2
    )
    return [Part("top", top), *legs, *aprons]


def build_cabinet() -> list[Part]:
    """Two-door cabinet 0.8 x 0.9 x 0.45 m on a recessed plinth.

    The body sits 5 mm into the plinth, doors 2 mm into the body front and each
    handle 2 mm into its door near the door's free (centre) edge.
    """
    plinth = rounded_box((-0.38, 0.0, -0.2), (0.38, 0.08, 0.18), 0.003)
    body = rounded_box((-0.4, 0.075, -0.225), (0.4, 0.9, 0.2), 0.004)
    door = rounded_box((-0.397, 0.09, 0.198), (-0.0015, 0.885, 0.218), 0.003)
    handle = rounded_box((-0.047, 0.62, 0.216), (-0.033, 0.78, 0.24), 0.004)
    return [
        Part("body", body),
        *_mirror_pair("door", door, X),
        *_mirror_pair("handle", handle, X),
        Part("plinth", plinth),
    ]


def build_shelf() -> list[Part]:
    """Open bookshelf 0.8 x 1.6 x 0.3 m with five boards 0.383 m apart.

    Boards enter both side panels by 5 mm and the back panel by 2 mm; the back panel
    enters the side panels by 3 mm and runs from inside the bottom board to inside
    the top board, whose top is flush with the side panels.
    """
    height, board_thickness, spacing = 1.6, 0.018, 0.383
    bottom = height - board_thickness - 4 * spacing
    side = rounded_box((-0.4, 0.0, -0.15), (-0.382, height, 0.15), 0.003)
    board = rounded_box(
        (-0.387, bottom, -0.143), (0.387, bottom + board_thickness, 0.148), 0.002
    )
    back = rounded_box(
        (-0.385, bottom + 0.005, -0.147), (0.385, height - 0.005, -0.141), 0.001
    )
    return [
        *_mirror_pair("side_panel", side, X),
        *_row("board", board, (0.0, spacing, 0.0), 5),
        Part("back_panel", back),
    ]


ASSETS: dict[str, Callable[[], list[Part]]] = {
    "chair": build_chair,
    "table": build_table,
    "cabinet": build_cabinet,
    "shelf": build_shelf,
}


# --------------------------------------------------------------------------- export


def _material(label: str) -> PBRMaterial:
    """Fresh PBR material named after the label, so exporters keep one per label."""
    spec = MATERIALS[label]
    return PBRMaterial(
        name=label,
        baseColorFactor=list(spec.rgba),
        metallicFactor=spec.metallic,
        roughnessFactor=spec.roughness,
    )


def to_scene(parts: Sequence[Part]) -> trimesh.Scene:
    """Scene with one node per part; node, geometry and part share one name."""
    names = [p.name for p in parts]
    if len(set(names)) != len(names):
        raise ValueError(f"duplicate part names in {names}")
    scene = trimesh.Scene()
    for part in parts:
        mesh = part.mesh.copy()
        mesh.visual = TextureVisuals(material=_material(part.label))
        scene.add_geometry(mesh, node_name=part.name, geom_name=part.name)
    return scene


def asset_bytes(name: str) -> bytes:
    """GLB bytes of one bundled asset."""
    return to_scene(ASSETS[name]()).export(file_type="glb")


def build(
    out_dir: Path = EXAMPLES_DIR, names: Sequence[str] = tuple(ASSETS)
) -> list[Path]:
    """Write ``<name>.glb`` and its pre-fitted parts (``<name>.glb.parts.json``) for each
    requested asset into ``out_dir``."""
    from parsel_mesh.prefit import write_prefit

    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for name in names:
        path = out_dir / f"{name}.glb"
        path.write_bytes(asset_bytes(name))
        paths.append(path)
        write_prefit(path)
    return paths


def stale(out_dir: Path = EXAMPLES_DIR) -> list[str]:
    """Names of assets whose file (or pre-fitted parts) in ``out_dir`` differs from a fresh build."""
    from parsel_mesh.prefit import prefit_data, prefit_path

    def fresh(n: str) -> bool:
        path = out_dir / f"{n}.glb"
        if not path.is_file() or path.read_bytes() != asset_bytes(n) or not prefit_path(path).is_file():
            return False
        return json.loads(prefit_path(path).read_text(encoding="utf-8")) == prefit_data(path)

    return [n for n in ASSETS if not fresh(n)]


def main(argv: Sequence[str] | None = None) -> int:
    """Command line entry: build (default) or ``--check`` the committed files."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--out", type=Path, default=EXAMPLES_DIR, help="output directory"
    )
    parser.add_argument(
        "--check", action="store_true", help="exit 1 if files differ from a fresh build"
    )
    args = parser.parse_args(argv)
    if args.check:
        differing = stale(args.out)
        for name in differing:
            print(f"stale: {name}.glb (or its .parts.json)", file=sys.stderr)
        return 1 if differing else 0
    for path in build(args.out):
        print(f"{path} {path.stat().st_size} bytes")
    return 0


if __name__ == "__main__":
    sys.exit(main())
