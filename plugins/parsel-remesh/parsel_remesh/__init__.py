"""parsel-remesh: one watertight mesh of an edited shape (docs/viewer.md, "Watertight remeshing").

Each part's signed distance field is read in the part's frame as posed by its edited
hexahedron; the union (minimum) goes through marching cubes, and the faces take the
labels of the nearest parts. Exported by suffix: ``.watertight.obj``,
``.watertight.ply``, ``.watertight.glb`` (``parsel apply SHAPE PROGRAM -o x.watertight.ply``).
The function is ``parsel_remesh.remesh.remesh``. This module only holds the hook;
scikit-image and trimesh load when a file is written.
"""

from __future__ import annotations

from parsel_core import hookimpl

__version__ = "0.1.0"


@hookimpl
def parsel_exporters():
    from parsel_remesh.exporters import watertight_exporters

    return watertight_exporters()
