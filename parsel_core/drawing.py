"""Headless pictures of hexahedra coloured by label, with relations marked (matplotlib, Agg)."""

from __future__ import annotations

import io
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.io import atomic_write_bytes
from parsel_core.relations import (
    Attachment,
    GroundContact,
    ReflectionSymmetry,
    RotationSymmetry,
    TranslationSymmetry,
)

#: How each relation kind is marked: (colour, marker or None, line style or None, legend label).
RELATION_MARKS = {
    "attachment": ("red", "o", None, "attachment"),
    "ground": ("black", "s", None, "ground contact"),
    "reflection": ("grey", None, "--", "reflection pair"),
    "translation": ("tab:purple", "D", ":", "translation group"),
    "rotation": ("tab:brown", "D", ":", "rotation group"),
}

#: World axes (x, y up, z front) in the order a matplotlib 3D plot takes them, so y is drawn upwards.
PLOT_AXES = [0, 2, 1]

# The 12 edges of a hexahedron in canonical corner order: corners differing in one bit.
HEX_EDGES = tuple((k, k ^ bit) for k in range(8) for bit in (4, 2, 1) if k < k ^ bit)


def label_colours(labels) -> dict[str, tuple]:
    """A stable colour per label (sorted labels over matplotlib's tab20)."""
    from matplotlib import colormaps

    palette = colormaps["tab20"]
    return {label: palette(i % 20) for i, label in enumerate(sorted(set(labels)))}


def relation_mark(relation) -> str | None:
    """The key of :data:`RELATION_MARKS` a relation is drawn with (None: not drawn)."""
    for cls, kind in ((Attachment, "attachment"), (GroundContact, "ground"), (ReflectionSymmetry, "reflection"),
                      (TranslationSymmetry, "translation"), (RotationSymmetry, "rotation")):
        if isinstance(relation, cls):
            return kind
    return None


def draw_shape(ax, shape: ShapeGraph, corners: Mapping[str, np.ndarray] | None = None,
               relations: bool = True, title: str | None = None, zoom: float = 1.0) -> None:
    """Draw every real part's hexahedron on a 3D axis; y is drawn upwards."""
    corners = shape.rest_corners() if corners is None else corners
    colours = label_colours(p.label for p in shape.parts.values())

    def view(points):  # world -> plot coordinates, one array per plot axis
        points = np.asarray(points)
        return tuple(points[..., axis] for axis in PLOT_AXES)

    for pid, part in shape.parts.items():
        c = np.asarray(corners[pid])
        for a, b in HEX_EDGES:
            ax.plot(*view(c[[a, b]]), color=colours[part.label], linewidth=1.2)
    if relations:
        for relation in shape.relations.values():
            kind = relation_mark(relation)
            if kind is None:
                continue
            colour = RELATION_MARKS[kind][0]
            if isinstance(relation, Attachment):
                ax.scatter(*view(relation.points(corners)), color=colour, s=8, depthshade=False)
            elif isinstance(relation, GroundContact):
                points = np.asarray(relation.weights) @ np.asarray(corners[relation.members[0]])
                ax.scatter(*view(points), color=colour, s=6, marker="s", depthshade=False)
            else:
                centres = np.array([np.asarray(corners[m]).mean(axis=0) for m in relation.members])
                ax.plot(*view(centres), color=colour, linestyle=RELATION_MARKS[kind][2], linewidth=0.9)
                if kind != "reflection":  # groups: a mark at each member's centre
                    ax.scatter(*view(centres), color=colour, s=10, marker="D", depthshade=False)
    everything = np.concatenate([np.asarray(corners[p]) for p in shape.parts])
    lo, hi = everything.min(axis=0), everything.max(axis=0)
    set_camera(ax, (lo + hi) / 2, float((hi - lo).max()) / 2 or 1.0, zoom=zoom, title=title)


def set_camera(ax, mid: np.ndarray, radius: float, *, zoom: float = 1.0, elev: float = 20.0,
               title: str | None = None) -> None:
    """The one camera of parsel's pictures (``inspect --png``, filmstrips, GIFs): a cube of
    half-width ``radius`` about the world point ``mid``, y up, seen from the front left, no
    axes, so that shapes drawn by different commands look alike and frames of one strip
    share a scale."""
    for set_lim, axis in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), PLOT_AXES):
        set_lim(mid[axis] - radius, mid[axis] + radius)
    ax.set_box_aspect((1, 1, 1), zoom=zoom)
    ax.view_init(elev=elev, azim=-60)
    ax.set_axis_off()
    if title:
        ax.set_title(title, fontsize=9)


#: Picture formats by file suffix.
PICTURE_FORMATS = {".png": "png", ".svg": "svg", ".pdf": "pdf"}


def picture_format(path: Path, formats: Mapping[str, str] = PICTURE_FORMATS) -> str:
    """The format a picture file's suffix asks for among ``formats`` (suffix -> format);
    an unknown suffix is an error naming the file and the known ones."""
    suffix = path.suffix.lower()
    if suffix not in formats:
        raise ParselError(f"{path}: unknown picture format {suffix or '(none)'!r} "
                          f"(known: {', '.join(sorted(formats))})")
    return formats[suffix]


def save_shape_png(shape: ShapeGraph, path: Path | str, corners: Mapping[str, np.ndarray] | None = None) -> None:
    """One picture of the shape with a label legend, written atomically; the format follows
    the suffix (``.png``, ``.svg``, ``.pdf``)."""
    path = Path(path)
    fmt = picture_format(path)
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt
    from matplotlib.lines import Line2D

    figure = plt.figure(figsize=(6, 6), dpi=120)
    ax = figure.add_axes((0.0, 0.0, 1.0, 0.95), projection="3d")  # the whole picture; matplotlib pads 3D boxes
    draw_shape(ax, shape, corners, zoom=1.3)
    figure.text(0.02, 0.98, f"{shape.name}: {len(shape.parts)} parts, {len(shape.relations)} relations",
                ha="left", va="top", fontsize=9)
    colours = label_colours(p.label for p in shape.parts.values())
    handles = [Line2D([], [], color=c, label=label) for label, c in colours.items()]
    kinds = {relation_mark(r) for r in shape.relations.values()} - {None}
    for kind, (colour, marker, style, label) in RELATION_MARKS.items():
        if kind in kinds:  # a legend entry for every kind drawn, and only those
            handles.append(Line2D([], [], color=colour, marker=marker or "", linestyle=style or "", label=label))
    figure.legend(handles=handles, loc="upper left", bbox_to_anchor=(0.01, 0.95), fontsize=7, frameon=False)
    buffer = io.BytesIO()
    figure.savefig(buffer, format=fmt)
    plt.close(figure)
    atomic_write_bytes(path, buffer.getvalue())
