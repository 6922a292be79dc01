"""Labels from part names, made-up names, sidecar label files."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from parsel_core.errors import ParselError
from parsel_mesh.naming import (
    is_generated_name,
    label_of,
    natural_key,
    read_sidecar,
    resolve_labels,
    sidecar_path,
)


@pytest.mark.parametrize(("name", "label"), [
    ("leg.003", "leg"),
    ("back_slat_2", "back_slat"),
    ("Leg-01", "leg"),
    ("seat", "seat"),
    ("Back Slat 2", "back_slat"),
    ("leg_1.002", "leg"),
    ("Box001", "box"),
    ("leg_", "leg"),
    ("mp3_player", "mp3_player"),
    ("003", "003"),
])
def test_label_of(name, label):
    assert label_of(name) == label


def test_generated_names():
    path = Path("/data/chair.ply")
    assert is_generated_name("geometry_0")
    assert is_generated_name("")
    assert is_generated_name("chair.ply", path)
    assert is_generated_name("chair", path)
    assert not is_generated_name("seat", path)
    assert not is_generated_name("geometry_leg")


def test_natural_order():
    assert sorted(["leg.10", "leg.2", "leg.1"], key=natural_key) == ["leg.1", "leg.2", "leg.10"]


def test_sidecar_path(tmp_path):
    assert sidecar_path(tmp_path / "chair.glb") == tmp_path / "chair.labels.json"
    (tmp_path / "shape").mkdir()
    assert sidecar_path(tmp_path / "shape") == tmp_path / "shape.labels.json"


def test_read_sidecar(tmp_path):
    path = tmp_path / "chair.glb"
    assert read_sidecar(path) is None
    (tmp_path / "chair.labels.json").write_text(json.dumps({"Cube.001": " seat "}))
    assert read_sidecar(path) == {"Cube.001": "seat"}


@pytest.mark.parametrize(("text", "fragment"), [
    ("{not json", "not valid JSON"),
    ("[1, 2]", "must be a JSON object"),
    ('{"a": 3}', "label of part 'a' must be a non-empty string"),
    ('{"a": ""}', "label of part 'a' must be a non-empty string"),
])
def test_bad_sidecar(tmp_path, text, fragment):
    (tmp_path / "chair.labels.json").write_text(text)
    with pytest.raises(ParselError, match=fragment) as info:
        read_sidecar(tmp_path / "chair.glb")
    assert "chair.labels.json" in str(info.value)


def test_resolve_labels():
    labels = resolve_labels(["leg.000", "Cube"], {"Cube": "seat"}, defaults={"leg.000": "front_leg"})
    assert labels == {"leg.000": "front_leg", "Cube": "seat"}
    assert resolve_labels(["leg.000"]) == {"leg.000": "leg"}


def test_resolve_labels_unknown_part():
    with pytest.raises(ParselError, match=r"x.labels.json: labels file names unknown part\(s\) 'stool'"):
        resolve_labels(["leg.000"], {"stool": "seat"}, source="x.labels.json")
