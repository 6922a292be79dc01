"""``parsel render``: a filmstrip of the edited shape at several parameter values (matplotlib, Agg).

Parts with meshes are drawn deformed by the ``cage`` deformer; parts without are drawn
as their filled hexahedra. All triangles of a frame go into one ``Poly3DCollection``,
so matplotlib's depth sort works across parts, and each is shaded by its normal so the
shape reads as a solid. Colours are the labels' colours of ``parsel inspect --png``.
A ``.gif`` path gives an animation instead of a strip: one picture per parameter value,
played forwards then backwards so the loop has no jump (encoded by Pillow, which
matplotlib already depends on; no external binary).
"""

from __future__ import annotations

import io
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from parsel_core.drawing import PICTURE_FORMATS, PLOT_AXES, picture_format, set_camera
from parsel_core.errors import ParselError
from parsel_core.graph import ShapeGraph
from parsel_core.hexahedron import FACE_TRIANGLES
from parsel_core.io import atomic_write_bytes
from parsel_core.program import Evaluation, Program, evaluator
from parsel_core.verbosity import logger

MAX_FRAMES = 24
#: What ``parsel render`` writes, by suffix: the strip's picture formats and the animation.
FILMSTRIP_FORMATS = {**PICTURE_FORMATS, ".gif": "gif"}
#: Milliseconds per animation frame.
GIF_FRAME_MS = 120
LIGHT = np.array([0.35, 0.85, 0.55]) / np.linalg.norm([0.35, 0.85, 0.55])


@dataclass
class FrameGeometry:
    """Triangles (t, 3, 3) of one frame and the label of each."""

    triangles: np.ndarray
    labels: list[str]


def has_meshes(shape: ShapeGraph) -> bool:
    return bool(shape.parts) and all(getattr(p.mesh, "vertices", None) is not None for p in shape.parts.values())


def frame_geometry(shape: ShapeGraph, evaluation: Evaluation, remesh: bool = False,
                   remesh_options: Mapping[str, Any] | None = None) -> FrameGeometry:
    """The triangles to draw: deformed meshes, the watertight remesh, or the hexahedra."""
    if remesh:
        try:
            from parsel_remesh.remesh import remesh as watertight
        except ImportError:
            raise ParselError("--remesh needs the parsel-remesh plugin (pip install -e plugins/parsel-remesh)") \
                from None
        result = watertight(shape, evaluation, **dict(remesh_options or {}))
        return FrameGeometry(np.asarray(result.mesh.vertices)[np.asarray(result.mesh.faces)], list(result.face_labels))
    triangles, labels = [], []
    if has_meshes(shape):
        from parsel_mesh.deform import deformed_vertices, source_part

        for name, vertices in deformed_vertices(shape, evaluation).items():
            part = shape.parts[source_part(shape, name)]
            faces = np.asarray(part.mesh.faces)
            triangles.append(vertices[faces])
            labels += [part.label] * len(faces)
    else:
        faces = FACE_TRIANGLES
        replaced = {m for g in evaluation.instances for m in shape.relation(g).members}
        for pid, part in shape.parts.items():
            if pid not in replaced:
                triangles.append(np.asarray(evaluation.parts[pid], dtype=float)[faces])
                labels += [part.label] * len(faces)
        for group, instances in evaluation.instances.items():
            label = shape.parts[shape.relation(group).members[0]].label
            for corners in np.asarray(instances, dtype=float):
                triangles.append(corners[faces])
                labels += [label] * len(faces)
    return FrameGeometry(np.concatenate(triangles) if triangles else np.zeros((0, 3, 3)), labels)


def filmstrip_format(path: Path) -> str:
    """The format a filmstrip path's suffix asks for (a picture format or ``gif``)."""
    return picture_format(path, FILMSTRIP_FORMATS)


def _shaded(colours: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)
    light = 0.45 + 0.55 * np.abs(normals @ LIGHT)
    return np.clip(colours[:, :3] * light[:, None], 0, 1)


#: How much each frame's 3D box is enlarged so the model fills its cell (matplotlib pads 3D axes).
FRAME_ZOOM = 1.45


def draw_filmstrip(shape: ShapeGraph, program: Program, path: Path | str, frames: int = 5,
                   parameter: str | None = None, values: Mapping[str, float] | None = None, remesh: bool = False,
                   remesh_options: Mapping[str, Any] | None = None, dpi: int = 110, backend: str | None = None,
                   progress: bool = True) -> Path:
    """Draw ``frames`` views of ``shape`` edited by ``program``, ``parameter`` swept over its range.

    Other parameters take ``values`` or their defaults. The picture is written atomically;
    its format comes from the suffix (``.png``, ``.svg``, ``.pdf``). ``backend`` evaluates
    through that CAS backend instead of the numpy reference; ``progress`` allows a display
    on stderr (shown only with ``remesh``, which takes seconds per frame).
    """
    path = Path(path)
    fmt = filmstrip_format(path)
    if path.is_dir():
        raise ParselError(f"{path}: is a directory")
    if not path.parent.is_dir():
        raise ParselError(f"{path}: output directory {path.parent} does not exist")
    if not 1 <= frames <= MAX_FRAMES:
        raise ParselError(f"--frames must be between 1 and {MAX_FRAMES}, got {frames}")
    program.validate(shape)
    if not program.parameters:
        raise ParselError("the program has no parameter to draw a filmstrip across")
    fixed = program.values(values)
    swept = program.parameter(parameter) if parameter else program.parameters[0]
    xs = np.linspace(swept.lo, swept.hi, frames) if frames > 1 else np.array([fixed[swept.name]])
    from parsel_core.progress import progress as progress_display

    bar = progress_display(len(xs), "frames", enabled=remesh and progress)  # remeshing: seconds per frame
    evaluate = evaluator(program, shape, backend)
    geometries = []
    for x in xs:
        started = time.perf_counter()
        geometries.append(frame_geometry(shape, evaluate({**fixed, swept.name: float(x)}), remesh, remesh_options))
        logger.debug(f"frame {swept.name} = {x:.4g}: {len(geometries[-1].triangles)} triangles in "
                     f"{time.perf_counter() - started:.3f} s ({backend or 'numpy reference'} evaluation"
                     f"{', remeshed' if remesh else ''})")
        bar.update(1)
    bar.close()

    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt
    from matplotlib.patches import Patch

    from parsel_core.drawing import label_colours

    colours = label_colours(p.label for p in shape.parts.values())
    points = np.concatenate([g.triangles.reshape(-1, 3) for g in geometries if len(g.triangles)])
    points = points[np.all(np.isfinite(points), axis=1)]
    lo, hi = points.min(axis=0), points.max(axis=0)
    view = (lo + hi) / 2, float((hi - lo).max()) / 2 or 1.0
    handles = [Patch(color=colour, label=label) for label, colour in colours.items()]
    title = f"{shape.name}{' (watertight remesh)' if remesh else ''}"
    if fmt == "gif":
        pictures = []
        for x, geometry in zip(xs, geometries):
            figure = plt.figure(figsize=(3.6, 3.8), dpi=dpi)
            _draw_frame(figure.add_subplot(projection="3d"), geometry, colours, view, f"{swept.name} = {x:.3g}")
            figure.legend(handles=handles, loc="lower center", ncol=min(len(handles), 4), fontsize=7,
                          frameon=False)
            figure.suptitle(title, fontsize=10)
            figure.subplots_adjust(left=0, right=1, top=0.9, bottom=0.12)
            pictures.append(_figure_rgb(figure))
            plt.close(figure)
        atomic_write_bytes(path, gif_bytes(pictures))
        return path
    # Frames side by side with no gaps, each 3D box zoomed to fill its cell; the title sits
    # in the top-left corner and each frame's value under its model, so nothing collides.
    figure = plt.figure(figsize=(2.6 * frames, 3.3), dpi=dpi)
    width = 1.0 / frames
    for i, (x, geometry) in enumerate(zip(xs, geometries)):
        ax = figure.add_axes((i * width, 0.17, width, 0.78), projection="3d")
        _draw_frame(ax, geometry, colours, view, None, zoom=FRAME_ZOOM)
        figure.text((i + 0.5) * width, 0.17, f"{swept.name} = {x:.3g}", ha="center", va="top", fontsize=9)
    figure.legend(handles=handles, loc="lower center", ncol=min(len(handles), 8), fontsize=7, frameon=False)
    figure.text(0.006, 0.985, title, ha="left", va="top", fontsize=10)
    buffer = io.BytesIO()
    figure.savefig(buffer, format=fmt)
    plt.close(figure)
    atomic_write_bytes(path, buffer.getvalue())
    return path


def _draw_frame(ax, geometry: FrameGeometry, colours: Mapping[str, tuple], view: tuple[np.ndarray, float],
                title: str | None, zoom: float = 1.0) -> None:
    """One frame on a 3D axis; ``view`` (centre, radius) is shared by all frames so motion shows."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    rgba = np.array([colours.get(label, (0.6, 0.6, 0.6, 1.0)) for label in geometry.labels]).reshape(-1, 4)
    drawn = geometry.triangles[..., PLOT_AXES]
    ax.add_collection3d(Poly3DCollection(drawn, facecolors=_shaded(rgba, geometry.triangles), edgecolors="none",
                                         linewidths=0))
    set_camera(ax, *view, zoom=zoom, elev=18, title=title)


def _figure_rgb(figure) -> np.ndarray:
    """The figure rendered by Agg, as an (h, w, 3) uint8 array."""
    figure.canvas.draw()
    return np.asarray(figure.canvas.buffer_rgba())[..., :3].copy()


def gif_bytes(pictures: list[np.ndarray], frame_ms: int = GIF_FRAME_MS) -> bytes:
    """An endlessly looping GIF of ``pictures`` played forwards then backwards (no jump at the loop).

    All frames share one adaptive palette, so colours do not flicker from frame to frame."""
    from PIL import Image

    order = pictures + pictures[-2:0:-1] if len(pictures) > 2 else list(pictures)
    images = [Image.fromarray(p) for p in order]
    palette = Image.fromarray(np.concatenate(pictures, axis=0)).quantize(colors=255, method=Image.Quantize.MEDIANCUT)
    frames = [image.quantize(palette=palette, dither=Image.Dither.NONE) for image in images]
    buffer = io.BytesIO()
    frames[0].save(buffer, format="GIF", save_all=True, append_images=frames[1:], duration=frame_ms, loop=0,
                   disposal=1, optimize=False)
    return buffer.getvalue()
