"""parsel-fit: a program's parameters fitted to a target shape (docs/fitting.md).

``parsel fit SHAPE PROGRAM TARGET -o fitted.json`` finds the parameter values that bring
the edited shape closest to a target (a mesh, a point cloud or another shape) by the
Chamfer distance between surface samples: what ShapeAssembly does for point clouds, and
what turns an editing program into a handle that can be fitted to data. The hook only
registers the command; the work is in submodules imported when it runs.
"""

from __future__ import annotations

from parsel_core import hookimpl

__version__ = "0.1.0"


@hookimpl
def parsel_register_commands(subparsers):
    from parsel_fit.commands import register

    register(subparsers)
