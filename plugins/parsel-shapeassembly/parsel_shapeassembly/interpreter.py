"""Executor for ShapeAssembly programs (numpy, float64).

This reproduces the interpreter published with the ShapeAssembly paper
(Jones et al., SIGGRAPH Asia 2020, ``code/ShapeAssembly.py`` of
rkjones4/ShapeAssembly), including its quirks, because downstream code
compares against shapes produced by that interpreter.  Behaviour that
matters for exactness:

* Every block runs in its own frame: a fresh, axis-aligned ``bbox`` centred
  at the origin.  Statements take effect immediately, in order.
* ``attach`` depends on how many attachments the moved cuboid already has;
  *being the target* of an earlier attach counts too (the reference records
  the target point on the target cuboid).  0 previous: translate.  1: grow
  one dimension (the one needing the smallest change, tried in the order
  height, width, length, earlier wins ties) then rotate minimally about the
  previous point.  2+: rotate about the line through the first two previous
  points when all previous points are colinear, then maybe grow the
  dimension whose change direction is within ``acos(0.9)`` of the target
  (the *last* such one wins).  Aligned cuboids never rotate: after the first
  attach they only grow towards the target cuboid, when the closest pair of
  their 10x10x10 sample points is more than 5% of the larger cuboid apart
  and no corner of one lies inside the other.
* ``squeeze`` expands into two attaches (face centre to the opposite face of
  the other cuboid, with the ``bbox`` faces flipped).
* ``reflect``/``translate`` declare copies with the source's *current*
  dimensions and aligned flag, then replay each attachment that moved the
  source, with the source point reflected/translated in the block frame and
  re-expressed (clamped to [0, 1]) in the target's local coordinates.  The
  reference names copies ``cube{n}`` (``n`` = cuboids declared so far); that
  key is used internally (made unique should it clash).
* A cuboid named ``Program_*`` is the bounding box of the block of that name;
  blocks are expanded breadth first.  The cuboids of a block are placed with
  the reference's ``apply_delta``: dimensions are multiplied element-wise by
  ``placed_bbox.dims / block_bbox.dims``, positions and axes are rotated by
  the placed bbox's axes and translated by its centre (positions are *not*
  rescaled).
* A copy of a sub-program made by ``translate`` expands to the same block.
  One made by ``reflect`` expands to the block executed normally and then
  mirrored through its bbox centre along the reflection axis: every cuboid's
  centre coordinate on that axis is negated and its frame becomes ``-(S a)``
  (``S`` the mirror), i.e. turned 180 degrees about the axis so that it stays
  right-handed.  This is what the reference data show (the published
  ``flipRefSubProg``, which re-runs the block with flipped attach
  coordinates, gives the same boxes but different corner orders).  Nested
  sub-programs of a mirrored block are placed in their mirrored (turned)
  boxes without being mirrored themselves; the corpus has no such case.

Naming of output cuboids
    A leaf is named by its path from the root block: root-level leaves keep
    their local name (``cube2``); leaves of sub-programs are prefixed by the
    chain of ``Program_*`` cuboids that contain them
    (``Program_1/Program_3/cube0``).  A ``reflect`` copy of ``c`` is named
    ``c_ref``; the ``k``-th ``translate`` copy is ``c_t1`` ... ``c_tN``.  A copy
    of a sub-program uses that name as its path element
    (``Program_2_ref/cube0``).  Should a copy name already be taken in the
    block (e.g. the same cuboid reflected twice), ``_2``, ``_3``, ... is
    appended.  Leaves are listed in the reference's order (breadth first over
    blocks; declaration order within a block, copies after declared cuboids
    in the order the macros ran).

Declared relations
    :class:`DeclaredRelation` lists what the program states, on leaf names, in
    world coordinates, in execution order, block instance by block instance
    (breadth first; every placed copy of a sub-program repeats its block's
    relations for its own leaves):

    * ``"attachment"``: one per executed attach, including the two a
      ``squeeze`` expands into and those that reflect/translate replay for
      their copies (``params["via"]`` is ``"attach"``, ``"squeeze"``,
      ``"reflect"`` or ``"translate"``).  ``members`` are the moved leaves
      then the target leaves.  A sub-program cuboid stands for its leaves
      that lie within 2% of the sub-program's largest dimension of the
      attachment point; when none does, for the sub-program path itself
      (e.g. ``Program_1``).  An attachment to a block's ``bbox`` has only the
      moved leaves as members and ``params["target"] == "<block>/bbox"``.
      ``params``: ``source``/``target`` (path names), ``source_local`` /
      ``target_local`` (the [0, 1]^3 coordinates on the placed cuboids; in a
      mirrored block these are the mirrored statement coordinates),
      ``point`` (world position of the target point), ``source_point``
      (world position of the moved cuboid's point; differs from ``point``
      where the interpreter did not satisfy the attachment), ``block`` and
      ``line``.
    * ``"reflection"``: ``members`` = leaves of the source then of the copy;
      ``params``: ``axis`` (``"X"``/``"Y"``/``"Z"``), ``source``, ``copy``,
      ``plane_point`` and ``plane_normal`` (world), ``block``, ``line``.
    * ``"translation"``: ``members`` = leaves of the source then of each copy
      in order; ``params``: ``axis``, ``source``, ``copies``, ``count``,
      ``distance`` (the program's fraction of the bbox), ``direction`` (world
      unit vector), ``step`` (distance between consecutive members; block
      positions are not rescaled on placement, so it holds in the world too),
      ``block``, ``line``.

Numerics
    The reference runs in float32 torch.  This module computes in float64 but
    reproduces the float32 outcome of the decisions that change the result
    discontinuously: rotation angles come from a float32 ``acos`` of a
    float32 dot product (cosines within ~3e-8 of 1 mean no rotation); the
    ``+ 1e-8`` guards vanish where float32 absorbs them; near-zero
    discriminants, vectors and near-tied candidate dimensions are decided as
    exact zeros/ties.  The faiss closest-point search is replaced by an exact
    search (first index on ties).  Remaining differences stem from float32
    rounding noise deciding whether a corner lying exactly on another
    cuboid's face counts as inside.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from os import PathLike
from pathlib import Path

import numpy as np

from .parser import (
    SUBPROGRAM_PREFIX,
    AttachStmt,
    Block,
    CuboidStmt,
    ProgramAST,
    ReflectStmt,
    ShapeAssemblyError,
    SqueezeStmt,
    Statement,
    TranslateStmt,
    parse_program,
)

__all__ = [
    "Cuboid",
    "DeclaredRelation",
    "ExecutedProgram",
    "ShapeAssemblyError",
    "execute",
    "execute_file",
    "execute_program",
    "parse_program",
]

# Thresholds of the reference interpreter.
EPS = 0.01
SMALL_EPS = 1e-4
COS_DIST_THRESH = 0.9
ALIGNED_GAP_FRACTION = 0.05
SAMPLE_GRID = 10
DISC_REL_TOL = 1e-6
ZERO_TOL = 1e-9
TIE_REL_TOL = 1e-9
_F32_EPS_TERM = np.float32(1e-8)
TOUCH_FRACTION = 0.02
# Sub-programs may be shared, so expansion can be exponential; the corpus maximum is ~100.
MAX_CUBOIDS = 100_000

# Local axis indices: length = x (right), height = y (top), width = z (front).
LENGTH, HEIGHT, WIDTH = 0, 1, 2
# The reference tries dimensions in this order; ties and "last wins" depend on it.
DIM_ORDER = (HEIGHT, WIDTH, LENGTH)
AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}

# face -> (centre in local coords, axis index, value of that coordinate on the *other* cuboid)
FACE_INFO: dict[str, tuple[tuple[float, float, float], int, float]] = {
    "right": ((1.0, 0.5, 0.5), 0, 0.0),
    "left": ((0.0, 0.5, 0.5), 0, 1.0),
    "top": ((0.5, 1.0, 0.5), 1, 0.0),
    "bot": ((0.5, 0.0, 0.5), 1, 1.0),
    "front": ((0.5, 0.5, 1.0), 2, 0.0),
    "back": ((0.5, 0.5, 0.0), 2, 1.0),
}
OPPOSITE_FACE = {"right": "left", "left": "right", "top": "bot", "bot": "top", "front": "back", "back": "front"}

# Corner sign pattern of the reference: (x, y, z) signs, x slowest.
CORNER_SIGNS = np.array(
    [[sx, sy, sz] for sx in (1.0, -1.0) for sy in (1.0, -1.0) for sz in (1.0, -1.0)], dtype=np.float64
)


def _sample_grid() -> np.ndarray:
    """The reference's 10x10x10 unit-cube sample, x varying fastest."""
    a = np.arange(SAMPLE_GRID, dtype=np.float64) / (SAMPLE_GRID - 1)
    zz, yy, xx = np.meshgrid(a, a, a, indexing="ij")
    return np.stack((xx.ravel(), yy.ravel(), zz.ravel()), axis=1)


UNIT_GRID = _sample_grid()


# --------------------------------------------------------------------------
# Public result types
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class Cuboid:
    """A leaf cuboid in world space.

    ``axes`` rows are the local x (right), y (top), z (front) directions;
    ``dims`` are full edge lengths along them.
    """

    name: str
    center: np.ndarray
    axes: np.ndarray
    dims: np.ndarray

    def corners(self) -> np.ndarray:
        """(8, 3) corners in the reference order (+++, ++-, +-+, +--, -++, -+-, --+, ---)."""
        return self.center + (CORNER_SIGNS * (self.dims / 2.0)) @ self.axes


@dataclass(frozen=True)
class DeclaredRelation:
    """A relation the program declares, on leaf names and in world terms
    (see the module docstring for ``params``)."""

    kind: str
    members: tuple[str, ...]
    params: dict = field(hash=False)


@dataclass(frozen=True)
class ExecutedProgram:
    """Leaf cuboids and declared relations of an executed program."""

    cuboids: list[Cuboid]
    relations: list[DeclaredRelation]


# --------------------------------------------------------------------------
# Small vector helpers (3-vectors; plain arithmetic is faster than np.cross/linalg.norm)
# --------------------------------------------------------------------------


def _norm(v: np.ndarray) -> float:
    return math.sqrt(float(v @ v))


def _plus_eps(x: float) -> float:
    """``x + 1e-8`` as the float32 reference sees it: the guard term vanishes
    when it is below half an ulp of ``x`` (|x| >~ 0.17), and adding it in
    float64 anyway would shift results by ~1e-10 and flip exact-zero tests."""
    x32 = np.float32(x)
    if x32 + _F32_EPS_TERM == x32:
        return x
    return x + 1e-8


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.array((a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]), dtype=np.float64)


def _axis_angle_matrix(angle: float, n: np.ndarray) -> np.ndarray:
    """Rodrigues rotation matrix, written as in the reference (``n`` need not be unit)."""
    s, c = math.sin(angle), math.cos(angle)
    nx, ny, nz = float(n[0]), float(n[1]), float(n[2])
    return np.array(
        (
            (c + (1 - c) * nx * nx, (1 - c) * nx * ny - s * nz, (1 - c) * nx * nz + s * ny),
            ((1 - c) * nx * ny + s * nz, c + (1 - c) * ny * ny, (1 - c) * ny * nz - s * nx),
            ((1 - c) * nx * nz - s * ny, (1 - c) * ny * nz + s * nx, c + (1 - c) * nz * nz),
        ),
        dtype=np.float64,
    )


_QUARTER_X = np.array(((1.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0)))
_QUARTER_Y = np.array(((0.0, 0.0, 1.0), (0.0, 1.0, 0.0), (-1.0, 0.0, 0.0)))
_QUARTER_Z = np.array(((0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)))


def _acos_f32(u: np.ndarray, v: np.ndarray, guard: float = 0.0) -> float:
    """Angle between ``u`` and ``v`` computed the way the float32 reference does.

    The reference normalises both vectors (dividing by ``norm + guard``),
    takes their float32 dot product and its float32 ``acos``.  Near 1 the
    cosine is quantised in steps of 6e-8, so small angles come out
    noticeably different from the exact value (and angles below ~2.4e-4 rad
    become 0).  Geometry downstream of a rotation is sensitive to this,
    so the float32 steps are emulated here."""
    f32 = np.float32
    u32 = u.astype(f32)
    v32 = v.astype(f32)
    nu = u32 / f32(math.sqrt(float(u32.astype(np.float64) @ u32.astype(np.float64))) + guard)
    nv = v32 / f32(math.sqrt(float(v32.astype(np.float64) @ v32.astype(np.float64))) + guard)
    cosang = f32(f32(f32(nu[0] * nv[0]) + f32(nu[1] * nv[1])) + f32(nu[2] * nv[2]))
    if cosang > 1.0 or cosang < -1.0:
        return math.nan
    return float(np.arccos(cosang))


def _min_rotation(cur: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Rotation taking direction ``cur`` to ``target`` (the reference's
    ``findMinRotation``, including its choice of axis for opposite vectors)."""
    ncur = cur / _norm(cur)
    ntarget = target / _norm(target)
    normal = _cross(ncur, ntarget)
    nlen = _norm(normal)
    if nlen < ZERO_TOL:
        if float((_QUARTER_X @ ncur) @ ncur) != 0.0:
            cnormal = _QUARTER_X @ ncur
        elif float((_QUARTER_Y @ ncur) @ ncur) != 0.0:
            cnormal = _QUARTER_Y @ cur
        else:
            cnormal = _QUARTER_Z @ ncur
        return _axis_angle_matrix(math.pi, cnormal / _norm(cnormal))
    angle = _acos_f32(cur, target)
    if angle == 0.0 or math.isnan(angle):
        return np.eye(3)
    return _axis_angle_matrix(angle, normal / nlen)


# --------------------------------------------------------------------------
# Mutable execution state of one block
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class _ChildRef:
    """What a non-leaf cuboid expands into: a block, mirrored along ``flip`` for reflect copies."""

    block: str
    flip: str | None = None


@dataclass(eq=False)
class _Box:
    """A cuboid during execution of a block (the reference's ``Cuboid``)."""

    key: str
    label: str
    dims: np.ndarray
    pos: np.ndarray
    axes: np.ndarray  # rows: right, top, front directions
    aligned: bool
    child: _ChildRef | None
    attachments: list[_Att] = field(default_factory=list)
    move_atts: list[_Att] = field(default_factory=list)

    def point(self, local: np.ndarray) -> np.ndarray:
        """World position of local coordinates in [0, 1]^3."""
        return ((local - 0.5) * self.dims) @ self.axes + self.pos

    def local_of(self, gpt: np.ndarray, clamp: bool = False) -> np.ndarray:
        """Local coordinates of a world point (``getRelPos``)."""
        origin = self.point(np.zeros(3))
        if _is_diagonal(self.axes):
            # LAPACK's solve of a diagonal system is exactly this division.
            rel = (gpt - origin) / (self.dims * np.diagonal(self.axes))
        else:
            rel = np.linalg.solve((self.axes * self.dims[:, None]).T, gpt - origin)
        return np.clip(rel, 0.0, 1.0) if clamp else rel

    def corners(self) -> np.ndarray:
        return self.pos + (CORNER_SIGNS * (self.dims / 2.0)) @ self.axes


@dataclass(eq=False)
class _AttPoint:
    """A point fixed in a cuboid's local frame."""

    box: _Box
    local: np.ndarray

    def pos(self) -> np.ndarray:
        return self.box.point(self.local)

    def change_vector(self, dim: int) -> np.ndarray:
        """Velocity of this point when the cuboid grows by one unit along ``dim`` (centre fixed)."""
        return (self.local[dim] - 0.5) * self.box.axes[dim]


@dataclass(eq=False)
class _Att:
    """A recorded attachment: ``point`` should sit at ``gpos``; ``other`` is the partner's key."""

    point: _AttPoint
    gpos: np.ndarray
    other: str


@dataclass(frozen=True)
class _CopyOrigin:
    """Why a cuboid was declared by a macro, kept for declared relations."""

    kind: str  # "reflection" | "translation"
    source: str  # key of the copied cuboid
    axis: str
    index: int  # 1..count for translation, 1 for reflection
    count: int
    distance: float
    step: float  # local distance between consecutive members (translation)
    line: int


@dataclass(frozen=True)
class _DeclareOp:
    """Primitive cuboid declaration (what ``Cuboid`` lines and macros expand to)."""

    key: str
    label: str
    dims: tuple[float, float, float]
    aligned: bool
    child: _ChildRef | None
    origin: _CopyOrigin | None
    line: int


@dataclass(frozen=True)
class _AttachOp:
    """Primitive attach (what ``attach`` lines and macros expand to)."""

    moved: str
    target: str
    moved_point: tuple[float, float, float]
    target_point: tuple[float, float, float]
    via: str
    line: int


PrimitiveOp = _DeclareOp | _AttachOp


def _closest_sample_points(a: _Box, b: _Box) -> tuple[np.ndarray, np.ndarray] | None:
    """Closest pair between the two cuboids' sample grids, or ``None`` when a
    corner of one lies inside the other (the reference's ``getClosestPoints``).

    Ties go to the first sample of ``a`` and, for it, the first sample of
    ``b`` (x varying fastest), as with the reference's exhaustive search."""
    for inner, outer in ((a, b), (b, a)):
        for corner in inner.corners():
            rp = outer.local_of(corner)
            if rp.min() >= 0.0 and rp.max() <= 1.0:
                return None
    rot_a, rot_b = _grid_frame(a), _grid_frame(b)
    if _is_diagonal(rot_a) and _is_diagonal(rot_b):
        return _closest_separable(_grid_lines(a, rot_a), _grid_lines(b, rot_b))
    pa = ((UNIT_GRID - 0.5) * a.dims) @ rot_a + a.pos
    pb = ((UNIT_GRID - 0.5) * b.dims) @ rot_b + b.pos
    d2 = (
        (pa[:, None, 0] - pb[None, :, 0]) ** 2
        + (pa[:, None, 1] - pb[None, :, 1]) ** 2
        + (pa[:, None, 2] - pb[None, :, 2]) ** 2
    )
    nearest = d2.argmin(axis=1)
    best_a = int(d2[np.arange(len(pa)), nearest].argmin())
    return pa[best_a], pb[nearest[best_a]]


def _grid_frame(box: _Box) -> np.ndarray:
    """Rows x, y, x cross y of the sampling frame (the reference ignores the z axis)."""
    xdir = box.axes[0] / _plus_eps(_norm(box.axes[0]))
    ydir = box.axes[1] / _plus_eps(_norm(box.axes[1]))
    return np.stack((xdir, ydir, _cross(xdir, ydir)))


def _is_diagonal(m: np.ndarray) -> bool:
    return not np.any(m[~np.eye(3, dtype=bool)])


def _grid_lines(box: _Box, rot: np.ndarray) -> list[np.ndarray]:
    """World coordinate of the 10 sample planes along each axis of a box whose
    sampling frame is diagonal (bitwise equal to the full 3D sample grid)."""
    g = UNIT_GRID[:SAMPLE_GRID, 0]
    return [((g - 0.5) * box.dims[d]) * rot[d, d] + box.pos[d] for d in range(3)]


def _closest_separable(la: list[np.ndarray], lb: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Closest grid pair for axis-aligned grids, per axis instead of 1000x1000.

    The squared distance is a sum of per-axis terms, so the nearest sample of
    ``b`` is the per-axis nearest plane (first on ties) and the best sample of
    ``a`` minimises the sum of per-axis minima, summed in the same order."""
    mins, idx = [], []
    for d in range(3):
        diff = (la[d][:, None] - lb[d][None, :]) ** 2
        idx.append(diff.argmin(axis=1))
        mins.append(diff.min(axis=1))
    total = (mins[0][None, None, :] + mins[1][None, :, None]) + mins[2][:, None, None]
    i, j, k = np.unravel_index(int(total.argmin()), total.shape)
    pa = np.array((la[0][k], la[1][j], la[2][i]))
    pb = np.array((lb[0][idx[0][k]], lb[1][idx[1][j]], lb[2][idx[2][i]]))
    return pa, pb


class _BlockRun:
    """Executes the statements of one block in its own frame, recording the
    primitive operations (declarations and attaches) that macros expand to,
    from which the declared relations are derived."""

    def __init__(self, block: Block, source: str) -> None:
        self.block = block
        self.source = source
        bbox_dims = np.array(block.bbox.dims, dtype=np.float64)
        self.boxes: dict[str, _Box] = {"bbox": _Box("bbox", "bbox", bbox_dims, np.zeros(3), np.eye(3), True, None)}
        self.ops: list[PrimitiveOp] = []
        self._labels: set[str] = {"bbox"}

    # -- statements ---------------------------------------------------------

    def run_statement(self, stmt: Statement) -> None:
        if isinstance(stmt, CuboidStmt):
            if stmt.name == "bbox":
                self.boxes["bbox"].dims = np.array(stmt.dims, dtype=np.float64)
                return
            child = _ChildRef(stmt.name) if stmt.name.startswith(SUBPROGRAM_PREFIX) else None
            self.run_op(_DeclareOp(stmt.name, stmt.name, stmt.dims, stmt.aligned, child, None, stmt.line))
        elif isinstance(stmt, AttachStmt):
            self.run_op(_AttachOp(stmt.moved, stmt.target, stmt.moved_point, stmt.target_point, "attach", stmt.line))
        elif isinstance(stmt, SqueezeStmt):
            self._squeeze(stmt)
        elif isinstance(stmt, ReflectStmt):
            self._reflect(stmt)
        elif isinstance(stmt, TranslateStmt):
            self._translate(stmt)
        else:  # pragma: no cover - the parser only produces the types above
            raise TypeError(f"unknown statement {stmt!r}")

    def run_op(self, op: PrimitiveOp) -> None:
        """Execute one primitive operation and record it."""
        self.ops.append(op)
        if isinstance(op, _DeclareOp):
            self._declare(op)
            return
        try:
            self._attach(op)
        except np.linalg.LinAlgError as exc:
            raise ShapeAssemblyError(
                f"degenerate cuboid while attaching {op.moved}: {exc}", self.source, op.line
            ) from None

    def _declare(self, op: _DeclareOp) -> None:
        self._labels.add(op.label)
        self.boxes[op.key] = _Box(
            op.key, op.label, np.array(op.dims, dtype=np.float64), np.zeros(3), np.eye(3), op.aligned, op.child
        )

    def _squeeze(self, stmt: SqueezeStmt) -> None:
        """Two attaches: ``face`` of the moved cuboid onto ``first``, the opposite face onto ``second``."""
        for target, face in ((stmt.first, stmt.face), (stmt.second, OPPOSITE_FACE[stmt.face])):
            centre, axis, value = FACE_INFO[face]
            if target == "bbox":
                value = 1.0 - value
            u, v = (stmt.u, stmt.v)
            other = {0: (value, u, v), 1: (u, value, v), 2: (u, v, value)}[axis]
            self.run_op(_AttachOp(stmt.moved, target, centre, other, "squeeze", stmt.line))

    def _copy_key(self) -> str:
        """Reference naming ``cube{n}`` (n = cuboids so far); made unique if already taken."""
        key = f"cube{len(self.boxes) - 1}"
        while key in self.boxes:
            key += "'"
        return key

    def _copy_label(self, base: str) -> str:
        label, n = base, 1
        while label in self._labels:
            n += 1
            label = f"{base}_{n}"
        return label

    def _declare_copy(self, src: _Box, label: str, child: _ChildRef | None, origin: _CopyOrigin) -> str:
        key = self._copy_key()
        dims = (float(src.dims[0]), float(src.dims[1]), float(src.dims[2]))
        self.run_op(_DeclareOp(key, self._copy_label(label), dims, src.aligned, child, origin, origin.line))
        return key

    def _replay(
        self,
        src: _Box,
        copy_key: str,
        via: str,
        line: int,
        move: Callable[[np.ndarray], np.ndarray],
        flip_axis: int | None,
    ) -> None:
        """Re-issue every attach that moved ``src`` for its copy, moving the
        source point with ``move`` and expressing it in the target's frame."""
        for att in list(src.move_atts):
            local = att.point.local.copy()
            if flip_axis is not None:
                local[flip_axis] = 1.0 - local[flip_axis]
            moved_world = move(att.point.pos())
            target_local = self.boxes[att.other].local_of(moved_world, clamp=True)
            self.run_op(_AttachOp(copy_key, att.other, tuple(local.tolist()), tuple(target_local.tolist()), via, line))

    def _reflect(self, stmt: ReflectStmt) -> None:
        src = self.boxes[stmt.cuboid]
        bbox = self.boxes["bbox"]
        axis = AXIS_INDEX[stmt.axis]
        normal = bbox.axes[axis] / _norm(bbox.axes[axis])
        centre = bbox.pos.copy()
        child = _ChildRef(src.child.block, stmt.axis) if src.child is not None else None
        origin = _CopyOrigin("reflection", src.key, stmt.axis, 1, 1, 0.0, 0.0, stmt.line)
        key = self._declare_copy(src, f"{src.label}_ref", child, origin)

        def mirror(p: np.ndarray) -> np.ndarray:
            return p - 2.0 * normal * float(normal @ (p - centre))

        self._replay(src, key, "reflect", stmt.line, mirror, axis)

    def _translate(self, stmt: TranslateStmt) -> None:
        src = self.boxes[stmt.cuboid]
        bbox = self.boxes["bbox"]
        axis = AXIS_INDEX[stmt.axis]
        direction = bbox.axes[axis]
        step = float(bbox.dims[axis]) * stmt.distance / float(stmt.count)
        for i in range(1, stmt.count + 1):
            origin = _CopyOrigin("translation", src.key, stmt.axis, i, stmt.count, stmt.distance, step, stmt.line)
            key = self._declare_copy(src, f"{src.label}_t{i}", src.child, origin)
            offset = direction * (step * i)
            self._replay(src, key, "translate", stmt.line, lambda p, o=offset: p + o, None)

    # -- attach -------------------------------------------------------------

    def _attach(self, op: _AttachOp) -> None:
        moved = self.boxes[op.moved]
        target = self.boxes[op.target]
        if moved.key == "bbox":
            raise ShapeAssemblyError("the bounding box cannot be moved", self.source, op.line)
        ap = _AttPoint(moved, np.array(op.moved_point, dtype=np.float64))
        tp = _AttPoint(target, np.array(op.target_point, dtype=np.float64))
        gpos = tp.pos()
        target.attachments.append(_Att(tp, gpos, moved.key))
        prev = moved.attachments
        if len(prev) == 0:
            _first_attach(ap, gpos)
        elif moved.aligned:
            _aligned_attach(ap, tp)
        elif len(prev) == 1:
            _second_attach(ap, gpos, prev[0])
        else:
            if _colinear(prev):
                _orient(ap, gpos, prev)
            _maybe_scale(ap, gpos, prev)
        record = _Att(ap, gpos, target.key)
        prev.append(record)
        moved.move_atts.append(record)


# --------------------------------------------------------------------------
# Attachment solvers (the reference's first/second/gen/aligned attach)
# --------------------------------------------------------------------------


def _first_attach(ap: _AttPoint, gpos: np.ndarray) -> None:
    """No previous attachment: translate so the points coincide."""
    ap.box.pos = ap.box.pos + (gpos - ap.pos())


def _positive_root(at: float, bt: float, ct: float) -> tuple[float, float]:
    """``(-b + sqrt(b^2 - 4ac)) / (2a + 1e-8)`` and the discriminant; NaN root when it is negative."""
    disc = bt * bt - 4.0 * at * ct
    root = (-bt + math.sqrt(disc)) / _plus_eps(2.0 * at) if disc >= 0.0 else math.nan
    return root, disc


def _solvable(at: float, bt: float, ct: float) -> bool:
    """The reference's ``b^2 - 4ac > 0`` test, with discriminants that are zero
    up to rounding counted as not positive.

    A zero discriminant arises when the new target coincides with the previous
    one (e.g. two attachments to the same bbox face); the float32 reference
    then evaluates it as <= 0 and leaves the cuboid unscaled, whereas float64
    rounding noise could be positive and collapse a dimension."""
    disc = bt * bt - 4.0 * at * ct
    return disc > DISC_REL_TOL * (bt * bt + abs(4.0 * at * ct))


def _second_attach(ap: _AttPoint, gpos: np.ndarray, prev: _Att) -> None:
    """One previous attachment: grow one dimension so the new point is at the
    right distance from the previous one, then rotate about the previous point."""
    box = ap.box
    p_ap, a = prev.point, prev.gpos
    b = ap.pos()
    c = gpos
    if _norm(b - c) < SMALL_EPS:
        return
    dist2 = float((c - a) @ (c - a))
    min_dim, min_sf = HEIGHT, 1e8
    cn = b - a
    for dim in DIM_ORDER:
        nsf = ap.change_vector(dim)
        psf = p_ap.change_vector(dim)
        if float(np.abs(nsf).sum() + np.abs(psf).sum()) < SMALL_EPS:
            continue
        dn = nsf - psf
        at, bt, ct = float(dn @ dn), 2.0 * float(cn @ dn), float(cn @ cn) - dist2
        sf, _ = _positive_root(at, bt, ct)
        # Strictly smaller, so the earlier dimension wins ties; float64 noise
        # must not break exact ties (symmetric cuboids) differently.
        if abs(sf) < abs(min_sf) * (1.0 - TIE_REL_TOL) and _solvable(at, bt, ct):
            min_sf, min_dim = sf, dim
    if min_sf == 1e8:
        nsf = sum(ap.change_vector(d) for d in (HEIGHT, LENGTH, WIDTH))
        psf = sum(p_ap.change_vector(d) for d in (HEIGHT, LENGTH, WIDTH))
        dn = nsf - psf
        at, bt, ct = float(dn @ dn), 2.0 * float(cn @ dn), float(cn @ cn) - dist2
        sf, _ = _positive_root(at, bt, ct)
        if not math.isnan(sf) and _solvable(at, bt, ct):
            box.dims = box.dims + sf
    else:
        box.dims = box.dims.copy()
        box.dims[min_dim] += min_sf

    box.pos = box.pos + (a - p_ap.pos())
    nb = ap.pos() - a
    nc = c - a
    if _norm(nb) < ZERO_TOL or _norm(nc) < ZERO_TOL or _norm(nb - nc) < SMALL_EPS:
        return
    rot = _min_rotation(nb, nc)
    box.axes = box.axes @ rot.T
    box.pos = box.pos + (a - p_ap.pos())


def _colinear(prev: Sequence[_Att]) -> bool:
    """Whether all previous attachment targets lie on one line (|cross| <= EPS, unnormalised)."""
    if len(prev) == 2:
        return True
    o = prev[0].gpos
    line = prev[1].gpos - o
    return all(_norm(_cross(p.gpos - o, line)) <= EPS for p in prev[2:])


def _orient(ap: _AttPoint, gpos: np.ndarray, prev: Sequence[_Att]) -> None:
    """Rotate about the line through the first two previous targets so the new
    point turns towards its target (the reference's ``doOrient``)."""
    box = ap.box
    a0, a1 = prev[0].gpos, prev[1].gpos
    b = ap.pos()
    c = gpos
    axis = (a0 - a1) / _plus_eps(_norm(a0 - a1))
    aa = _plus_eps(float(axis @ axis))
    c_p = c + ((float(axis @ b) - float(axis @ c)) / aa) * axis
    a_p = a0 + ((float(axis @ b) - float(axis @ a0)) / aa) * axis
    fn = b - a_p
    noc = c_p - a_p
    at = float(fn @ fn)
    sf, _ = _positive_root(at, 2.0 * float((b - a_p) @ fn), float((b - a_p) @ (b - a_p)) - float(noc @ noc))
    if math.isnan(sf):
        return
    nob = (b + sf * fn) - a_p
    if _norm(nob) < ZERO_TOL or _norm(noc) < ZERO_TOL or _norm(nob - noc) < EPS:
        return
    nb = nob / _plus_eps(_norm(nob))
    nc = noc / _plus_eps(_norm(noc))
    angle = _acos_f32(nob, noc, 1e-8)
    rot = _axis_angle_matrix(angle, axis)
    if _norm(rot @ nb - nc) > EPS:
        rot = _axis_angle_matrix(angle, -axis)
    box.axes = box.axes @ rot.T
    box.pos = box.pos + (a0 - prev[0].point.pos())


def _maybe_scale(ap: _AttPoint, gpos: np.ndarray, prev: Sequence[_Att]) -> None:
    """Grow a dimension shared by all previous points towards the target when
    its direction is within acos(0.9) of the target direction (``maybeScale``)."""
    box = ap.box
    b = ap.pos()
    t_dir = gpos - b
    if _norm(t_dir) < EPS:
        return
    first = prev[0].point
    eq_dims = [
        dim
        for dim in DIM_ORDER
        if all(_norm(first.change_vector(dim) - p.point.change_vector(dim)) <= EPS for p in prev)
    ]
    nt_dir = t_dir / _plus_eps(_norm(t_dir))
    best = None
    for dim in eq_dims:
        sf = ap.change_vector(dim)
        nsf = sf / _plus_eps(_norm(sf))
        if float(nt_dir @ nsf) > COS_DIST_THRESH:
            best = dim  # the reference never tightens its threshold: the last qualifying dim wins
    if best is None:
        return
    axis = ap.change_vector(best)
    d = 1.0 / _plus_eps(_norm(axis - first.change_vector(best)))
    naxis = axis / _plus_eps(_norm(axis))
    t = (float(naxis @ b) - float(naxis @ gpos)) / _plus_eps(float(naxis @ naxis))
    offset = (gpos + t * naxis) - b
    growth = _norm((gpos - offset) - b)
    box.dims = box.dims.copy()
    box.dims[best] += growth * d
    box.pos = box.pos + (prev[0].gpos - first.pos())


def _aligned_attach(ap: _AttPoint, tp: _AttPoint) -> None:
    """Aligned cuboid with a previous attachment: grow (never rotate) towards
    the target cuboid if the two are more than 5% apart (``aligned_attach``)."""
    box = ap.box
    pair = _closest_sample_points(box, tp.box)
    if pair is None:
        return
    b, c = pair
    mv = max(float(box.dims.max()), float(tp.box.dims.max()))
    if _norm(b - c) < mv * ALIGNED_GAP_FRACTION:
        return
    rp = box.local_of(b, clamp=True)
    opposite = _AttPoint(box, 1.0 - rp)
    anchor = opposite.pos()
    grow = np.zeros(3)
    for dim in (LENGTH, HEIGHT, WIDTH):
        cv = (rp[dim] - 0.5) * box.axes[dim][dim]
        if cv != 0:
            grow[dim] = (c[dim] - b[dim]) / (2.0 * cv)
    box.dims = box.dims + np.where(grow > 0, grow, 0.0)
    box.pos = box.pos + (anchor - opposite.pos())


# --------------------------------------------------------------------------
# Blocks and hierarchy
# --------------------------------------------------------------------------


@dataclass(frozen=True)
class _LocalBox:
    """Final block-frame state of one cuboid of a block."""

    key: str
    label: str
    dims: np.ndarray
    pos: np.ndarray
    axes: np.ndarray
    child: _ChildRef | None


@dataclass(frozen=True)
class _LocalResult:
    """A block executed in its own frame (mirrored when ``mirror`` is set)."""

    bbox_dims: np.ndarray
    boxes: tuple[_LocalBox, ...]
    ops: tuple[PrimitiveOp, ...]
    mirror: np.ndarray  # (3,) +-1: the block-frame reflection applied to every cuboid


def _mirror_box(lb: _LocalBox, signs: np.ndarray) -> _LocalBox:
    """Mirror a block-frame cuboid through the bbox centre along the axes where
    ``signs`` is -1, keeping a right-handed frame: centre ``S c``, axes
    ``-(S a)`` (the reference's ``flipCuboid``; for one flipped axis this is a
    180 degree turn of the frame about that axis)."""
    return _LocalBox(lb.key, lb.label, lb.dims, lb.pos * signs, -(lb.axes * signs), lb.child)


class _Executor:
    """Runs a parsed program: local block runs (cached) and breadth-first placement."""

    def __init__(self, ast: ProgramAST) -> None:
        self.ast = ast
        self._cache: dict[_ChildRef, _LocalResult] = {}

    def local(self, ref: _ChildRef) -> _LocalResult:
        """Block ``ref.block`` executed in its own frame, mirrored along ``ref.flip``.

        The result does not depend on where the block is placed, so every
        instance of a block (and every mirrored copy) shares one run."""
        if ref not in self._cache:
            if ref.flip is None:
                self._cache[ref] = self._run_local(ref.block)
            else:
                base = self.local(_ChildRef(ref.block))
                signs = np.ones(3)
                signs[AXIS_INDEX[ref.flip]] = -1.0
                boxes = tuple(_mirror_box(lb, signs) for lb in base.boxes)
                self._cache[ref] = _LocalResult(base.bbox_dims, boxes, base.ops, signs)
        return self._cache[ref]

    def _run_local(self, name: str) -> _LocalResult:
        block = self.ast.blocks[name]
        run = _BlockRun(block, self.ast.source)
        for stmt in block.statements:
            run.run_statement(stmt)
        boxes = tuple(
            _LocalBox(b.key, b.label, b.dims.copy(), b.pos.copy(), b.axes.copy(), b.child)
            for b in run.boxes.values()
            if b.key != "bbox"
        )
        for b in boxes:
            if not (np.all(np.isfinite(b.dims)) and np.all(np.isfinite(b.axes)) and np.all(np.isfinite(b.pos))):
                raise ShapeAssemblyError(
                    f"cuboid {b.label!r} of block {name} has non-finite geometry", self.ast.source, block.line
                )
        return _LocalResult(run.boxes["bbox"].dims.copy(), boxes, tuple(run.ops), np.ones(3))

    def run(self) -> ExecutedProgram:
        root = self.ast.blocks[self.ast.root]
        root_box = _Placed("", "bbox", np.array(root.bbox.dims, dtype=np.float64), np.zeros(3), np.eye(3))
        queue: deque[tuple[_ChildRef, _Placed]] = deque([(_ChildRef(self.ast.root), root_box)])
        nodes: list[_PlacedNode] = []
        leaves: list[Cuboid] = []
        while queue:
            ref, abox = queue.popleft()
            local = self.local(ref)
            prefix = f"{abox.path}/" if abox.path else ""
            placed: dict[str, _Placed] = {"bbox": abox}
            leaf_keys: set[str] = set()
            if len(leaves) + len(queue) + len(local.boxes) > MAX_CUBOIDS:
                block = self.ast.blocks[ref.block]
                raise ShapeAssemblyError(
                    f"program expands to more than {MAX_CUBOIDS} cuboids", self.ast.source, block.line
                )
            for lb in local.boxes:
                world = _apply_delta(abox, local.bbox_dims, lb, prefix + lb.label)
                placed[lb.key] = world
                if lb.child is not None:
                    queue.append((lb.child, world))
                else:
                    leaf_keys.add(lb.key)
                    leaves.append(world.to_cuboid())
            nodes.append(_PlacedNode(ref, abox, local, placed, leaf_keys))
        return ExecutedProgram(leaves, _relations(nodes, leaves))


@dataclass(frozen=True)
class _Placed:
    """A cuboid (leaf, sub-program box or block bbox) in world space."""

    path: str
    label: str
    dims: np.ndarray
    pos: np.ndarray
    axes: np.ndarray

    def point(self, local: Sequence[float]) -> np.ndarray:
        return ((np.asarray(local, dtype=np.float64) - 0.5) * self.dims) @ self.axes + self.pos

    def to_cuboid(self) -> Cuboid:
        """Unit axes with lengths folded into ``dims`` (identical corners)."""
        norms = np.sqrt((self.axes**2).sum(axis=1))
        safe = np.where(norms > 0, norms, 1.0)
        return Cuboid(self.path, self.pos.copy(), self.axes / safe[:, None], self.dims * norms)


def _apply_delta(abox: _Placed, rbox_dims: np.ndarray, lb: _LocalBox, path: str) -> _Placed:
    """Place a block-frame cuboid into the world box of its block (the
    reference's ``apply_delta``: element-wise dim ratio, rotated but unscaled position)."""
    rot = abox.axes.T
    return _Placed(
        path,
        lb.label,
        lb.dims * (abox.dims / rbox_dims),
        rot @ lb.pos + abox.pos,
        lb.axes @ rot.T,
    )


@dataclass(frozen=True)
class _PlacedNode:
    """One executed block instance in world space."""

    ref: _ChildRef
    abox: _Placed
    local: _LocalResult
    placed: dict[str, _Placed]
    leaf_keys: set[str]


# --------------------------------------------------------------------------
# Declared relations
# --------------------------------------------------------------------------


def _tuple3(v: Sequence[float]) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def _leaves_under(path: str, leaves: Sequence[Cuboid]) -> list[Cuboid]:
    prefix = path + "/"
    return [c for c in leaves if c.name.startswith(prefix)]


def _distance_to_box(point: np.ndarray, c: Cuboid) -> float:
    local = c.axes @ (point - c.center)
    excess = np.maximum(np.abs(local) - c.dims / 2.0, 0.0)
    return _norm(excess)


def _touching(placed: _Placed, point: np.ndarray, leaves: Sequence[Cuboid]) -> tuple[str, ...]:
    """Leaves of sub-program ``placed`` within 2% of its size of ``point`` (or its path)."""
    tol = TOUCH_FRACTION * float(np.max(np.abs(placed.dims)))
    hits = tuple(c.name for c in _leaves_under(placed.path, leaves) if _distance_to_box(point, c) <= tol)
    return hits or (placed.path,)


def _dedupe(names: Iterable[str]) -> tuple[str, ...]:
    return tuple(dict.fromkeys(names))


class _NodeRelations:
    """Turns the primitive operations of one placed block into declared relations."""

    def __init__(self, node: _PlacedNode, leaves: Sequence[Cuboid]) -> None:
        self.node = node
        self.leaves = leaves
        self.block_path = node.abox.path or node.ref.block
        self.mirror = node.local.mirror
        self.mirrored = bool(np.any(self.mirror < 0))

    def members(self, key: str, point: np.ndarray | None) -> tuple[str, ...]:
        """Leaf names standing for cuboid ``key`` (all leaves of a sub-program,
        or those touching ``point`` when given)."""
        if key == "bbox":
            return ()
        placed = self.node.placed[key]
        if key in self.node.leaf_keys:
            return (placed.path,)
        if point is None:
            return tuple(c.name for c in _leaves_under(placed.path, self.leaves)) or (placed.path,)
        return _touching(placed, point, self.leaves)

    def path(self, key: str) -> str:
        return f"{self.block_path}/bbox" if key == "bbox" else self.node.placed[key].path

    def effective_local(self, key: str, local: Sequence[float]) -> tuple[float, float, float]:
        """Local coordinates, on the placed cuboid, of the point a statement names.

        In a mirrored block the cuboid frames are turned (``-(S a)``), so the
        mirror image of local point ``v`` is ``1 - v``; the bbox is not turned,
        only its mirrored coordinates flip."""
        v = np.asarray(local, dtype=np.float64)
        if not self.mirrored:
            return _tuple3(v)
        if key == "bbox":
            return _tuple3(np.where(self.mirror < 0, 1.0 - v, v))
        return _tuple3(1.0 - v)

    def world_direction(self, axis: str) -> np.ndarray:
        """World direction of a block axis, after the block's mirror."""
        e = np.zeros(3)
        e[AXIS_INDEX[axis]] = 1.0
        d = (e * self.mirror) @ self.node.abox.axes
        return d / _norm(d)

    def attachment(self, op: _AttachOp) -> DeclaredRelation:
        src, dst = self.node.placed[op.moved], self.node.placed[op.target]
        src_local = self.effective_local(op.moved, op.moved_point)
        dst_local = self.effective_local(op.target, op.target_point)
        point = dst.point(dst_local)
        source_point = src.point(src_local)
        members = self.members(op.moved, source_point) + self.members(op.target, point)
        params = {
            "via": op.via,
            "source": self.path(op.moved),
            "target": self.path(op.target),
            "source_local": src_local,
            "target_local": dst_local,
            "point": _tuple3(point),
            "source_point": _tuple3(source_point),
            "block": self.block_path,
            "line": op.line,
        }
        return DeclaredRelation("attachment", _dedupe(members), params)

    def reflection(self, op: _DeclareOp, origin: _CopyOrigin) -> DeclaredRelation:
        params = {
            "axis": origin.axis,
            "source": self.path(origin.source),
            "copy": self.path(op.key),
            "plane_point": _tuple3(self.node.abox.pos),
            "plane_normal": _tuple3(self.world_direction(origin.axis)),
            "block": self.block_path,
            "line": origin.line,
        }
        members = self.members(origin.source, None) + self.members(op.key, None)
        return DeclaredRelation("reflection", _dedupe(members), params)

    def translation(self, origin: _CopyOrigin, copies: Sequence[str]) -> DeclaredRelation:
        params = {
            "axis": origin.axis,
            "source": self.path(origin.source),
            "copies": tuple(self.path(k) for k in copies),
            "count": origin.count,
            "distance": origin.distance,
            "direction": _tuple3(self.world_direction(origin.axis)),
            "step": origin.step,
            "block": self.block_path,
            "line": origin.line,
        }
        members = self.members(origin.source, None)
        for k in copies:
            members += self.members(k, None)
        return DeclaredRelation("translation", _dedupe(members), params)

    def all(self) -> list[DeclaredRelation]:
        out: list[DeclaredRelation] = []
        groups: dict[tuple[str, int], list[str]] = {}
        for op in self.node.local.ops:
            if isinstance(op, _AttachOp):
                out.append(self.attachment(op))
            elif op.origin is not None and op.origin.kind == "reflection":
                out.append(self.reflection(op, op.origin))
            elif op.origin is not None and op.origin.kind == "translation":
                group = groups.setdefault((op.origin.source, op.origin.line), [])
                group.append(op.key)
                if op.origin.index == op.origin.count:
                    out.append(self.translation(op.origin, group))
                    del groups[(op.origin.source, op.origin.line)]
        return out


def _relations(nodes: Sequence[_PlacedNode], leaves: Sequence[Cuboid]) -> list[DeclaredRelation]:
    out: list[DeclaredRelation] = []
    for node in nodes:
        out.extend(_NodeRelations(node, leaves).all())
    return out


# --------------------------------------------------------------------------
# Entry points
# --------------------------------------------------------------------------


def execute_program(ast: ProgramAST) -> ExecutedProgram:
    """Execute an already parsed program.

    Degenerate input (zero-size or non-finite cuboids) raises
    :class:`ShapeAssemblyError` instead of numpy warnings."""
    with np.errstate(all="ignore"):
        return _Executor(ast).run()


def execute(text: str, source: str = "<string>") -> ExecutedProgram:
    """Parse and execute ShapeAssembly program text."""
    return execute_program(parse_program(text, source))


def execute_file(path: str | PathLike[str]) -> ExecutedProgram:
    """Execute a program file; errors name the file as ``<category>/<name>``."""
    p = Path(path)
    source = f"{p.parent.name}/{p.name}" if p.parent.name else p.name
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ShapeAssemblyError(f"cannot read program: {exc}", source, None) from exc
    return execute(text, source)
