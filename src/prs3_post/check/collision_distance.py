"""The clearance of the bodies from the part at many poses, and along the motion between them: the
staged bounds and the exact measurements (the module docstring of :mod:`prs3_post.check.collision`
describes the three stages).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from prs3_post.check.collision_bodies import Region, frames, surface_points, swept_region
from prs3_post.core.types import BoolArray, FloatArray, IntArray
from prs3_post.part.face import Face
from prs3_post.part.meshdist import (
    PAIR_BUDGET,
    inside,
    nearest_distance,
    segment_triangle_distance,
    triangle_distance,
)
from prs3_post.part.meshindex import TriangleIndex

__all__ = ["AFTER_HIT", "LEVELS", "MEASURE_BLOCK", "PIECE_MM", "REACH_MM", "SWEEP_SLACK_MM", "Clearance",
           "ClearancePoses", "Part", "Spread", "body_pieces", "check_between", "clearance", "cylinder_penetration",
           "pose_bounds"]

#: mm, the longest piece a body is cut into for the bounds (or its radius, if longer).
PIECE_MM = 10.0
#: Poses per group at each level of the bounds.
LEVELS = (4096, 256, 16, 1)
#: mm beyond ``clearance_min``: a body farther than this from the part is reported as "over" it.
REACH_MM = 10.0
#: mm: the motion between two poses may come this much closer than ``clearance_min`` unseen (the
#: halving stops there).
SWEEP_SLACK_MM = 0.05
#: Poses measured on their surface points at a time (memory: points × poses × triangles per pass).
MEASURE_BLOCK = 64
#: Blocks of :data:`MEASURE_BLOCK` poses measured, closest bound first, once a body is found too close (the depth
#: reported is the deepest of those: the lowest bounds are where it is).
AFTER_HIT = 4
#: mm: minima this close are the same (the report's rounding); the earliest pose is named.
_TIE_MM = 5e-4
#: mm: how much closer than at the segment's ends (or as close at its middle) a triangle must be for its
#: nearest point of the segment to be an inner one (:meth:`ClearancePoses._side`).
_INNER_MM = 1e-9
#: Pairs measured at a time (memory).
_CHUNK = PAIR_BUDGET


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
class Part:
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
    def of(cls, triangles: FloatArray, face: Face | None, band: float) -> Part:
        normal = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
        others = np.ones(len(triangles), dtype=bool)
        if face is not None:
            others[np.asarray(face.triangles, dtype=np.int64)] = False
        index = TriangleIndex(triangles)
        return cls(triangles=triangles, normal=normal, offset=(normal * triangles[:, 0]).sum(axis=1),
                   low=index.low, high=index.high, others=others, face=face, band=band, index=index)


def body_pieces(cylinders: FloatArray) -> FloatArray:
    """(Q, 4): radius, start, end (mm along the axis from the tip) and body of each piece."""
    out = []
    for b, (radius, z0, z1) in enumerate(cylinders):
        if z1 <= z0:                                    # a body not checked
            continue
        n = max(1, math.ceil((z1 - z0) / max(radius, PIECE_MM)))
        edges = np.linspace(z0, z1, n + 1)
        out += [(radius, edges[k], edges[k + 1], b) for k in range(n)]
    return np.array(out, dtype=np.float64)


def _pose_pairs(part: Part, tip: FloatArray, axis: FloatArray, cutting: BoolArray, pieces: FloatArray,
                s: IntArray, q: IntArray, t: IntArray, near: float, spread: Spread | None = None) -> FloatArray:
    """(K,) mm: a lower bound of the distance of piece ``q`` at pose ``s`` from triangle ``t``, pair by
    pair (inf: a pair that does not count: the cutting tool's part below the band, or the face).

    ``spread``: each pose stands for a group of poses (:class:`Spread`): every body point of the
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
        assert face is not None                     # a tool cuts only with a face (swept_region)
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
class Spread:
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


def pose_bounds(part: Part, tip: FloatArray, axis: FloatArray, cutting: BoolArray, pieces: FloatArray, *,
                reach: float, near: float, spread: Spread | None = None) -> tuple[FloatArray, IntArray, IntArray]:
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
    """A level of :func:`pose_bounds`: ``size`` poses per group, each group's largest tip move (mm) and axis
    chord from its first pose, and whether all its poses cut (each (G,))."""

    size: int
    moved: FloatArray
    turned: FloatArray
    all_cut: BoolArray


def _group_pairs(part: Part, tip: FloatArray, axis: FloatArray, pieces: FloatArray, level: _Level, reach: float,
                 beyond: float, g: IntArray, q: IntArray, t: IntArray) -> BoolArray:
    """(K,) bool: the (group ``g``, piece ``q``, triangle ``t``) pairs of a level of :func:`pose_bounds` that
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


def _plane_gap(part: Part, tip: FloatArray, axis: FloatArray, pieces: FloatArray, level: _Level, g: IntArray,
               q: IntArray, t: IntArray) -> FloatArray:
    """(K,) mm: a lower bound of the gap between triangle ``t``'s plane and piece ``q`` at every pose of
    group ``g``, less than the plane bound :func:`_pose_pairs` gives any of those poses.

    The piece's cylinder at the group's first pose is min(h₀, h₁) − r·sin∠(axis, normal) from the
    plane (h: its end centres' heights; 0 where it crosses it); at another pose of the group each of
    its points is at most ``moved`` + (max |z| + r)·``turned`` from one of those (the tip's move, the
    axis's turn about the tip), and a cutting tool cut at the band, or spread by a group of the scan
    (:class:`Spread`, within ``moved``), is no nearer. Less :data:`_PLANE_SLACK_MM`."""
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


def _signed(points: FloatArray, part: Part, cutting: BoolArray, face: Face | None, reach: float,
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


def _row_caps(points: FloatArray, part: Part, near: BoolArray, off: BoolArray, mine: BoolArray, reach: float,
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
    x, y = frames(axis[None, :])
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


class ClearancePoses:
    """The poses checked so far (the given ones, then the midpoints of intervals), with each body's
    clearance: a lower bound, or measured on its surface (``exact``)."""

    def __init__(self, part: Part, face: Face | None, region: Region, cylinders: FloatArray, clearance_min: float,
                 *, near: float | None = None):
        self.part, self.face, self.region, self.clearance_min = part, face, region, clearance_min
        self.pieces = body_pieces(cylinders)
        self.cylinders = cylinders
        self.unchecked = cylinders[:, 2] <= cylinders[:, 1]      # bodies given no length
        self.local, self.body = surface_points(cylinders)
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
        value, key, tri = pose_bounds(self.part, tip, axis, cutting, self.pieces, reach=self.reach, near=self.near)
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

    def measure(self, rows: IntArray, b: int, block: int = MEASURE_BLOCK, *, reach: float | None = None) -> None:
        """Measure body ``b`` at poses ``rows`` on its surface points, against the triangles near it (as
        far as :attr:`near`: a body farther is at least that far), or with ``reach`` against every
        triangle as far as that."""
        mine = self.local[self.body == b]
        x, y = frames(self.axis[rows]) if len(rows) else (np.zeros((0, 3)), np.zeros((0, 3)))
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
            measured = self._side(r, b, dist[np.arange(len(r)), best], reach)
            self._solid(r, b, measured)
            exact = measured < (self.near if reach is None else reach)
            self.value[r, b] = np.where(exact, measured, np.maximum(measured, self.value[r, b]))  # two bounds
            self.point[r, b] = np.where(exact[:, None], world[np.arange(len(r)), best], self.point[r, b])
            self.exact[r, b] = exact
            self.found[b] = min(self.found[b], float(self.value[r, b].min()))


    def _side(self, rows: IntArray, b: int, measured: FloatArray, reach: float | None = None) -> FloatArray:
        """``measured`` (the surface points' minimum at ``rows``) lowered to the exact clearance of body
        ``b``'s side where a triangle near it is nearest to an inner point of its axis segment: there the
        body's nearest point is on its side, across from it, and the clearance is that distance less the
        radius. The surface points alone overstate it by up to r (1 − cos(π / AZIMUTHS)) (0.128 mm for a
        15 mm holder) by where their azimuths fall, so the header's minimum (the main job's poses) and
        verify's (its own) would differ by that much; this is the same value at any pose and azimuth.
        A pose nearest to an end of the axis (its rim) keeps the points' value; so does the cutting tool.
        With ``reach`` (the poses were measured against every triangle as far as that), the triangles
        looked at are those whose boxes are within the measured clearance of the side, not only the
        ones within :attr:`near`: a side 8 mm clear is as exact as one 1 mm clear."""
        radius, z0, z1 = (float(v) for v in self.cylinders[b])
        todo = np.flatnonzero((measured > 0.0) & ~(self.cutting[rows] & (b == 0)))
        if z1 <= z0 or not len(todo):
            return measured
        if reach is None:
            near = [self.triangles_near(int(rows[k]), b) for k in todo.tolist()]
        else:
            ends = np.stack([self.tip[rows[todo]] + z * self.axis[rows[todo]] for z in (z0, z1)])
            near = [np.zeros(0, dtype=np.int64) for _ in todo]
            look = np.minimum(measured[todo], reach) + radius
            for query, tri_ in self.part.index.pairs_near(ends.min(axis=0), ends.max(axis=0), look):
                for k in np.unique(query).tolist():
                    near[k] = np.concatenate([near[k], tri_[query == k]])
        count = np.array([len(t) for t in near])
        if not count.sum():
            return measured
        pose = np.repeat(todo, count)
        tri = self.part.triangles[np.concatenate(near)]
        tip, axis = self.tip[rows[pose]], self.axis[rows[pose]]
        p0, p1 = tip + z0 * axis, tip + z1 * axis
        a, b_, c = tri[:, 0], tri[:, 1], tri[:, 2]
        gap = segment_triangle_distance(p0, p1, tri)
        ends = np.minimum(triangle_distance(p0, a, b_, c), triangle_distance(p1, a, b_, c))
        middle = triangle_distance(0.5 * (p0 + p1), a, b_, c)
        # the distance along the segment is convex: below both ends, or as low at the middle, is inside it
        inner = (gap < ends - _INNER_MM) | (middle <= gap + _INNER_MM)
        side = np.where(inner & (gap > radius), gap - radius, np.inf)
        lowest = np.full(len(measured), np.inf)
        np.minimum.at(lowest, pose, side)
        return np.minimum(measured, lowest)

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
              feed_tips: FloatArray, *, clearance_min: float, block: int = MEASURE_BLOCK, refine_max: int = 0,
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
    part = Part.of(triangles, face, clearance_min)
    poses = ClearancePoses(part, face, swept_region(face, feed_tips, float(cylinders[0, 0]) + 1e-6), cylinders,
                           clearance_min, near=near)
    linked = np.zeros(len(tip), dtype=bool) if connected is None else np.asarray(connected, dtype=bool).copy()
    if len(linked):
        linked[0] = False
    poses.add(tip, axis, np.arange(len(tip)), starts=~linked)
    if (poses.found >= clearance_min).all():            # else refused already: the motion adds nothing
        check_between(poses, cylinders, np.flatnonzero(linked))
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


def check_between(poses: ClearancePoses, cylinders: FloatArray, later: IntArray) -> None:
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


def _refine(poses: ClearancePoses, refine_max: int, block: int) -> None:
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
