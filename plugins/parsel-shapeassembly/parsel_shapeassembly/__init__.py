"""ShapeAssembly programs as parsel shapes, and edited shapes back to programs (Jones et al., SIGGRAPH Asia 2020).

The parser and executor reproduce the reference interpreter (``interpreter.py``);
``loader.py`` turns an executed program into a shape graph of labelled boxes, keeping
the program's own declarations as *declared relations* for measuring detectors; ``exporter.py``
writes an edited shape as a program (``parsel apply ... -o edited.sa.txt``).
"""

from __future__ import annotations

from parsel_core import hookimpl


@hookimpl
def parsel_shape_loaders():
    from parsel_shapeassembly.loader import ShapeAssemblyLoader

    return [ShapeAssemblyLoader()]


@hookimpl
def parsel_exporters():
    from parsel_shapeassembly.exporter import ShapeAssemblyExporter

    return [ShapeAssemblyExporter()]
