"""The bodies the collision check measures (:mod:`prs3_post.check.collision`): cylinders on the tool
axis (the tool, the holder, the spindle nose), the points on their surfaces, and the swept region of a
feature where the cutting tool may touch the part.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from prs3_post.core.errors import LimitError
from prs3_post.core.types import BoolArray, FloatArray, IntArray
from prs3_post.machine.model import Holder
from prs3_post.part.face import Face
from prs3_post.part.setup_transform import Setup

__all__ = ["AZIMUTHS", "BODY_NAMES", "RING_SPACING_MM", "CollisionError", "Region", "body_cylinders", "frames",
           "surface_points", "swept_region"]

#: The bodies, bottom up.
BODY_NAMES = ("tool", "holder", "spindle nose")
AZIMUTHS = 24
RING_SPACING_MM = 2.0


class CollisionError(LimitError):
    """A body closer to the part than the clearance min (or inside it).

    Attributes
    ----------
    body : str — which: ``tool``, ``holder`` or ``spindle nose`` (:data:`BODY_NAMES`)
    """

    def __init__(self, message: str, *, body: str, names_keys: bool | tuple[str, ...] = False):
        super().__init__(message, names_keys=names_keys)
        self.body = body


def body_cylinders(tool_diameter: float, tool_length: float, holder: Holder) -> FloatArray:
    """(3, 3) mm: radius, start and end along the axis from the tip, of the tool, holder and nose.

    ``tool_length``: mm from the gauge line to the tip; the holder ends at the gauge line."""
    gauge = tool_length
    z1 = gauge - holder.holder_length
    return np.array([[tool_diameter / 2, 0.0, z1], [holder.holder_diameter / 2, z1, gauge],
                     [holder.nose_diameter / 2, gauge, gauge + holder.nose_length]])


def surface_points(cylinders: FloatArray) -> tuple[FloatArray, IntArray]:
    """Points on the cylinders' surfaces in the tool frame (z along the axis from the tip): (P, 3), body (P,)."""
    points, body = [], []
    angle = 2 * np.pi * np.arange(AZIMUTHS) / AZIMUTHS
    ring = np.column_stack([np.cos(angle), np.sin(angle)])
    for b, (radius, z0, z1) in enumerate(cylinders):
        stations = np.linspace(z0, z1, max(2, math.ceil((z1 - z0) / RING_SPACING_MM) + 1))
        side = np.concatenate([np.column_stack([radius * ring, np.full(AZIMUTHS, z)]) for z in stations])
        discs = [np.array([[0.0, 0.0, z]]) for z in (z0, z1)]
        for fraction in np.arange(1, math.ceil(radius / RING_SPACING_MM)) / math.ceil(radius / RING_SPACING_MM):
            discs += [np.column_stack([fraction * radius * ring, np.full(AZIMUTHS, z)]) for z in (z0, z1)]
        pts = np.concatenate([side, *discs])
        points.append(pts)
        body.append(np.full(len(pts), b))
    return np.concatenate(points), np.concatenate(body)


def frames(axis: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(S, 3) unit x and y vectors perpendicular to each unit axis."""
    helper = np.where(np.abs(axis[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    x = np.cross(axis, helper)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    return x, np.cross(axis, x)


@dataclass(frozen=True, slots=True)
class Region:
    """The feature's swept region: cells of a grid in the face's (u, v) plane (none: no region)."""

    face: Face | None
    cells: BoolArray
    low: FloatArray
    cell: float

    def contains(self, tip: FloatArray) -> BoolArray:
        """(S,) bool: the tips (S, 3) mm, part frame, lie over the region."""
        out = np.zeros(len(tip), dtype=bool)
        if self.face is None or not self.cells.size or not len(tip):
            return out
        uv = (tip - self.face.origin) @ np.stack([self.face.u, self.face.v], axis=1)
        at = np.floor((uv - self.low) / self.cell).astype(np.int64)
        ok = (at >= 0).all(axis=1) & (at < self.cells.shape).all(axis=1)
        out[ok] = self.cells[at[ok, 0], at[ok, 1]]
        return out

    def covers(self, tip: FloatArray, radius: FloatArray) -> BoolArray:
        """(S,) bool: every point within ``radius`` (S,) mm of the tips (S, 3), part frame, lies over the
        region (:meth:`contains` of each is True: the square of cells round the disc is all in)."""
        out = np.zeros(len(tip), dtype=bool)
        if self.face is None or not self.cells.size or not len(tip):
            return out
        uv = (tip - self.face.origin) @ np.stack([self.face.u, self.face.v], axis=1)
        reach = (np.asarray(radius, dtype=np.float64) + 1e-9)[:, None]
        first = np.floor((uv - reach - self.low) / self.cell).astype(np.int64)
        last = np.floor((uv + reach - self.low) / self.cell).astype(np.int64)
        ok = (first >= 0).all(axis=1) & (last < self.cells.shape).all(axis=1)
        table = np.zeros((self.cells.shape[0] + 1, self.cells.shape[1] + 1), dtype=np.int64)
        table[1:, 1:] = self.cells.cumsum(axis=0).cumsum(axis=1)   # cells in [0, i) × [0, j)
        f, e = first[ok], last[ok] + 1
        count = table[e[:, 0], e[:, 1]] - table[f[:, 0], e[:, 1]] - table[e[:, 0], f[:, 1]] + table[f[:, 0], f[:, 1]]
        out[ok] = count == (e - f).prod(axis=1)
        return out


#: Feed tips drawn into the swept region at a time (memory: a few arrays of this many rows).
_SWEPT_ROWS = 1 << 16


def swept_region(face: Face | None, feed_tips: FloatArray, radius: float, *, cell: float = 0.25,
                 setup: Setup | None = None) -> Region:
    """The region within about ``radius`` of the polyline of the feed tips (M, 3) in the face's (u, v).

    The polyline is drawn on a grid of ``cell`` mm (points every half cell along each segment),
    widened by ``radius`` plus a cell, and each tip looks up its cell: a region a cell or two wider
    than the exact one, at a cost linear in the rows. ``setup``: the tips are in the machine frame
    (taken to the part's as :func:`_to_part` does). The tips are taken ``_SWEPT_ROWS`` at a time
    (the grid's extent first, then each piece drawn from the last tip of the one before): the same
    cells as all at once, without arrays as long as the program.
    """
    none = Region(face=face, cells=np.zeros((0, 0), dtype=bool), low=np.zeros(2), cell=cell)
    if face is None or not len(feed_tips):
        return none
    tips = np.asarray(feed_tips, dtype=np.float64).reshape(-1, 3)
    plane_of = face

    def plane(lo: int, hi: int) -> tuple[FloatArray, FloatArray]:
        return _plane_coordinates(tips[lo:hi] if setup is None else _to_part(setup, tips[lo:hi]), plane_of)

    pieces = range(0, len(tips), _SWEPT_ROWS)
    least, most = np.full(2, np.inf), np.full(2, -np.inf)
    for lo in pieces:
        u, v = plane(lo, lo + _SWEPT_ROWS)
        least, most = np.minimum(least, [u.min(), v.min()]), np.maximum(most, [u.max(), v.max()])
    low = least - radius - 2 * cell
    size = np.ceil((most + radius + 2 * cell - low) / cell).astype(np.int64) + 1
    if size.prod() > 4e7:                               # a region too large to draw: no exemption
        return none
    grid = np.zeros(tuple(size), dtype=bool)
    for lo in pieces:                                   # each piece from the tip before: its segment too
        _draw(grid, *plane(max(lo - 1, 0), lo + _SWEPT_ROWS), low, cell)
    reach = math.ceil(radius / cell) + 1
    wide = np.zeros_like(grid)
    for du in range(-reach, reach + 1):
        for dv in range(-reach, reach + 1):
            if (abs(du) - 1) ** 2 + (abs(dv) - 1) ** 2 > (radius / cell) ** 2 and (du or dv):
                continue
            wide[max(du, 0):size[0] + min(du, 0), max(dv, 0):size[1] + min(dv, 0)] |= \
                grid[max(-du, 0):size[0] + min(-du, 0), max(-dv, 0):size[1] + min(-dv, 0)]
    return Region(face=face, cells=wide, low=low, cell=cell)


def _draw(grid: BoolArray, u: FloatArray, v: FloatArray, low: FloatArray, cell: float) -> None:
    """Mark the cells of ``grid`` (corner ``low``, ``cell`` mm) that the polyline of (u, v) (N,), (N,)
    mm passes through: every point's, and points every half cell along each segment between cells."""
    at_u = np.floor((u - low[0]) / cell).astype(np.int64)
    at_v = np.floor((v - low[1]) / cell).astype(np.int64)
    grid[at_u, at_v] = True                             # every tip; a segment within one cell adds no other
    crossing = np.flatnonzero((at_u[1:] != at_u[:-1]) | (at_v[1:] != at_v[:-1]))
    feed_uv = np.column_stack([u[crossing], v[crossing], u[crossing + 1], v[crossing + 1]])
    ends = feed_uv[:, :2], feed_uv[:, 2:]
    length = np.hypot(ends[1][:, 0] - ends[0][:, 0], ends[1][:, 1] - ends[0][:, 1])
    steps = np.maximum(1, np.ceil(length / (0.5 * cell)).astype(np.int64))
    seg = np.repeat(np.arange(len(steps)), steps + 1)
    t = (np.arange(len(seg)) - np.repeat(np.cumsum(steps + 1) - (steps + 1), steps + 1)) / np.repeat(steps, steps + 1)
    points = ends[0][seg] + t[:, None] * (ends[1][seg] - ends[0][seg])
    index = np.floor((points - low) / cell).astype(np.int64)
    grid[index[:, 0], index[:, 1]] = True


def _plane_coordinates(points: FloatArray, face: Face) -> tuple[FloatArray, FloatArray]:
    """(N,), (N,) mm: the u and v of points (N, 3) in the face's plane (column by column: a matrix
    product of a long (N, 3) array takes numpy's slow path)."""
    d = [points[:, k] - face.origin[k] for k in range(3)]
    u, v = (d[0] * axis[0] + d[1] * axis[1] + d[2] * axis[2] for axis in (face.u, face.v))
    return u, v


def _to_part(setup: Setup, points: FloatArray) -> FloatArray:
    """:meth:`Setup.points_to_part` column by column (a matrix product of a long (N, 3) array takes
    numpy's slow path)."""
    d = [points[:, k] - setup.shift[k] for k in range(3)]
    rotation = setup.rotation
    return np.column_stack([d[0] * rotation[0, j] + d[1] * rotation[1, j] + d[2] * rotation[2, j] for j in range(3)])
