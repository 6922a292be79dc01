"""The ``parsel.shape`` JSON loader and the built-in example shape."""

from __future__ import annotations

import json
from pathlib import Path

from parsel_core import hookimpl
from parsel_core.errors import ParselError
from parsel_core.examples import tiny_table
from parsel_core.graph import ShapeGraph
from parsel_core.interfaces import ShapeLoader


class ShapeJSONLoader(ShapeLoader):
    """Reads shapes saved by ``parsel`` itself (parts as corners, relations): docs/formats.md."""

    name = "shape-json"
    extensions = (".shape.json",)

    def load(self, path: Path) -> ShapeGraph:
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except OSError as exc:
            raise ParselError(f"{path}: cannot read: {exc.strerror}") from None
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ParselError(f"{path}: not valid JSON: {exc}") from None
        return ShapeGraph.from_dict(data, source=str(path))


@hookimpl
def parsel_shape_loaders():
    return [ShapeJSONLoader()]


@hookimpl
def parsel_example_shapes():
    return {"tiny_table": tiny_table}
