"""Clearance of the tool, the holder and the spindle nose from the part, along a program's motion.

The bodies are cylinders on the tool axis (:class:`~prs3_post.machine.model.Holder`): from the tip up
the tool (the operation's diameter, up to the holder), the holder (to the spindle's gauge line:
the tool's length is the machine's, or the tool table's), the spindle nose. The clearance of a pose
is the smallest signed distance of a body to the part's triangles (negative inside the part: ray
parity along a fixed direction), so a penetration is reported by its depth.

Only the tool may be in the part, and only where it cuts: while the tip is within the feature's
swept region (the tool radius around the feed moves' tips, in the face's plane), its part below
``clearance_min`` above the worked face is not checked and the rest is measured from the part
without that face (the tool touches the face where it enters, and the face's edges where a feature
runs over them: a point that high is that far from both; a wall beside the face rises higher, and
is measured). Everything else must stay ``clearance_min`` clear.

How, in three stages (numpy only):

1. **Bounds, coarse to fine.** Each body is cut into pieces (at most ``max(radius, PIECE_MM)``
   long). Poses are grouped ``LEVELS`` at a time (4096, 256, 16, then one): a group's piece is
   bounded by a sphere round its first pose's piece, widened by how far the group moves it, and a
   (group, piece, triangle) pair is dropped as soon as that sphere is ``REACH_MM`` beyond
   ``clearance_min`` from the triangle; the pairs left are split into the next level's groups. For
   one pose and a triangle the bound is the larger of the gap between the cylinder and the
   triangle's plane (tight for the holder's end over the face) and the exact distance between the
   cylinder's axis segment and the triangle less its radius (tight beside a wall). The first level
   meets only the triangles whose boxes the part's :class:`~prs3_post.part.meshindex.TriangleIndex`
   finds within that reach of each group's sphere (a superset of those it keeps, measured the same
   way), so no array is as long as groups × pieces × triangles; most pairs go there, and the cost
   follows the poses that are near the part and the triangles near them.
2. **Exact where it matters.** A pose whose bound is under ``clearance_min`` is measured on its
   bodies' surfaces: rings every ``RING_SPACING_MM`` along each, ``AZIMUTHS`` points per ring, and
   rings on its end discs, against the triangles whose pair bound was under ``clearance_min`` + 2 mm
   (exact point–triangle distances; farther, the body is "over" that); the
   sampling makes a cylinder facing a plane at most ``r (1 − cos(π / AZIMUTHS))`` (0.19 mm for the
   holder) closer than the points say. Poses are measured closest bound first; once a body is
   found too close, ``AFTER_HIT`` more blocks at most (its depth is the deepest of those), and the
   motion between poses is not checked further (the program is refused already).
3. **Between poses.** When the poses are the samples of one motion (``connected``), a body moves at
   most δ = |Δtip| + ρ·θ between two of them (ρ: its farthest point from the tip, θ: the axis's
   turn), so its clearance there is at least (c₀ + c₁ − δ) / 2 from the two poses' clearances c₀,
   c₁. Where that is under ``clearance_min`` − ``SWEEP_SLACK_MM`` the interval is halved (the tip
   straight between them, the axis on its great circle: exact for a move that translates the head,
   which verify samples at its end only) and the halves checked the same way. A rapid through the
   part between two features is caught there.

Why not a library: trimesh's proximity queries need rtree (not installed), and scipy (for a k-d tree)
is not installed either; python-fcl or manifold3d would be a compiled dependency for what the
staged bounds above do in numpy at 10⁵ poses a second or more on the demo parts
(``bench/bench_dynamics.py``). The nearest-triangle queries of the measurements walk the same
index (:func:`~prs3_post.part.meshdist.nearest_distance`); on fine meshes see ``bench/bench_collision.py``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, replace

import numpy as np

from prs3_post.core.toolpath import JointProgram
from prs3_post.core.types import BoolArray, FloatArray, IntArray
from prs3_post.machine.model import Holder, Machine
from prs3_post.part.face import Face
from prs3_post.part.meshdist import (
    PAIR_BUDGET,
    inside,
    nearest_distance,
    point_triangle_distance,
    segment_triangle_distance,
    triangle_distance,
)
from prs3_post.part.meshindex import TriangleIndex
from prs3_post.part.setup_transform import Setup

__all__ = ["BODY_NAMES", "RAPID_TOUCH_MM", "Approach", "Clearance", "ProgramClearance", "RapidClearance",
           "approach_label", "body_cylinders", "check_program", "check_rapids", "clearance", "feed_tips_of",
           "inside", "measure_program", "point_triangle_distance", "rapid_diameter_from_entry", "rapid_tool_clearance",
           "tool_words"]

#: The bodies, bottom up.
BODY_NAMES = ("tool", "holder", "spindle nose")
AZIMUTHS = 24
RING_SPACING_MM = 2.0
#: mm, the longest piece a body is cut into for the bounds (or its radius, if longer).
PIECE_MM = 10.0
#: Poses per group at each level of the bounds.
LEVELS = (4096, 256, 16, 1)
#: mm beyond ``clearance_min``: a body farther than this from the part is reported as "over" it.
REACH_MM = 10.0
#: mm: the motion between two poses may come this much closer than ``clearance_min`` unseen (the
#: halving stops there).
SWEEP_SLACK_MM = 0.05
#: Blocks of 64 poses measured, closest bound first, once a body is found too close (the depth
#: reported is the deepest of those: the lowest bounds are where it is).
AFTER_HIT = 4
#: mm: minima this close are the same (the report's rounding); the earliest pose is named.
_TIE_MM = 5e-4
#: Pairs measured at a time (memory).
_CHUNK = PAIR_BUDGET


def body_cylinders(tool_diameter: float, tool_length: float, holder: Holder) -> FloatArray:
    """(3, 3) mm: radius, start and end along the axis from the tip, of the tool, holder and nose.

    ``tool_length``: mm from the gauge line to the tip; the holder ends at the gauge line."""
    gauge = tool_length
    z1 = gauge - holder.holder_length
    return np.array([[tool_diameter / 2, 0.0, z1], [holder.holder_diameter / 2, z1, gauge],
                     [holder.nose_diameter / 2, gauge, gauge + holder.nose_length]])


def _surface_points(cylinders: FloatArray) -> tuple[FloatArray, IntArray]:
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


def _frames(axis: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(S, 3) unit x and y vectors perpendicular to each unit axis."""
    helper = np.where(np.abs(axis[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    x = np.cross(axis, helper)
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    return x, np.cross(axis, x)


@dataclass(frozen=True, slots=True)
class _Region:
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


def _swept(face: Face | None, feed_tips: FloatArray, radius: float, *, cell: float = 0.25,
           setup: Setup | None = None) -> _Region:
    """The region within about ``radius`` of the polyline of the feed tips (M, 3) in the face's (u, v).

    The polyline is drawn on a grid of ``cell`` mm (points every half cell along each segment),
    widened by ``radius`` plus a cell, and each tip looks up its cell: a region a cell or two wider
    than the exact one, at a cost linear in the rows. ``setup``: the tips are in the machine frame
    (taken to the part's as :func:`_to_part` does). The tips are taken ``_SWEPT_ROWS`` at a time
    (the grid's extent first, then each piece drawn from the last tip of the one before): the same
    cells as all at once, without arrays as long as the program.
    """
    none = _Region(face=face, cells=np.zeros((0, 0), dtype=bool), low=np.zeros(2), cell=cell)
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
    return _Region(face=face, cells=wide, low=low, cell=cell)


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


@dataclass(frozen=True, slots=True)
class Clearance:
    """The closest approach of each body to the part over the poses checked.

    Attributes
    ----------
    distance : (3,) float — mm, per body (tool, holder, nose): smallest signed distance (negative:
        penetration depth); inf: no pose (or the tool always below the face it cuts)
    sample : (3,) int — the pose of that minimum (-1: none); a minimum between two connected poses
        is the later pose's
    point : (3, 3) float — mm, part frame, the body point of that minimum
    exact : (3,) bool — the minimum over the surface points (False: a lower bound, which happens only
        above ``clearance_min``: the poses that could be closer were all measured)
    """

    distance: FloatArray
    sample: IntArray
    point: FloatArray
    exact: BoolArray

    def worst(self) -> int:
        """The body with the smallest clearance."""
        return int(np.argmin(self.distance))


@dataclass(frozen=True, slots=True)
class _Part:
    """The part's triangles with what the bounds need of them (part frame, mm)."""

    triangles: FloatArray          # (T, 3, 3)
    normal: FloatArray             # (T, 3) unit (0 for a degenerate triangle)
    offset: FloatArray             # (T,) normal · a point of the plane
    low: FloatArray                # (T, 3) bounding boxes
    high: FloatArray
    others: BoolArray              # (T,) not a triangle of the worked face
    face: Face | None              # the worked face (None: none, no tool cuts)
    band: float                    # mm above the face: the cutting tool's part below this may touch the part
    index: TriangleIndex           # the triangles' boxes, for the queries that need only the near ones

    @classmethod
    def of(cls, triangles: FloatArray, face: Face | None, band: float) -> _Part:
        normal = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
        others = np.ones(len(triangles), dtype=bool)
        if face is not None:
            others[np.asarray(face.triangles, dtype=np.int64)] = False
        index = TriangleIndex(triangles)
        return cls(triangles=triangles, normal=normal, offset=(normal * triangles[:, 0]).sum(axis=1),
                   low=index.low, high=index.high, others=others, face=face, band=band, index=index)


def _pieces(cylinders: FloatArray) -> FloatArray:
    """(Q, 4): radius, start, end (mm along the axis from the tip) and body of each piece."""
    out = []
    for b, (radius, z0, z1) in enumerate(cylinders):
        if z1 <= z0:                                    # a body not checked
            continue
        n = max(1, math.ceil((z1 - z0) / max(radius, PIECE_MM)))
        edges = np.linspace(z0, z1, n + 1)
        out += [(radius, edges[k], edges[k + 1], b) for k in range(n)]
    return np.array(out, dtype=np.float64)


def _pose_pairs(part: _Part, tip: FloatArray, axis: FloatArray, cutting: BoolArray, pieces: FloatArray,
                s: IntArray, q: IntArray, t: IntArray, near: float, spread: _Spread | None = None) -> FloatArray:
    """(K,) mm: a lower bound of the distance of piece ``q`` at pose ``s`` from triangle ``t``, pair by
    pair (inf: a pair that does not count: the cutting tool's part below the band, or the face).

    ``spread``: each pose stands for a group of poses (:class:`_Spread`): every body point of the
    group is the representative cylinder's moved by a vector of the tip's box plus at most
    ``(|z| + radius) · spread.turn`` (z: the piece's farthest station from the tip), so the plane
    bound is lower by the box's reach along the plane's normal and the axial one by the box's half
    diagonal (and both by the turn's); a cutting group's tool is not cut at the band (its poses'
    heights differ), only spared the face."""
    radius, a, p = pieces[q, 0], axis[s], tip[s]
    lo, hi = pieces[q, 1].copy(), pieces[q, 2]
    cut = cutting[s] & (pieces[q, 3] == 0)
    gone = cut & ~part.others[t]
    if cut.any() and spread is None:                # keep only what is above the band (less the tilt's reach)
        face = part.face
        assert face is not None                     # a tool cuts only with a face (_swept)
        along = a @ face.normal
        height = (p - face.origin) @ face.normal
        tilt = radius * np.sqrt(np.clip(1.0 - along ** 2, 0.0, 1.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            below = np.where(along > 1e-9, (part.band - tilt - height) / along, -np.inf)
        lo = np.where(cut, np.maximum(lo, below), lo)
        gone |= cut & (lo >= hi)
    e0, e1 = p + lo[:, None] * a, p + hi[:, None] * a
    normal = part.normal[t]
    h0 = (e0 * normal).sum(axis=1) - part.offset[t]
    h1 = (e1 * normal).sum(axis=1) - part.offset[t]
    bulge = radius * np.sqrt(np.clip(1.0 - (a * normal).sum(axis=1) ** 2, 0.0, 1.0))
    widen: FloatArray | float = 0.0
    if spread is not None:                          # the box along the plane's normal; a ball round the axis
        turned = (np.maximum(np.abs(lo), np.abs(hi)) + radius) * spread.turn[s]
        bulge = bulge + (np.abs(normal @ spread.frame.T) * spread.half[s]).sum(axis=1) + turned
        widen = np.linalg.norm(spread.half[s], axis=1) + turned
    bound = np.maximum(np.maximum(np.minimum(h0, h1) - bulge, -np.maximum(h0, h1) - bulge), 0.0)
    need = np.flatnonzero((bound < near) & ~gone)
    if len(need):
        corners = part.triangles[t[need]]
        axial = segment_triangle_distance(e0[need], e1[need], corners) - radius[need]
        # the slab: the triangle wholly below the piece's start or above its end, along the axis
        along = ((corners - p[need, None, :]) * a[need, None, :]).sum(axis=2)                 # (k, 3)
        slab = np.maximum(lo[need] - along.max(axis=1), along.min(axis=1) - hi[need])
        if spread is not None:
            axial -= np.asarray(widen)[need]
            far = np.linalg.norm(corners - p[need, None, :], axis=2).max(axis=1)
            slab -= (np.abs(a[need] @ spread.frame.T) * spread.half[s[need]]).sum(axis=1) + far * spread.turn[s[need]]
        bound[need] = np.maximum(bound[need], np.maximum(axial, slab))
    return np.where(gone, np.inf, bound)


@dataclass(frozen=True, slots=True)
class _Spread:
    """How far the poses a representative pose stands for may be from it (:func:`_pose_pairs`).

    Attributes
    ----------
    frame : (3, 3) float — unit rows: the axes of the box (part frame; the worked face's u, v and normal)
    half : (S, 3) float — mm, half the box's size along each: every tip of the group is in the box
        round the representative tip
    turn : (S,) float — the largest chord |a − a₀| between their unit axes and its axis (a body
        point at z along the axis and r off it moves at most (|z| + r) times that)
    """

    frame: FloatArray
    half: FloatArray
    turn: FloatArray


def _bounds(part: _Part, tip: FloatArray, axis: FloatArray, cutting: BoolArray, pieces: FloatArray, *,
            reach: float, near: float, spread: _Spread | None = None) -> tuple[FloatArray, IntArray, IntArray]:
    """(S, 3) mm: a lower bound of each body's clearance at each pose (at most ``reach``), coarse to
    fine (module docstring, stage 1); and the (pose × 3 + body, triangle) pairs whose bound is under
    ``near`` (the triangles a measurement of that body there needs: the others are that far), sorted.
    ``spread``: each pose stands for a group of poses (:func:`_pose_pairs`)."""
    n_pose, n_piece, n_tri = len(tip), len(pieces), len(part.triangles)
    out = np.full((n_pose, 3), reach)
    keys: list[IntArray] = []
    tris: list[IntArray] = []
    if not n_pose or not n_tri:
        return out, np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    centre = 0.5 * (pieces[:, 1] + pieces[:, 2])
    half = np.hypot(pieces[:, 0], 0.5 * (pieces[:, 2] - pieces[:, 1]))
    body = pieces[:, 3].astype(np.int64)
    beyond = max(reach, near)                           # a pair bound beyond this changes nothing
    extra = None if spread is None else (                # a group's own spread, at the bodies' farthest point
        np.linalg.norm(spread.half, axis=1) + (np.abs(pieces[:, 1:3]).max() + pieces[:, 0].max()) * spread.turn)
    g = q = t = np.zeros(0, dtype=np.int64)
    for level, size in enumerate(LEVELS):
        if size == 1:
            for k in range(0, len(g), _CHUNK):
                s_, q_, t_ = g[k:k + _CHUNK], q[k:k + _CHUNK], t[k:k + _CHUNK]
                bound = _pose_pairs(part, tip, axis, cutting, pieces, s_, q_, t_, near, spread)
                np.minimum.at(out, (s_, body[q_]), bound)
                close = bound < near
                keys.append(s_[close] * 3 + body[q_[close]])
                tris.append(t_[close])
            break
        first = np.arange(0, n_pose, size)
        owner = np.arange(n_pose) // size
        moved = np.maximum.reduceat(np.linalg.norm(tip - tip[first][owner], axis=1), first)
        turned = np.maximum.reduceat(np.linalg.norm(axis - axis[first][owner], axis=1), first)
        all_cut = np.logical_and.reduceat(cutting, first)
        if extra is not None:
            moved = moved + np.maximum.reduceat(extra, first)
        level_of = _Level(size=size, moved=moved, turned=turned, all_cut=all_cut)
        if level == 0:                                  # only the triangles whose boxes may be near a group's piece
            g_all = np.repeat(np.arange(len(first)), n_piece)
            q_all = np.tile(np.arange(n_piece), len(first))
            lead = g_all * size                         # each group's first pose
            ball = tip[lead] + centre[q_all, None] * axis[lead]
            radius = half[q_all] + moved[g_all] + np.abs(centre[q_all]) * turned[g_all] + reach
            found = []                                  # measured a piece at a time: memory as the pairs kept
            for query, t_ in part.index.pairs_near(ball, ball, radius, budget=_CHUNK):
                g_, q_ = g_all[query], q_all[query]
                kept = _group_pairs(part, tip, axis, pieces, level_of, reach, beyond, g_, q_, t_)
                found.append((g_[kept], q_[kept], t_[kept]))
            g, q, t = (np.concatenate([np.zeros(0, dtype=np.int64), *(f[j] for f in found)]) for j in range(3))
            keep = np.ones(len(g), dtype=bool)
        else:
            keep = np.zeros(len(g), dtype=bool)
            for k in range(0, len(g), _CHUNK):
                keep[k:k + _CHUNK] = _group_pairs(part, tip, axis, pieces, level_of, reach, beyond,
                                                  g[k:k + _CHUNK], q[k:k + _CHUNK], t[k:k + _CHUNK])
        ratio = size // LEVELS[level + 1]
        g = (g[keep][:, None] * ratio + np.arange(ratio)).ravel()
        q, t = np.repeat(q[keep], ratio), np.repeat(t[keep], ratio)
        fits = g * LEVELS[level + 1] < n_pose
        g, q, t = g[fits], q[fits], t[fits]
    key = np.concatenate([np.zeros(0, dtype=np.int64), *keys])
    tri = np.concatenate([np.zeros(0, dtype=np.int64), *tris])
    pair = np.unique(key * n_tri + tri).astype(np.int64)
    return out, (pair // n_tri).astype(np.int64), (pair % n_tri).astype(np.int64)


@dataclass(frozen=True, slots=True)
class _Level:
    """A level of :func:`_bounds`: ``size`` poses per group, each group's largest tip move (mm) and axis
    chord from its first pose, and whether all its poses cut (each (G,))."""

    size: int
    moved: FloatArray
    turned: FloatArray
    all_cut: BoolArray


def _group_pairs(part: _Part, tip: FloatArray, axis: FloatArray, pieces: FloatArray, level: _Level, reach: float,
                 beyond: float, g: IntArray, q: IntArray, t: IntArray) -> BoolArray:
    """(K,) bool: the (group ``g``, piece ``q``, triangle ``t``) pairs of a level of :func:`_bounds` that
    may be within ``reach``: the triangle is nearer than that to the sphere round the group's first
    pose's piece widened by how far the group moves it (and is not the face, for a group that cuts),
    and the piece's cylinder, so widened, is nearer than ``beyond`` to the triangle's plane
    (:func:`_plane_gap`: where it is not, no pose's bound of the pair is under ``beyond``)."""
    keep = _plane_gap(part, tip, axis, pieces, level, g, q, t) < beyond
    at = g[keep] * level.size
    q_k = q[keep]
    centre = 0.5 * (pieces[q_k, 1] + pieces[q_k, 2])
    ball = tip[at] + centre[:, None] * axis[at]
    widen = np.hypot(pieces[q_k, 0], 0.5 * (pieces[q_k, 2] - pieces[q_k, 1])) + level.moved[g[keep]] \
        + np.abs(centre) * level.turned[g[keep]]
    tri = part.triangles[t[keep]]
    gap = triangle_distance(ball, tri[:, 0], tri[:, 1], tri[:, 2]) - widen
    keep[keep] = (gap < reach) & ~(level.all_cut[g[keep]] & (pieces[q_k, 3] == 0) & ~part.others[t[keep]])
    return keep


#: mm: what the plane bound of a group (:func:`_plane_gap`) is lowered by, far more than the rounding
#: that tells it from the bound of one of its poses.
_PLANE_SLACK_MM = 1e-6


def _plane_gap(part: _Part, tip: FloatArray, axis: FloatArray, pieces: FloatArray, level: _Level, g: IntArray,
               q: IntArray, t: IntArray) -> FloatArray:
    """(K,) mm: a lower bound of the gap between triangle ``t``'s plane and piece ``q`` at every pose of
    group ``g``, less than the plane bound :func:`_pose_pairs` gives any of those poses.

    The piece's cylinder at the group's first pose is min(h₀, h₁) − r·sin∠(axis, normal) from the
    plane (h: its end centres' heights; 0 where it crosses it); at another pose of the group each of
    its points is at most ``moved`` + (max |z| + r)·``turned`` from one of those (the tip's move, the
    axis's turn about the tip), and a cutting tool cut at the band, or spread by a group of the scan
    (:class:`_Spread`, within ``moved``), is no nearer. Less :data:`_PLANE_SLACK_MM`."""
    at = g * level.size
    a, p = axis[at], tip[at]
    radius, z0, z1 = pieces[q, 0], pieces[q, 1], pieces[q, 2]
    normal = part.normal[t]
    along = (a * normal).sum(axis=1)
    base = (p * normal).sum(axis=1) - part.offset[t]
    h0, h1 = base + z0 * along, base + z1 * along
    bulge = radius * np.sqrt(np.clip(1.0 - along ** 2, 0.0, 1.0))
    plane = np.maximum(np.maximum(np.minimum(h0, h1) - bulge, -np.maximum(h0, h1) - bulge), 0.0)
    spread = level.moved[g] + (np.maximum(np.abs(z0), np.abs(z1)) + radius) * level.turned[g]
    gap: FloatArray = plane - spread - _PLANE_SLACK_MM
    return gap


#: One point in this many of a row's is measured first, for the row's cap (:func:`_signed`).
_CAP_STRIDE = 8


def _signed(points: FloatArray, part: _Part, cutting: BoolArray, face: Face | None, reach: float,
            outside: BoolArray, *, per: int = 0) -> FloatArray:
    """(P,) mm: signed distance of points to the part (negative inside; at most ``reach``: farther is
    not measured); where ``cutting`` (the tool in its swept region) a point below ``part.band`` over the face is
    not counted (inf) and the others are measured from the part without that face. ``outside``: points
    known to be outside (not tested).

    ``per`` > 0: only each row's least value and where it is are wanted (rows of ``per`` points): a
    point outside the part whose distance is more than the least of its row's measured first (one in
    :data:`_CAP_STRIDE`) is not measured further, and is given ``reach`` (more than that least, or
    the value it had: neither the least nor the first point that has it changes)."""
    lo, hi = points.min(axis=0) - reach, points.max(axis=0) + reach
    near = ((part.high >= lo) & (part.low <= hi)).all(axis=1)
    inner = np.zeros(len(points), dtype=bool)
    unknown = np.flatnonzero(~outside)
    inner[unknown] = inside(points[unknown], part.triangles)
    off = np.zeros(len(points), dtype=bool)             # measured from the part without the face
    counted = np.ones(len(points), dtype=bool)
    if cutting.any() and face is not None:
        height = (points - face.origin) @ face.normal
        off, counted = cutting, ~(cutting & (height < part.band))
    cap_all = cap_off = None
    if per > 0:                                         # each row's cap: the least of a few of its points, measured
        cap = _row_caps(points, part, near, off, counted & ~inner, reach, per)
        cap_all = np.where(inner, np.inf, np.where(off, 0.0, cap))
        cap_off = np.where(inner, np.inf, np.where(off & counted, cap, 0.0))
    dist = np.minimum(nearest_distance(points, part.triangles, index=part.index, mask=near, cap=cap_all), reach)
    deep = np.flatnonzero(inner & (dist >= reach))
    if len(deep):                                   # inside, and deeper than the near triangles say
        dist[deep] = nearest_distance(points[deep], part.triangles, index=part.index)
    dist = np.where(inner, -dist, dist)
    if cutting.any() and face is not None:
        off_face = np.minimum(nearest_distance(points, part.triangles, index=part.index, mask=near & part.others,
                                               cap=cap_off), reach)
        if len(deep):
            off_face[deep] = nearest_distance(points[deep], part.triangles, index=part.index, mask=part.others)
        dist = np.where(cutting, np.where(~counted, np.inf, np.where(inner, -off_face, off_face)), dist)
    return dist


def _row_caps(points: FloatArray, part: _Part, near: BoolArray, off: BoolArray, mine: BoolArray, reach: float,
              per: int) -> FloatArray:
    """(P,) mm: for each point, the least value (at most ``reach``) of one in :data:`_CAP_STRIDE` of its
    row's points ``mine`` (rows of ``per`` points; ``off``: measured without the face; inf: none)."""
    row = np.arange(len(points)) // per
    sample = np.flatnonzero(mine & (np.arange(len(points)) % per % _CAP_STRIDE == 0))
    value = np.full(len(sample), np.inf)
    for without_face in (False, True):
        at = np.flatnonzero(off[sample] == without_face)
        if len(at):
            mask = near & part.others if without_face else near
            value[at] = np.minimum(nearest_distance(points[sample[at]], part.triangles, index=part.index,
                                                    mask=mask), reach)
    least = np.full(row[-1] + 1 if len(row) else 0, np.inf)
    np.minimum.at(least, row[sample], value)
    out: FloatArray = least[row]
    return out


def _closest_to_axis(a: FloatArray, b: FloatArray) -> FloatArray:
    """(K,) in [0, 1]: where on the segments ``a`` → ``b`` ((K, 3) each, tool frame) the distance from the
    axis (x = y = 0) is least."""
    d = b[:, :2] - a[:, :2]
    length2 = (d * d).sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(length2 > 0.0, np.clip(-(a[:, :2] * d).sum(axis=1) / length2, 0.0, 1.0), 0.0)


def cylinder_penetration(tip: FloatArray, axis: FloatArray, cylinder: FloatArray, triangles: FloatArray) -> float:
    """mm: how deep the triangles reach into a solid cylinder, or 0 where none enters it, whatever their size
    against the surface points' spacing (a thin pin or plate the points straddle, a small solid wholly
    inside the body).

    A point at distance ρ from the axis and z along it is min(radius − ρ, z − start, end − z) inside;
    the value is the largest of that over each triangle's points nearest the axis within the cylinder's
    length (its edges clipped to the length: their ends and the point of each nearest the axis; and where
    the axis pierces it): a lower bound of the deepest point, positive exactly when one of those is inside.

    Parameters
    ----------
    tip, axis : (3,) float — mm, unit: the pose (the cylinder's stations are along ``axis`` from ``tip``)
    cylinder : (3,) float — radius, start, end (mm along the axis)
    triangles : (T, 3, 3) float — mm
    """
    radius, z0, z1 = (float(v) for v in cylinder)
    if len(triangles) == 0 or z1 <= z0 or radius <= 0.0:
        return 0.0
    x, y = _frames(axis[None, :])
    frame = np.stack([x[0], y[0], axis])                          # rows: x, y, z of the tool frame
    local = (triangles - tip) @ frame.T                            # (T, 3, 3): x, y, z per corner
    z = local[..., 2]
    local = local[(z.max(axis=1) >= z0) & (z.min(axis=1) <= z1)]
    if len(local) == 0:
        return 0.0
    points = []
    for i, j in ((0, 1), (1, 2), (2, 0)):                           # the edges, clipped to z0 <= z <= z1
        p, q = local[:, i], local[:, j]
        dz = q[:, 2] - p[:, 2]
        flat = np.abs(dz) < 1e-12
        within = (p[:, 2] >= z0) & (p[:, 2] <= z1)
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = (z0 - p[:, 2]) / dz, (z1 - p[:, 2]) / dz
        lo = np.where(flat, np.where(within, 0.0, 1.0), np.maximum(np.minimum(ta, tb), 0.0))
        hi = np.where(flat, np.where(within, 1.0, 0.0), np.minimum(np.maximum(ta, tb), 1.0))
        ok = lo <= hi
        a, b = p + lo[:, None] * (q - p), p + hi[:, None] * (q - p)
        t = _closest_to_axis(a, b)
        points += [pt[ok] for pt in (a, b, a + t[:, None] * (b - a))]
    e1, e2 = local[:, 1] - local[:, 0], local[:, 2] - local[:, 0]
    det = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]                # twice the triangle's area seen along z
    with np.errstate(divide="ignore", invalid="ignore"):
        u = (-local[:, 0, 0] * e2[:, 1] + local[:, 0, 1] * e2[:, 0]) / det
        v = (-local[:, 0, 1] * e1[:, 0] + local[:, 0, 0] * e1[:, 1]) / det
        pierced = (np.abs(det) > 1e-12) & (u >= 0.0) & (v >= 0.0) & (u + v <= 1.0)
    at = local[pierced, 0] + u[pierced, None] * e1[pierced] + v[pierced, None] * e2[pierced]
    points.append(at * np.array([0.0, 0.0, 1.0]))                   # on the axis
    every = np.concatenate(points)
    if len(every) == 0:
        return 0.0
    depth = np.minimum(radius - np.hypot(every[:, 0], every[:, 1]),
                       np.minimum(every[:, 2] - z0, z1 - every[:, 2]))
    return max(0.0, float(depth.max()))


class _Poses:
    """The poses checked so far (the given ones, then the midpoints of intervals), with each body's
    clearance: a lower bound, or measured on its surface (``exact``)."""

    def __init__(self, part: _Part, face: Face | None, region: _Region, cylinders: FloatArray, clearance_min: float,
                 *, near: float | None = None):
        self.part, self.face, self.region, self.clearance_min = part, face, region, clearance_min
        self.pieces = _pieces(cylinders)
        self.cylinders = cylinders
        self.unchecked = cylinders[:, 2] <= cylinders[:, 1]      # bodies given no length
        self.local, self.body = _surface_points(cylinders)
        self.reach = clearance_min + REACH_MM
        self.tip = np.zeros((0, 3))
        self.axis = np.zeros((0, 3))
        self.cutting = np.zeros(0, dtype=bool)
        self.origin = np.zeros(0, dtype=np.int64)       # the given pose each one reports as
        self.value = np.zeros((0, 3))
        self.exact = np.zeros((0, 3), dtype=bool)
        self.point = np.zeros((0, 3, 3))
        self.found = np.full(3, np.inf)                 # the smallest clearance measured, per body
        self.near = clearance_min + 2.0 if near is None else near   # measured as far as this (farther: "over" it)
        self.pairs: list[tuple[IntArray, IntArray]] = []   # per add(): (pose × 3 + body, triangle), sorted

    def add(self, tip: FloatArray, axis: FloatArray, origin: IntArray, *, starts: BoolArray) -> IntArray:
        """Add poses, bound them and measure those that may be too close; their indices. ``starts``:
        the poses that no checked motion leads to (a body inside the part there is looked for)."""
        cutting = self.region.contains(tip)
        value, key, tri = _bounds(self.part, tip, axis, cutting, self.pieces, reach=self.reach, near=self.near)
        value[:, self.unchecked] = np.inf
        first = np.flatnonzero(starts)
        if len(first):                                  # a body inside the part with nothing near it
            centre = 0.5 * (self.pieces[:, 1] + self.pieces[:, 2])
            points = (tip[first, None] + centre[None, :, None] * axis[first, None]).reshape(-1, 3)
            hit = inside(points, self.part.triangles).reshape(len(first), -1)
            hit &= ~(cutting[first, None] & (self.pieces[None, :, 3] == 0))
            for k in range(len(self.pieces)):
                value[first[hit[:, k]], int(self.pieces[k, 3])] = -np.inf
        at = len(self.tip)
        self.pairs.append((key + 3 * at, tri))
        self.tip, self.axis = np.concatenate([self.tip, tip]), np.concatenate([self.axis, axis])
        self.cutting = np.concatenate([self.cutting, cutting])
        self.origin = np.concatenate([self.origin, origin])
        self.value = np.concatenate([self.value, value])
        self.exact = np.concatenate([self.exact, np.zeros((len(tip), 3), dtype=bool)])
        self.point = np.concatenate([self.point, np.repeat(tip[:, None, :], 3, axis=1)])
        mine = np.arange(at, at + len(tip))
        for b in range(3):                              # closest bound first, until one is too close
            order = mine[np.argsort(value[:, b], kind="stable")]
            after = 0
            for k in range(0, len(order), 64):
                rows = order[k:k + 64]
                lowest = self.value[rows[0], b]
                if lowest >= self.clearance_min or (self.found[b] < self.clearance_min and (
                        lowest >= self.found[b] or after >= AFTER_HIT)):
                    break
                after += self.found[b] < self.clearance_min
                self.measure(rows, b)
        return mine

    def triangles_near(self, row: int, b: int) -> IntArray:
        """The triangles within :attr:`near` of body ``b`` at pose ``row``, as the bounds found them."""
        key = 3 * row + b
        for keys, tris in self.pairs:
            if len(keys) and keys[0] <= key <= keys[-1]:
                return tris[np.searchsorted(keys, key, "left"):np.searchsorted(keys, key, "right")]
        return np.zeros(0, dtype=np.int64)

    def measure_near(self, r: int, b: int, world: FloatArray) -> FloatArray:
        """(P,) mm: :func:`_signed` of body ``b``'s points ``world`` at pose ``r``, against the
        triangles near it only (at most :attr:`near`: the others are farther)."""
        part, near = self.part, self.near
        tris = self.triangles_near(r, b)
        cut = bool(self.cutting[r]) and b == 0
        if cut:
            tris = tris[part.others[tris]]
        box = ((world[:, None, :] >= part.low[tris] - near) & (world[:, None, :] <= part.high[tris] + near)).all(-1)
        point, pair = np.nonzero(box)                   # outside a triangle's box widened by near: that far
        corner = part.triangles[tris[pair]]
        dist = np.full(len(world), near)
        np.minimum.at(dist, point, triangle_distance(world[point], corner[:, 0], corner[:, 1], corner[:, 2]))
        if self.value[r, b] <= 0.0:                     # the bound does not say all outside
            inner = inside(world, part.triangles)
            deep = np.flatnonzero(inner & (dist >= near))
            if len(deep):
                dist[deep] = nearest_distance(world[deep], part.triangles, index=part.index,
                                              mask=part.others if cut else None)
            dist = np.where(inner, -dist, dist)
        if cut and self.face is not None:
            dist = np.where((world - self.face.origin) @ self.face.normal < part.band, np.inf, dist)
        return dist

    def measure(self, rows: IntArray, b: int, block: int = 64, *, reach: float | None = None) -> None:
        """Measure body ``b`` at poses ``rows`` on its surface points, against the triangles near it (as
        far as :attr:`near`: a body farther is at least that far), or with ``reach`` against every
        triangle as far as that."""
        mine = self.local[self.body == b]
        x, y = _frames(self.axis[rows]) if len(rows) else (np.zeros((0, 3)), np.zeros((0, 3)))
        for k in range(0, len(rows), block):
            r = rows[k:k + block]
            xr, yr = x[k:k + block], y[k:k + block]
            world = (self.tip[r, None] + mine[None, :, :1] * xr[:, None] + mine[None, :, 1:2] * yr[:, None]
                     + mine[None, :, 2:] * self.axis[r, None])                    # (s, p, 3)
            if reach is None:
                dist = np.stack([self.measure_near(int(i), b, w) for i, w in zip(r, world, strict=True)])
            else:
                cut = np.repeat(self.cutting[r], len(mine)) if b == 0 else np.zeros(len(r) * len(mine), dtype=bool)
                outside = np.repeat(self.value[r, b] > 0.0, len(mine))          # the bound says: all outside
                dist = _signed(world.reshape(-1, 3), self.part, cut, self.face, reach, outside,
                               per=len(mine)).reshape(len(r), -1)
            best = np.argmin(dist, axis=1)
            measured = dist[np.arange(len(r)), best]
            self._solid(r, b, measured)
            exact = measured < (self.near if reach is None else reach)
            self.value[r, b] = np.where(exact, measured, np.maximum(measured, self.value[r, b]))  # two bounds
            self.point[r, b] = np.where(exact[:, None], world[np.arange(len(r)), best], self.point[r, b])
            self.exact[r, b] = exact
            self.found[b] = min(self.found[b], float(self.value[r, b].min()))


    def _solid(self, rows: IntArray, b: int, measured: FloatArray) -> None:
        """Where the surface points found body ``b`` clear of the part at ``rows`` (``measured`` > 0), make
        ``measured`` the solid body's penetration (negative) if any triangle enters it: a feature thinner
        than the points' spacing, or wholly inside the body, is not missed (:func:`cylinder_penetration`).
        The cutting tool is left to its surface points (what it cuts is not counted)."""
        cylinder = self.cylinders[b]
        if cylinder[2] <= cylinder[1]:
            return
        todo = np.flatnonzero((measured > 0.0) & ~(self.cutting[rows] & (b == 0)))
        if not len(todo):
            return
        # a triangle that enters the cylinder meets its box: the index's (widened by its slack, far more
        # than the rounding of the depths) are all that can give a depth above 0, so the depth is the same
        tip, axis = self.tip[rows[todo]], self.axis[rows[todo]]
        ends = np.stack([tip + cylinder[1] * axis, tip + cylinder[2] * axis])
        found = list(self.part.index.pairs_near(ends.min(axis=0) - cylinder[0], ends.max(axis=0) + cylinder[0], 0.0))
        query = np.concatenate([np.zeros(0, dtype=np.int64), *(f[0] for f in found)])
        tri = np.concatenate([np.zeros(0, dtype=np.int64), *(f[1] for f in found)])
        order = np.lexsort((tri, query))                  # each row's triangles in the part's order
        query, tri = query[order], tri[order]
        bounds = np.searchsorted(query, np.arange(len(todo) + 1))
        for k, i in enumerate(todo.tolist()):
            near = tri[bounds[k]:bounds[k + 1]]
            depth = cylinder_penetration(tip[k], axis[k], cylinder, self.part.triangles[near])
            if depth > 0.0:
                measured[i] = -depth


def clearance(triangles: FloatArray, tip: FloatArray, axis: FloatArray, cylinders: FloatArray, face: Face | None,
              feed_tips: FloatArray, *, clearance_min: float, block: int = 64, refine_max: int = 0,
              connected: BoolArray | None = None, near: float | None = None) -> Clearance:
    """The clearance of the bodies from the part at every pose (part frame), and between connected ones.

    Parameters
    ----------
    triangles : (T, 3, 3) float — mm, the part
    tip, axis : (S, 3) float — mm, unit: the poses (samples of the program's moves)
    cylinders : (3, 3) float — :func:`body_cylinders`
    face : Face | None — the worked face (its plane bounds the tool's exempt part; None: no face, the
        tool is checked like the other bodies, unless it is given no length in ``cylinders``)
    feed_tips : (M, 3) float — mm, the tips of the feed moves in order (the swept region)
    clearance_min : float — mm
    block : int — poses measured at a time
    refine_max : int — poses measured beyond those whose bound is under ``clearance_min``, to sharpen
        the reported minimum (where it stays a bound, ``exact`` says so)
    connected : (S,) bool, optional — pose k is reached from pose k − 1 by a motion to check (the tip
        straight, the axis on its great circle between them); default: the poses alone
    near : float, optional — mm: the bounds are the exact axis-segment distances (less the radius) from
        the triangles nearer than this, and the poses are measured against those (default
        ``clearance_min`` + 2: farther, a body is "over" that)
    """
    tip = np.asarray(tip, dtype=np.float64).reshape(-1, 3)
    axis = np.asarray(axis, dtype=np.float64).reshape(-1, 3)
    triangles = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    part = _Part.of(triangles, face, clearance_min)
    poses = _Poses(part, face, _swept(face, feed_tips, float(cylinders[0, 0]) + 1e-6), cylinders, clearance_min,
                   near=near)
    linked = np.zeros(len(tip), dtype=bool) if connected is None else np.asarray(connected, dtype=bool).copy()
    if len(linked):
        linked[0] = False
    poses.add(tip, axis, np.arange(len(tip)), starts=~linked)
    if (poses.found >= clearance_min).all():            # else refused already: the motion adds nothing
        _between(poses, cylinders, np.flatnonzero(linked))
    _refine(poses, refine_max, block)
    best = np.full(3, np.inf)
    where = np.full(3, -1, dtype=np.int64)
    point = np.zeros((3, 3))
    exact = np.ones(3, dtype=bool)
    for b in range(3):
        value = poses.value[:, b]
        if poses.found[b] < clearance_min:              # too close: what was measured (the rest are bounds)
            value = np.where(poses.exact[:, b], value, np.inf)
        if len(value) and value.min() < np.inf:          # the earliest pose as close as the closest, a measured
            tied = np.flatnonzero(value <= value.min() + _TIE_MM)   # one before a bound
            k = int(tied[np.lexsort((value[tied], poses.origin[tied], ~poses.exact[tied, b]))[0]])
            best[b], where[b], point[b], exact[b] = value[k], poses.origin[k], poses.point[k, b], poses.exact[k, b]
    return Clearance(distance=best, sample=where, point=point, exact=exact)


def _between(poses: _Poses, cylinders: FloatArray, later: IntArray) -> None:
    """Check the motion between each pose ``later`` and the one before it (module docstring, stage 3)."""
    farthest = np.array([max(math.hypot(r, z0), math.hypot(r, z1)) for r, z0, z1 in cylinders])
    start, end = later - 1, later
    floor = poses.clearance_min - SWEEP_SLACK_MM
    while len(start):
        moved = np.linalg.norm(poses.tip[end] - poses.tip[start], axis=1)
        chord = np.linalg.norm(poses.axis[end] - poses.axis[start], axis=1)
        turn = 2.0 * np.arcsin(np.clip(0.5 * chord, 0.0, 1.0))
        delta = moved[:, None] + turn[:, None] * farthest[None, :]                   # (I, 3)
        low = 0.5 * (poses.value[start] + poses.value[end] - delta)
        found = (poses.exact[start] & (poses.value[start] < poses.clearance_min)) | (
            poses.exact[end] & (poses.value[end] < poses.clearance_min))              # already too close there
        bad = ((low < floor) & (delta > 2.0 * SWEEP_SLACK_MM) & ~found).any(axis=1)
        if not bad.any():
            return
        start, end = start[bad], end[bad]
        if (poses.found < poses.clearance_min).any():
            return
        half = poses.axis[start] + poses.axis[end]
        norm = np.linalg.norm(half, axis=1, keepdims=True)
        half = np.where(norm > 1e-9, half / np.maximum(norm, 1e-300), poses.axis[start])
        mid = poses.add(0.5 * (poses.tip[start] + poses.tip[end]), half, poses.origin[end],
                        starts=np.zeros(len(start), dtype=bool))
        start, end = np.concatenate([start, mid]), np.concatenate([mid, end])


def _refine(poses: _Poses, refine_max: int, block: int) -> None:
    """Measure up to ``refine_max`` more poses per body, in order of their bound, while a bound is
    below the smallest clearance measured."""
    for b in range(3):
        spent = 0
        order = np.argsort(np.where(poses.exact[:, b], np.inf, poses.value[:, b]), kind="stable")
        order = order[~poses.exact[order, b]]
        while spent < refine_max and spent < len(order):
            rows = order[spent:spent + block]
            measured = poses.value[poses.exact[:, b], b]
            if len(measured) and poses.value[rows[0], b] >= measured.min() - _TIE_MM:
                break
            poses.measure(rows, b, block, reach=np.inf)
            spent += len(rows)


def check_program(machine: Machine, program: JointProgram, setup: Setup, triangles: FloatArray, face: Face | None,
                  tool_diameter: float, *, clearance_min: float) -> str:
    """Replay ``program`` (verify's FK samples) and check the bodies' clearance from the part.

    ``face`` None: a CAM program's (``convert --part``), whose tool cuts what the CAM program
    removes, where it removes it: the tool is not checked (its gouges are the CAM system's to
    check), the holder and the nose are.

    Returns
    -------
    str — the header's ``collision`` entry: each body's smallest clearance (:func:`measure_program`)

    Raises
    ------
    LimitError
        ``hole 1, peck 1: the holder hits the part, 2.498 mm deep (clearance min 1.000 mm)`` or
        ``...: the tool comes within 0.400 mm of the part (clearance min 1.000 mm)``.
    """
    found = measure_program(machine, program, setup, triangles, face, tool_diameter, clearance_min=clearance_min)
    return found if isinstance(found, str) else found.entry(clearance_min, cam=face is None)


@dataclass(frozen=True, slots=True)
class ProgramClearance:
    """Each body's smallest clearance over a program's motion (:func:`measure_program`).

    Attributes
    ----------
    distance : (3,) float — mm, per body (tool, holder, nose): the smallest clearance measured on the
        body's surface points, to the header's 0.001 mm, where it is under the horizon (``exact``);
        else the horizon, ``clearance_min`` + ``REACH_MM`` (the body is farther than that everywhere)
    exact : (3,) bool — the distance is the minimum (else: over the horizon)
    row : (3,) int — the program row of each exact minimum (its earliest sample; -1: over the horizon)
    point : (3, 3) float — mm, part frame: the body's point there (zeros where ``row`` is -1)
    """

    distance: FloatArray
    exact: BoolArray
    row: IntArray = field(default_factory=lambda: np.full(3, -1, dtype=np.int64))
    point: FloatArray = field(default_factory=lambda: np.zeros((3, 3)))

    def merged(self, other: ProgramClearance) -> ProgramClearance:
        """Each body's smaller clearance of this and ``other`` (rows of the same program; a measured
        one before a bound it ties)."""
        take = (other.distance < self.distance) | ((other.distance == self.distance) & other.exact & ~self.exact)
        return ProgramClearance(distance=np.where(take, other.distance, self.distance),
                                exact=np.where(take, other.exact, self.exact), row=np.where(take, other.row, self.row),
                                point=np.where(take[:, None], other.point, self.point))

    def shifted(self, rows: int) -> ProgramClearance:
        """The same minima in a program where this one's rows start at row ``rows``."""
        return replace(self, row=np.where(self.row >= 0, self.row + rows, -1))

    def approach(self) -> Approach | None:
        """The closest of the bodies measured (None: every body over the horizon, or not checked)."""
        measured = np.flatnonzero(self.exact & (self.row >= 0))
        if not len(measured):
            return None
        b = int(measured[np.argmin(self.distance[measured])])
        return Approach(body=b, distance=float(self.distance[b]), exact=True, row=int(self.row[b]),
                        point=self.point[b].copy())

    def entry(self, clearance_min: float, *, cam: bool = False, rapids: RapidClearance | None = None) -> str:
        """The header's ``collision`` entry: ``clear of the part by at least 1.000 mm: tool 3.250 mm,
        holder over 11.000 mm, spindle nose over 11.000 mm`` (``cam``: the tool is not checked;
        ``rapids``: a CAM program's tool, checked in its rapids only)."""
        from prs3_post.core.numbers import exact_text

        shown = [f"{name} {'' if exact else 'over '}{d:.3f} mm" for name, d, exact in zip(
            BODY_NAMES, self.distance.tolist(), self.exact.tolist(), strict=True)]
        if cam:
            shown[0] = "tool not checked (it cuts what the CAM program removes)"
        if rapids is not None:
            shown[0] = f"{rapids.entry()}, not in feeds (it cuts what the CAM program removes)"
        return f"clear of the part by at least {exact_text(clearance_min, 3)} mm: {', '.join(shown)}"


@dataclass(frozen=True, slots=True)
class Approach:
    """A body's closest approach to the part, where a preview marks it.

    Attributes
    ----------
    body : int — index in :data:`BODY_NAMES`
    distance : float — mm (negative: depth in the part)
    exact : bool — measured (False: a lower bound, stated as ``over``)
    row : int — the program row (move) of that pose
    point : (3,) float — mm, part frame: the body's point there
    """

    body: int
    distance: float
    exact: bool
    row: int
    point: FloatArray

    def label(self, line: int) -> str:
        """``closest: holder 8.637 mm clear, line 27`` (``line``: the program line of :attr:`row`)."""
        return approach_label(self.body, self.distance, self.exact, line)


def approach_label(body: int, distance: float, exact: bool, line: int) -> str:
    """The preview's words on a closest approach: ``closest: holder 8.637 mm clear, line 27``,
    ``closest: tool 2.000 mm deep in the part, line 9``."""
    what = f"{-distance:.3f} mm deep in the part" if distance < 0 else \
        f"{'over ' if not exact else ''}{distance:.3f} mm clear"
    return f"closest: {BODY_NAMES[body]} {what}, line {line}"


def measure_program(machine: Machine, program: JointProgram, setup: Setup, triangles: FloatArray,
                    face: Face | None, tool_diameter: float, *, clearance_min: float,
                    feed_tips: FloatArray | None = None) -> ProgramClearance | str:
    """Each body's smallest clearance along ``program`` (verify's FK samples and the motion between
    them), streamed: the groups of rows the scan bounds beyond the horizon as a whole
    (:mod:`prs3_post.check.collision_scan`) are not replayed, the others are replayed and checked
    ``REPLAY_ROWS`` rows at a time, keeping only each body's smallest clearance (:class:`_Stream`),
    so the memory does not grow with the program. Once a body is found too close, the whole program
    is checked as :func:`clearance` checks it, for the message (its line and depth). ``feed_tips``
    (M, 3) mm, machine frame: the feed tips whose swept region spares the cutting tool (default:
    this program's; a job's moves between operations: the operation's, :func:`feed_tips_of`).

    Returns
    -------
    ProgramClearance, or str — ``not checked: no [holder] in the machine file``

    Raises
    ------
    LimitError
        A body closer than ``clearance_min`` (:func:`check_program`).
    """
    from prs3_post.core.errors import LimitError

    if machine.holder is None:
        return "not checked: no [holder] in the machine file"
    length = machine.geometry.tool_length - machine.geometry.gauge_offset     # gauge line to tip
    if length <= machine.holder.holder_length:
        raise LimitError(f"the tool sticks out {length:.3f} mm below the gauge line, not more than the holder's "
                         f"length {machine.holder.holder_length:.3f} mm: the holder would cut (a longer tool, or "
                         "a shorter holder in the machine file)")
    bodies = body_cylinders(tool_diameter, length, machine.holder)
    if face is None:
        bodies[0, 2] = bodies[0, 1]                             # the tool: not checked
    triangles = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    streamed = _streamed(machine, program, setup, triangles, face, bodies, clearance_min, feed_tips)
    if streamed is not None:
        return streamed
    sample_row, tip, axis, own_tips = _replayed(machine, program)
    feed_tips = own_tips if feed_tips is None else feed_tips
    tip, axis = setup.points_to_part(tip), setup.axes_to_part(axis)
    ok = np.asarray(np.isfinite(tip).all(axis=1) & np.isfinite(axis).all(axis=1), dtype=bool)
    linked = ok & np.concatenate([[False], ok[:-1]])          # the motion from the sample before, both known
    result = clearance(triangles, tip[ok], axis[ok], bodies, face, setup.points_to_part(feed_tips),
                       clearance_min=clearance_min, connected=linked[ok])
    b = result.worst()
    if result.distance[b] < clearance_min:
        row = int(sample_row[np.flatnonzero(ok)[result.sample[b]]])
        d = float(result.distance[b])
        what = (f"hits the part, {-d:.3f} mm deep" if d < 0 else f"comes within {d:.3f} mm of the part")
        raise LimitError(f"{program.describe(row)}: the {BODY_NAMES[b]} {what} (clearance min "
                         f"{_exact(clearance_min)} mm)")
    return ProgramClearance(distance=np.where(result.exact, result.distance, clearance_min + REACH_MM),
                            exact=result.exact.copy())   # not reached: the stream found a body too close


def feed_tips_of(machine: Machine, program: JointProgram) -> FloatArray:
    """(M, 3) mm, machine frame: the end tips of ``program``'s FEED rows, as :func:`measure_program`
    draws its swept region from them."""
    from prs3_post.check.collision_scan import scan_program

    return scan_program(machine, program, np.eye(3)).feed_tips


def _exact(value: float) -> str:
    from prs3_post.core.numbers import exact_text

    return exact_text(value, 3)


#: mm: the header's resolution; the streamed minima are found to it (:meth:`_Stream.minima`).
RESOLUTION_MM = 1e-3


def _streamed(machine: Machine, program: JointProgram, setup: Setup, triangles: FloatArray, face: Face | None,
              bodies: FloatArray, clearance_min: float, feed_tips: FloatArray | None = None
              ) -> ProgramClearance | None:
    """:func:`measure_program`'s streamed check; None once a body is found closer than ``clearance_min``."""
    from prs3_post.check.collision_scan import scan_program

    frame = np.eye(3) if face is None else np.stack([face.u, face.v, face.normal])   # part frame, rows
    scan = scan_program(machine, program, setup.axes_to_part(np.eye(3)) @ frame.T)
    part = _Part.of(triangles, face, clearance_min)
    region = _swept(face, scan.feed_tips if feed_tips is None else feed_tips, float(bodies[0, 0]) + 1e-6,
                    setup=setup)
    stream = _Stream(part, face, region, bodies, clearance_min)
    bound = np.full((len(scan.flat), 3), -np.inf)        # each group's bound per body (−inf: none)
    groups = np.flatnonzero(scan.flat)
    tip, axis = setup.points_to_part(scan.tip[groups]), setup.axes_to_part(scan.axis[groups])
    # a group of feed moves (and the row before) follows the feed tips' polyline, which the region
    # is drawn round with the tool's radius and a cell more: every pose of it is over the region
    cutting = scan.feeding[groups] & (region.cells.size > 0) & (scan.wobble[groups] < 0.2 * region.cell)
    spread = _Spread(frame=frame, half=scan.half[groups], turn=scan.turn[groups])
    del scan                                             # its feed tips (a row each) before the bounds
    if len(groups):                                      # each flat group bounded as a whole
        bound[groups] = _bounds(part, tip, axis, cutting, stream.pieces, reach=stream.reach, near=stream.reach,
                                spread=spread)[0]
    bound[:, stream.unchecked] = np.inf
    # safe: no pose, no motion of the group comes too close
    safe: BoolArray = np.asarray((bound >= clearance_min).all(axis=1), dtype=np.bool_)
    n = len(program)
    for lo, hi in _runs(~safe, n):                       # the others in order: poses, then the motion between
        for at in range(lo, hi, REPLAY_ROWS):
            row, tip, axis = _replay_rows(machine, program, at, min(hi, at + REPLAY_ROWS))
            if not stream.add(row, setup.points_to_part(tip), setup.axes_to_part(axis), carried=at > 0):
                return None
    for b in np.flatnonzero(~stream.unchecked).tolist():  # the safe groups' share of the minima, closest first
        order = np.flatnonzero(safe & (bound[:, b] < stream.reach))
        order = order[np.argsort(bound[order, b], kind="stable")]
        k = 0
        while k < len(order) and bound[order[k], b] < min(stream.reach, stream.best[b] - 0.5 * RESOLUTION_MM):
            chosen: BoolArray = np.zeros(len(safe), dtype=np.bool_)
            chosen[order[k:k + _GROUPS_AT_ONCE]] = True
            for lo, hi in _runs(chosen, n):
                row, tip, axis = _replay_rows(machine, program, lo, hi)
                stream.measure(row, setup.points_to_part(tip), setup.axes_to_part(axis))
            k += _GROUPS_AT_ONCE
    return stream.result()


#: Groups the minima of the safe ones replay at a time (closest bound first).
_GROUPS_AT_ONCE = 8


def _runs(groups: BoolArray, n: int) -> list[tuple[int, int]]:
    """The row ranges [lo, hi) of the runs of consecutive True groups (GROUP_ROWS rows each, ``n`` rows)."""
    from prs3_post.check.collision_scan import GROUP_ROWS

    keep = np.repeat(groups, GROUP_ROWS)[:n]
    edges = np.flatnonzero(np.diff(np.concatenate([[False], keep, [False]]).astype(np.int8)))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))


def _to_part(setup: Setup, points: FloatArray) -> FloatArray:
    """:meth:`Setup.points_to_part` column by column (a matrix product of a long (N, 3) array takes
    numpy's slow path)."""
    d = [points[:, k] - setup.shift[k] for k in range(3)]
    rotation = setup.rotation
    return np.column_stack([d[0] * rotation[0, j] + d[1] * rotation[1, j] + d[2] * rotation[2, j] for j in range(3)])


def _replay_rows(machine: Machine, program: JointProgram, lo: int, hi: int) -> tuple[IntArray, FloatArray, FloatArray]:
    """verify's samples of rows ``lo`` .. ``hi`` replayed from the row before (its end is where row
    ``lo``'s move starts, and the first sample): each sample's row, tip and axis (machine frame)."""
    from prs3_post.core.toolpath import program_from_columns
    from prs3_post.kinematics.replay import replay

    start = max(lo - 1, 0)
    columns = {name: getattr(program, name)[start:hi] for name in ("kind", "stage", "strokes", "inverse_time",
                                                                  "source")}
    rep = replay(machine, program_from_columns(columns))
    return rep.row + start, rep.tip, rep.axis


class _Stream:
    """The check of a program's samples, a piece at a time (:func:`_streamed`): what carries from one
    piece to the next is each body's smallest clearance so far (``best``, to RESOLUTION_MM; the
    smallest measured, ``found``).

    Each piece starts with the end of the row before it (the previous piece's last sample, or the
    last row of a group bounded as a whole): the motion from there is checked (stage 3), and it is
    never a pose where a body is looked for inside the part (the motion to it was checked). In each
    piece the poses are bounded and those under ``clearance_min`` measured as :func:`clearance` does;
    then, per body, the poses under the horizon in order of their bound while the bound is under the
    smallest clearance found (less half the resolution: a pose left out cannot round lower), so the
    minimum does not depend on the pieces' sizes.
    """

    def __init__(self, part: _Part, face: Face | None, region: _Region, cylinders: FloatArray,
                 clearance_min: float):
        self.part, self.face, self.region, self.cylinders = part, face, region, cylinders
        self.clearance_min = clearance_min
        self.reach = clearance_min + REACH_MM
        self.pieces = _pieces(cylinders)
        self.unchecked = cylinders[:, 2] <= cylinders[:, 1]
        self.found = np.full(3, np.inf)
        self.best = np.full(3, np.inf)
        self.row = np.full(3, -1, dtype=np.int64)         # the row and body point of each ``best``
        self.point = np.zeros((3, 3))

    def add(self, row: IntArray, tip: FloatArray, axis: FloatArray, *, carried: bool) -> bool:
        """Check a piece's samples (part frame; the first one the end of the row before if ``carried``);
        False: a body is closer than ``clearance_min``."""
        ok: BoolArray = np.asarray(np.isfinite(tip).all(axis=1) & np.isfinite(axis).all(axis=1), dtype=np.bool_)
        linked: BoolArray = ok & np.concatenate([[False], ok[:-1]])
        starts = ~linked
        if carried and len(starts):
            starts[0] = False
        poses = _Poses(self.part, self.face, self.region, self.cylinders, self.clearance_min)
        poses.found = self.found.copy()
        samples = poses.add(tip[ok], axis[ok], row[ok], starts=starts[ok])
        if (poses.found >= self.clearance_min).all():
            _between(poses, self.cylinders, np.flatnonzero(linked[ok]))
        self.found = poses.found
        if (poses.found < self.clearance_min).any():
            return False
        self.minima(poses, samples)
        return True

    def measure(self, row: IntArray, tip: FloatArray, axis: FloatArray) -> None:
        """Lower ``best`` by the samples of groups whose every pose is ``clearance_min`` clear (their
        bounds say so: nothing is measured under it, the motion is not checked further)."""
        ok = np.isfinite(tip).all(axis=1) & np.isfinite(axis).all(axis=1)
        poses = _Poses(self.part, self.face, self.region, self.cylinders, self.clearance_min)
        self.minima(poses, poses.add(tip[ok], axis[ok], row[ok], starts=np.zeros(int(ok.sum()), dtype=bool)))

    def minima(self, poses: _Poses, samples: IntArray, block: int = 64) -> None:
        """Lower ``best`` by the ``samples`` of ``poses`` (not the midpoints the motion check added):
        measure, body by body, in order of the bound (module docstring of :class:`_Stream`)."""
        half = 0.5 * RESOLUTION_MM
        for b in range(3):
            if self.unchecked[b]:
                continue
            value, exact = poses.value[:, b], poses.exact[:, b]
            self._lower(b, poses, samples[exact[samples] & (value[samples] < self.reach)])
            order = samples[~exact[samples] & (value[samples] < self.reach)]
            order = order[np.argsort(value[order], kind="stable")]
            for k in range(0, len(order), block):
                rows = order[k:k + block]
                if value[rows[0]] >= min(self.reach, self.best[b] - half):
                    break
                poses.measure(rows, b, block, reach=self.reach)
                self._lower(b, poses, rows[poses.exact[rows, b]])

    def _lower(self, b: int, poses: _Poses, measured: IntArray) -> None:
        """Lower ``best`` of body ``b`` by the poses ``measured`` (their values exact), keeping the row and
        the body's point of the minimum: the earliest row of those that round to it."""
        if not len(measured):
            return
        rounded = np.round(poses.value[measured, b] / RESOLUTION_MM) * RESOLUTION_MM
        low = float(rounded.min())
        at = measured[rounded == low]
        k = int(at[np.argmin(poses.origin[at])])
        row = int(poses.origin[k])
        if low < self.best[b] or (low == self.best[b] and (self.row[b] < 0 or row < self.row[b])):
            self.best[b], self.row[b], self.point[b] = low, row, poses.point[k, b]

    def result(self) -> ProgramClearance:
        exact = np.isfinite(self.best) & ~self.unchecked
        return ProgramClearance(distance=np.where(exact, self.best, self.reach), exact=exact,
                                row=np.where(exact, self.row, -1), point=np.where(exact[:, None], self.point, 0.0))


#: Program rows replayed at a time by :func:`check_program` (the replay's limit tables are what
#: costs memory; the check keeps only the samples' tips and axes).
REPLAY_ROWS = 65536


def _replayed(machine: Machine, program: JointProgram) -> tuple[IntArray, FloatArray, FloatArray, FloatArray]:
    """verify's FK samples of ``program`` (machine frame), REPLAY_ROWS program rows at a time, each piece
    from the previous one's last row (its end is where the piece's first move starts: the samples are
    those of one replay): the row, tip and axis of each sample, and the end tips of the FEED rows."""
    from prs3_post.core.toolpath import MoveKind, program_from_columns
    from prs3_post.kinematics.replay import replay

    out_row, out_tip, out_axis, out_feed = [], [], [], []
    n, rows = len(program), REPLAY_ROWS
    for lo in range(0, max(n, 1), rows):
        start, hi = max(lo - 1, 0), min(n, lo + rows)
        columns = {name: getattr(program, name)[start:hi] for name in ("kind", "stage", "strokes", "inverse_time",
                                                                      "source")}
        rep = replay(machine, program_from_columns(columns))
        mine = rep.row >= lo - start                     # not the previous piece's last row again
        out_row.append(rep.row[mine] + start)
        out_tip.append(rep.tip[mine])
        out_axis.append(rep.axis[mine])
        feed = np.flatnonzero(program.kind[lo:hi] == MoveKind.FEED) + (lo - start)
        out_feed.append(rep.tip[rep.end[feed]])
    return (np.concatenate(out_row), np.concatenate(out_tip), np.concatenate(out_axis),
            np.concatenate(out_feed).reshape(-1, 3))


#: mm: how far a rapid's tool may reach into the part's triangles unrefused. A CAM program's rapid
#: may start or end where a cut left the tool touching the finished part (retracting past the wall
#: it cut, or with its tip on the floor), and an STL's facets lie off the true surface by their
#: chord; what a rapid must not do is cut. The tool is checked eroded by twice this (its radius and
#: its tip end), held this far from the part: touching passes with a margin, a penetration of more
#: than this is refused.
RAPID_TOUCH_MM = 0.05
#: mm: a rapid that moves the tip along the tool axis, away from the part, sideways by at most this
#: (the tip's offset plus the axis's turn times the tool's length) retracts the tool through where
#: it and the holder already were: its tool is not checked (the holder is, at every pose).
RETRACT_SIDEWAYS_MM = 0.5 * RAPID_TOUCH_MM


@dataclass(frozen=True, slots=True)
class RapidClearance:
    """The tool's closest approach to the part in a CAM program's rapids (:func:`rapid_tool_clearance`).

    Attributes
    ----------
    diameter : float — mm, the tool's diameter checked (0: unknown, its axis segment)
    distance : float — mm, the tool's smallest clearance in the rapids (negative: depth in the part);
        inf: no rapid checked
    exact : bool — measured on the tool's surface (False: a lower bound, stated as ``over``)
    row : int — the program row (the rapid) of that minimum (-1: none)
    fraction : float — the fraction along that row's move (0: its start)
    point : (3,) float — mm, part frame: the tool's point of that minimum
    rapids : int — rapid rows checked (retracts along the tool axis are not: RETRACT_SIDEWAYS_MM)
    """

    diameter: float
    distance: float
    exact: bool
    row: int
    fraction: float
    point: FloatArray
    rapids: int

    def entry(self) -> str:
        """The header's words on the tool in the rapids: ``tool in rapids 2.345 mm (6.000 mm diameter)``
        (``none to check``: no rapid but retracts along the tool axis)."""
        if self.rapids == 0:
            shown = "none to check"
        else:
            text = f"{self.distance:.3f}"
            text = text[1:] if text.startswith("-") and float(text) == 0 else text     # never -0.000
            shown = f"{'' if self.exact else 'over '}{text} mm"
        return f"tool in rapids {shown} ({tool_words(self.diameter)})"

    def message(self, program: JointProgram) -> str:
        """The refusal: ``part.cls:12: the tool hits the part in a rapid, 4.950 mm deep (...)``."""
        d = self.distance
        what = f"hits the part in a rapid, {-d:.3f} mm deep" if d < 0 else f"comes within {d:.3f} mm of the part"
        return (f"{program.describe(self.row)}: the tool {what} (a rapid may touch the part, not cut it: "
                f"{RAPID_TOUCH_MM:.3f} mm at most; {tool_words(self.diameter)})")


def rapid_diameter_from_entry(text: str) -> float:
    """mm: the tool diameter a converted program's ``collision`` entry says its rapids were checked
    with (:meth:`RapidClearance.entry`, its parentheses perhaps brackets); 0 where it says none (the
    diameter unknown, or a program converted without a part: the tool is then its axis).

    >>> rapid_diameter_from_entry("clear of the part by at least 1.000 mm: tool in rapids 2.000 mm [6.000 mm diameter]")
    6.0
    >>> rapid_diameter_from_entry("not checked (no part given)")
    0.0
    """
    found = re.search(r"tool in rapids [^(\[]*[(\[]([0-9]+\.[0-9]+) mm diameter", text)
    return float(found.group(1)) if found else 0.0


def tool_words(diameter: float) -> str:
    """What the rapid check took the tool to be: ``6.000 mm diameter``, or its axis where none is known."""
    return (f"{diameter:.3f} mm diameter" if diameter > 0
            else "diameter unknown: its axis, 0 mm radius")


def rapid_tool_clearance(machine: Machine, program: JointProgram, setup: Setup, triangles: FloatArray,
                         tool_diameter: float) -> RapidClearance:
    """The tool's clearance from the part in the rapids of a CAM program (``convert --part``; verify
    of a converted program), at verify's samples of each rapid and along the motion between them.

    A feed cuts what the CAM program removes; a rapid must not. Each run of rapids is checked from
    where the row before it left the tool (that pose is the motion's start: the tool may touch the
    part there, as a cut leaves it); a rapid that only retracts the tool along its axis
    (:data:`RETRACT_SIDEWAYS_MM`) is not checked, so a run starts after it. The tool is the
    cylinder of ``tool_diameter`` (0: unknown, its axis segment) from the tip to the holder,
    eroded by 2 × :data:`RAPID_TOUCH_MM` and held that far from the part (:data:`RAPID_TOUCH_MM`):
    the clearance stated is the eroded tool's less the erosion (exact where the part faces the
    tool's side or end).

    Raises
    ------
    ValueError
        The machine has no ``[holder]`` (the tool ends where it begins).
    """
    from prs3_post.core.toolpath import MoveKind, program_from_columns
    from prs3_post.kinematics.replay import replay

    if machine.holder is None:
        raise ValueError(f"machine {machine.name} has no [holder]")
    erosion = 2.0 * RAPID_TOUCH_MM
    length = machine.geometry.tool_length - machine.geometry.gauge_offset
    cylinders = body_cylinders(tool_diameter, length, machine.holder)
    cylinders[0] = [max(cylinders[0, 0] - erosion, 0.0), erosion, cylinders[0, 2]]
    cylinders[1:, 2] = cylinders[1:, 1]                         # the holder and nose: check_program's
    none = RapidClearance(diameter=tool_diameter, distance=math.inf, exact=True, row=-1, fraction=0.0,
                          point=np.zeros(3), rapids=0)
    rapid = np.flatnonzero(program.kind == MoveKind.RAPID)
    rapid = rapid[rapid > 0]                                    # row 0: a start, not a move
    if not len(rapid) or cylinders[0, 2] <= cylinders[0, 1]:
        return none
    keep = np.zeros(len(program), dtype=bool)
    keep[rapid] = keep[rapid - 1] = True
    rows = np.flatnonzero(keep)                                 # the rapids and the rows they start from
    is_rapid = np.zeros(len(rows), dtype=bool)
    is_rapid[np.searchsorted(rows, rapid)] = True
    columns = {name: getattr(program, name)[rows] for name in ("kind", "stage", "strokes", "inverse_time", "source")}
    rep = replay(machine, program_from_columns(columns))
    tip, axis = setup.points_to_part(rep.tip), setup.axes_to_part(rep.axis)
    # a retract: the axis kept, the tip moved along it (up, away from the part), barely sideways
    end_tip, end_axis = tip[rep.end], axis[rep.end]
    step = np.diff(end_tip, axis=0)
    along = (step * end_axis[:-1]).sum(axis=1)
    sideways = np.linalg.norm(step - along[:, None] * end_axis[:-1], axis=1) + \
        np.linalg.norm(np.diff(end_axis, axis=0), axis=1) * cylinders[0, 2]
    retract = np.concatenate([[False], (along > 0) & (sideways <= RETRACT_SIDEWAYS_MM)])
    checked = is_rapid & ~retract                               # sub-row 0 is never a rapid (its row before is kept)
    if not checked.any():
        return none
    # the samples of the checked rapids, each run's start: the end sample of the row before it
    sampled = checked[rep.row]
    starts = np.zeros(len(rep.row), dtype=bool)
    starts[rep.end[np.flatnonzero(checked[1:] & ~checked[:-1])]] = True   # the end of the row before a run
    mine = np.flatnonzero(sampled | starts)
    ok = np.isfinite(tip[mine]).all(axis=1) & np.isfinite(axis[mine]).all(axis=1)
    mine = mine[ok]
    connected = np.concatenate([[False], sampled[mine[1:]] & (np.diff(mine) == 1)])
    found = clearance(triangles, tip[mine], axis[mine], cylinders, None, np.zeros((0, 3)),
                      clearance_min=RAPID_TOUCH_MM, refine_max=_RAPID_REFINE, connected=connected,
                      near=RAPID_TOUCH_MM + REACH_MM)
    if not np.isfinite(found.distance[0]):
        return replace(none, rapids=int(checked.sum()))
    k = int(mine[found.sample[0]])
    sub_row = int(rep.row[k])
    fraction = float(rep.fraction[k])
    if not checked[sub_row]:                                    # a run's start: named as the rapid it starts
        sub_row, fraction = sub_row + 1, 0.0
    return RapidClearance(diameter=tool_diameter, distance=float(found.distance[0]) - erosion,
                          exact=bool(found.exact[0]), row=int(rows[sub_row]), fraction=fraction,
                          point=found.point[0].copy(), rapids=int(checked.sum()))


#: Poses of the rapids measured beyond those the check needs, nearest first, to sharpen the minimum.
_RAPID_REFINE = 32


def check_rapids(machine: Machine, program: JointProgram, setup: Setup, triangles: FloatArray,
                 tool_diameter: float) -> RapidClearance:
    """:func:`rapid_tool_clearance`, refused when the tool cuts in a rapid.

    Raises
    ------
    LimitError
        ``part.cls:12: the tool hits the part in a rapid, 4.950 mm deep (a rapid may touch the part,
        not cut it: 0.050 mm at most; 6.000 mm diameter)``.
    """
    from prs3_post.core.errors import LimitError

    found = rapid_tool_clearance(machine, program, setup, triangles, tool_diameter)
    if found.distance < -RAPID_TOUCH_MM:
        raise LimitError(found.message(program))
    return found
