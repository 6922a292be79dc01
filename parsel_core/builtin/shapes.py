"""The ``parsel.shape`` JSON loader and the built-in example shape."""

from __future__ import annotations

from pathlib import Path

from parsel_core import hookimpl
from parsel_core.examples import tiny_table
from parsel_core.graph import ShapeGraph
from parsel_core.interfaces import ShapeLoader
from parsel_core.io import read_json


class ShapeJSONLoader(ShapeLoader):
    """Reads shapes saved by ``parsel`` itself (parts as corners, relations): docs/formats.md."""

    name = "shape-json"
    extensions = (".shape.json",)

    def load(self, path: Path) -> ShapeGraph:
        return ShapeGraph.from_dict(read_json(path), source=str(path))


@hookimpl
def parsel_shape_loaders():
    return [ShapeJSONLoader()]


@hookimpl
def parsel_example_shapes():
    return {"tiny_table": tiny_table}
