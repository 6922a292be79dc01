"""The picture sent with a request (``parsel edit --with-image``): the shape at rest, every
part's box drawn in its label's colour with the part's id written at its centre, seen from
the front-right and above. The prompt templates describe exactly this picture, so a model
that takes images can match ids in the text to what it sees.
"""

from __future__ import annotations

import io

import numpy as np

from parsel_core.graph import ShapeGraph

#: What the prompt says about the picture when one is attached.
PICTURE_TEXT = (
    "A picture of the shape is attached: every part is drawn as the edges of its box in its label's "
    "colour, with its id written at its centre; red dots mark attachments and dashed grey lines join "
    "mirrored parts. The view is from the front-right and above, with +y up."
)
#: Size of the picture in pixels (square); small enough to cost few image tokens.
PIXELS = 512


def shape_picture(shape: ShapeGraph, pixels: int = PIXELS) -> bytes:
    """The PNG bytes of the shape with part ids (deterministic for a given shape)."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    from parsel_core.drawing import draw_shape

    dpi = 100
    figure = plt.figure(figsize=(pixels / dpi, pixels / dpi), dpi=dpi)
    ax = figure.add_subplot(projection="3d")
    corners = shape.rest_corners()
    draw_shape(ax, shape, corners, title=shape.name)
    for pid in shape.parts:
        centre = np.asarray(corners[pid]).mean(axis=0)
        ax.text(centre[0], centre[2], centre[1], pid, fontsize=6, ha="center", va="center")
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", metadata={"Software": None})
    plt.close(figure)
    return buffer.getvalue()
