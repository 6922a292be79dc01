"""Every hook a parsel plugin can implement.

A plugin is a module (or object) with functions decorated by ``parsel_core.hookimpl``
and named like the specs below; it is found through the ``parsel`` entry-point group
of an installed package::

    [project.entry-points.parsel]
    my_plugin = "my_package.plugin"

Each ``parsel_*`` hook returns a list of contributions (classes or instances); the
engine gathers the lists of all plugins. Built-in behaviour is registered through the
same hooks (``parsel_core.builtin.*``), so a plugin can add to it and, by using the
same name, replace it: later registrations win, and installed plugins come after the
built-ins. See docs/plugins.md for a walkthrough.
"""

from __future__ import annotations

import pluggy

hookspec = pluggy.HookspecMarker("parsel")


@hookspec
def parsel_edit_operators():
    """Edit operators to add to the DSL.

    Return a list of :class:`parsel_core.ops.EditOp` subclasses. Each has a unique
    ``name`` (its name in program text and JSON), dataclass fields for its numeric
    parameters (``unit_fields`` / ``point_fields`` list which are directions and
    points, so mirroring and validation work), and a ``transform(points, amount, math)``
    that maps points (``(..., m, 3)`` float or object arrays) at ``amount`` using only
    arithmetic and ``math.sin`` / ``math.cos`` / ``math.sqrt`` (elementwise on every kind
    of value: :mod:`parsel_core.opmath`), so the same code runs numerically,
    symbolically and, generated from it, in the slider page's JavaScript. Override
    ``mirrored`` when the map is not the same in a mirror (rotations turn the other way).
    """


@hookspec
def parsel_cas_backends():
    """Computer-algebra backends.

    Return a list of :class:`parsel_core.cas.CASBackend` subclasses (instantiated on
    first use, so importing a plugin stays cheap). Users pick one by its ``name`` with
    ``--backend`` or the ``cas_backend`` setting.
    """


@hookspec
def parsel_shape_loaders():
    """Readers of shape files.

    Return a list of :class:`parsel_core.interfaces.ShapeLoader` instances. The first
    loader whose ``can_load(path)`` is true reads the file (loaders of later-registered
    plugins are asked first).
    """


@hookspec
def parsel_relation_detectors():
    """Detectors of inter-part relations.

    Return a list of :class:`parsel_core.interfaces.RelationDetector` instances; all
    of them run on a loaded shape and their relations are merged.
    """


@hookspec
def parsel_llm_providers():
    """Language-model providers.

    Return a list of :class:`parsel_core.interfaces.LLMProvider` classes or instances,
    selected by ``name`` with ``--provider``.
    """


@hookspec
def parsel_deformers():
    """Mesh deformers that move part meshes with their hexahedra.

    Return a list of :class:`parsel_core.interfaces.Deformer` instances, selected by
    ``name``.
    """


@hookspec
def parsel_exporters():
    """Writers of edited shapes.

    Return a list of :class:`parsel_core.interfaces.Exporter` instances; the output
    path's suffix picks one.
    """


@hookspec
def parsel_solvers():
    """Edit-propagation solvers.

    Return a list of :class:`parsel_core.interfaces.Solver` classes or instances,
    selected by ``name`` with ``--solver``.
    """


@hookspec
def parsel_example_shapes():
    """Named example shapes that commands accept in place of a path.

    Return a dict mapping a name (``chair``) to a zero-argument callable returning a
    :class:`parsel_core.graph.ShapeGraph`, or to a path that a shape loader reads.
    """


@hookspec
def parsel_prompt_templates():
    """Prompt templates for the language layer, by name.

    Return a dict mapping a template name (``seed_edit``, ``type_hints``,
    ``reflection_validity``, ``group_validity``, ``one_shot``, ``proxydural``,
    ``variations``) to the
    template's text or to a path of a text file. Later plugins override earlier ones,
    so a plugin can replace one prompt without copying the others.
    """


@hookspec
def parsel_register_commands(subparsers):
    """Add sub-commands to the ``parsel`` command line.

    ``subparsers`` is the :mod:`argparse` sub-parser collection; add a parser and set
    its ``func`` default to a callable taking the parsed arguments and returning an
    exit status.
    """
