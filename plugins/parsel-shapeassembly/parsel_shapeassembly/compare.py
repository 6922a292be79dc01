"""Agreement of an executed program with the reference interpreter's leaf cuboids.

The reference (the ShapeAssembly paper's own interpreter) lists each leaf cuboid's 8
corners rounded to 1e-5; leaf names are not comparable, so cuboids are paired greedily
by their corners.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from parsel_shapeassembly.interpreter import ExecutedProgram

#: The reference rounds every coordinate to this many decimals.
REFERENCE_DECIMALS = 5


def corner_error(mine: Sequence[np.ndarray], reference: Sequence[np.ndarray]) -> float:
    """Largest corner deviation of a greedy one-to-one pairing of two cuboid lists (inf if counts differ)."""
    if len(mine) != len(reference):
        return float("inf")
    unused = list(range(len(reference)))
    worst = 0.0
    for corners in mine:
        errors = [float(np.abs(corners - reference[j]).max()) for j in unused]
        best = int(np.argmin(errors))
        worst = max(worst, errors[best])
        unused.pop(best)
    return worst


def reference_error(program: ExecutedProgram, reference: Sequence[Sequence[Sequence[float]]]) -> float:
    """:func:`corner_error` of the program's leaves, rounded as the reference is, against its corners."""
    mine = [np.round(c.corners(), REFERENCE_DECIMALS) for c in program.cuboids]
    return corner_error(mine, [np.asarray(c, dtype=np.float64) for c in reference])
