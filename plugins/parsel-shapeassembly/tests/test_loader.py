"""ShapeAssembly files as parsel shapes: parts, labels, declared and detected relations, errors."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from parsel_core.cli import main
from parsel_core.errors import ParselError
from parsel_core.loading import load_shape

FIXTURES = Path(__file__).parent / "fixtures"


@pytest.fixture
def chair(tmp_path) -> Path:
    """A corpus chair copied under a ``chair/`` folder, so the category labeller applies."""
    source = next(p for p in sorted(FIXTURES.rglob("*.txt")) if "1277" in p.name)
    target = tmp_path / "chair" / "1277.txt"
    target.parent.mkdir()
    shutil.copy(source, target)
    return target


def test_program_loads_as_labelled_boxes_with_declared_relations(chair):
    shape = load_shape(str(chair), detect=False)
    assert shape.name == "chair/1277" and len(shape.parts) == 11
    labels = {pid: p.label for pid, p in shape.parts.items()}
    assert labels["cube1"] == "seat"
    assert {labels[f"Program_1/{c}"] for c in ("cube0", "cube1", "cube0_ref", "cube1_ref")} == {"leg"}
    declared = shape.metadata["declared_relations"]
    kinds = {d["kind"] for d in declared}
    assert kinds == {"attachment", "reflection", "translation"}
    legs = shape.part("Program_1/cube0").hexahedron
    assert np.allclose(legs.extents, (0.099, 0.706, 0.094), atol=1e-6)
    assert np.allclose(legs.local_axes, np.eye(3), atol=1e-6)  # the canonical axis convention


def test_detected_relations_find_the_declared_leg_mirrors_and_back_row(chair):
    shape = load_shape(str(chair))
    pairs = {frozenset(r.members) for r in shape.relations.values() if r.kind == "reflection"}
    assert frozenset({"Program_1/cube0", "Program_1/cube0_ref"}) in pairs
    rows = [r for r in shape.relations.values() if r.kind == "translation"]
    assert any(len(r.members) == 5 for r in rows)
    grounded = {r.members[0] for r in shape.relations.values() if r.kind == "ground"}
    assert {"Program_1/cube0", "Program_1/cube1", "Program_1/cube0_ref", "Program_1/cube1_ref"} <= grounded


def test_labels_sidecar_overrides_and_names_unknown_parts(chair):
    sidecar = chair.with_name("1277.labels.json")
    sidecar.write_text(json.dumps({"cube1": "cushion"}))
    assert load_shape(str(chair), detect=False).part("cube1").label == "cushion"
    sidecar.write_text(json.dumps({"cube9": "cushion"}))
    with pytest.raises(ParselError, match="unknown part.*cube9"):
        load_shape(str(chair), detect=False)


def test_malformed_program_names_the_line(tmp_path, capsys):
    bad = tmp_path / "bad.txt"
    bad.write_text("Assembly Program_0 {\n\tbbox = Cuboid(1, 1, 1, True)\n\tcube0 = Cuboid(0.5, 0.5)\n}\n")
    assert main(["inspect", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "bad.txt:3" in err


def test_inspect_json_on_a_program(chair, capsys):
    assert main(["inspect", str(chair), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert len(data["parts"]) == 11 and data["relations"]


def test_parts_carry_closed_box_meshes_on_their_corners(chair):
    import trimesh

    shape = load_shape(str(chair), detect=False)
    for pid, part in shape.parts.items():
        mesh = trimesh.Trimesh(part.mesh.vertices, part.mesh.faces, process=False)
        assert mesh.is_volume, pid  # watertight, outward
        np.testing.assert_allclose(mesh.vertices, part.hexahedron.corners)
        assert mesh.volume == pytest.approx(abs(part.hexahedron.volume), rel=1e-9)


def test_an_edited_program_exports_as_a_mesh(chair, tmp_path):
    program = tmp_path / "raise.parsel"
    program.write_text("param x in [0, 1] default 0.5\ntranslate('Program_1/cube0', dir=(0, 1, 0), amount=0.1 * x)\n")
    out = tmp_path / "edited.glb"
    assert main(["apply", str(chair), str(program), "--set", "x=1", "-o", str(out)]) == 0
    import trimesh

    scene = trimesh.load(out, force="scene")
    assert len(scene.geometry) == 11


def test_loading_a_program_does_not_import_trimesh(chair, parsel_fresh_python):
    """Box meshes are plain vertex and face arrays (trimesh takes half a second to import)."""
    code = ("import sys; from parsel_core.loading import load_shape; "
            f"shape = load_shape({str(chair)!r}); "
            "assert all(p.mesh.faces.shape == (12, 3) for p in shape.parts.values()); "
            "print(sorted(m for m in ('trimesh', 'scipy', 'sympy') if m in sys.modules))")
    assert parsel_fresh_python(code).strip() == "[]"


def test_a_cushion_on_the_seat_is_labelled_seat_and_the_panel_behind_it_back():
    """PartNet seats are often a frame with a cushion on top; the cushion is flat, lies over
    the seat's footprint and is no back (the rules put every part above the seat behind it
    or among the backs)."""
    from parsel_shapeassembly.labels import label_parts

    def box(lo, hi):
        bits = np.array([[(k >> 2) & 1, (k >> 1) & 1, k & 1] for k in range(8)], float)
        return np.asarray(lo, float) + bits * (np.asarray(hi, float) - np.asarray(lo, float))

    corners = {
        "frame": box((-0.4, 0.40, -0.4), (0.4, 0.50, 0.4)),
        "cushion": box((-0.37, 0.50, -0.35), (0.37, 0.58, 0.38)),
        "back": box((-0.4, 0.50, -0.45), (0.4, 1.20, -0.40)),
        "top_rail": box((-0.4, 1.20, -0.46), (0.4, 1.24, -0.39)),
        "leg": box((-0.4, 0.0, -0.4), (-0.35, 0.40, -0.35)),
    }
    labels = label_parts("chair", corners)
    assert labels == {"frame": "seat", "cushion": "seat", "back": "back", "top_rail": "back", "leg": "leg"}
