"""parsel inspect --png: every relation kind drawn has a legend entry, groups are drawn, the shape fills the picture."""

from __future__ import annotations

import numpy as np

from parsel_core.drawing import RELATION_MARKS, relation_mark, save_shape_png
from parsel_core.examples import tiny_table


def test_the_legend_names_every_kind_drawn_and_the_shape_fills_the_picture(tmp_path, monkeypatch):
    from matplotlib import image, pyplot

    shape = tiny_table()  # attachments, ground contacts, a reflection and a translation group (the slats)
    kinds = {relation_mark(r) for r in shape.relations.values()}
    assert {"attachment", "ground", "reflection", "translation"} <= kinds
    legends = []
    original = pyplot.Figure.legend

    def keep(self, *args, **kwargs):
        legends.append([h.get_label() for h in kwargs["handles"]])
        return original(self, *args, **kwargs)

    monkeypatch.setattr(pyplot.Figure, "legend", keep)
    save_shape_png(shape, tmp_path / "t.png")
    (labels,) = legends
    assert [label for label in labels if label in {m[3] for m in RELATION_MARKS.values()}] == [
        RELATION_MARKS[k][3] for k in RELATION_MARKS if k in kinds]
    assert "translation group" in labels and "ground contact" in labels and "rotation group" not in labels
    pixels = image.imread(str(tmp_path / "t.png"))[..., :3]
    ink = np.any(pixels < 0.9, axis=-1)
    rows, columns = np.flatnonzero(ink.any(axis=1)), np.flatnonzero(ink.any(axis=0))
    assert rows[-1] - rows[0] > 0.8 * ink.shape[0] and columns[-1] - columns[0] > 0.8 * ink.shape[1]
