"""Distances between points, segments and triangles, and inside-the-mesh tests (numpy, pure).

Every function takes its pairs already formed (a point or segment and a triangle per row, or
broadcastable arrays), so that callers choose which pairs are worth measuring; :func:`nearest_distance`
chooses them with a :class:`~prs3_post.part.meshindex.TriangleIndex`, and :func:`inside` bins the
triangles along its ray so that a point meets only the triangles its ray can cross.
"""

from __future__ import annotations

import math

import numpy as np

from prs3_post.core.types import BoolArray, FloatArray
from prs3_post.part.meshindex import TriangleIndex, triangle_distance

__all__ = ["PAIR_BUDGET", "RAY", "inside", "nearest_distance", "point_triangle_distance", "segment_triangle_distance",
           "triangle_distance"]

#: Point × triangle pairs measured at a time (memory: a few hundred bytes each while measured).
PAIR_BUDGET = 1 << 17

#: The direction of the inside test's ray: no axis-aligned edge lies along it.
RAY = np.array([0.5773502691896258, 0.4082482904638631, 0.7071067811865476])


def _dot(x: FloatArray, y: FloatArray) -> FloatArray:
    return (x * y).sum(-1)


def point_triangle_distance(points: FloatArray, triangles: FloatArray) -> FloatArray:
    """(P, T) mm: exact distance from each point (P, 3) to each triangle (T, 3, 3)."""
    return triangle_distance(points[:, None, :], *(triangles[None, :, k, :] for k in range(3)))


def nearest_distance(points: FloatArray, triangles: FloatArray, *, budget: int = PAIR_BUDGET,
                     index: TriangleIndex | None = None, mask: BoolArray | None = None,
                     cap: FloatArray | None = None) -> FloatArray:
    """(P,) mm: exact distance from each point (P, 3) to the nearest triangle (T, 3, 3) (inf: none);
    the least of :func:`point_triangle_distance`'s row, the same number, in memory bounded by ``budget``.

    The triangles' :class:`~prs3_post.part.meshindex.TriangleIndex` (``index``, built on ``triangles``
    when not given) finds, for each point, the triangles that can be nearest (their boxes no farther
    than the nearest box's farthest corner, or a triangle's nearest corner, widened by far more than
    the rounding); each is measured as :func:`triangle_distance` measures the pair alone, ``budget``
    pairs at a time. ``mask`` (T,) bool: only those triangles count. ``cap`` (P,) mm: where a point's
    nearest is farther than its cap, inf instead (less is measured)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if index is None:
        index = TriangleIndex(np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3))
    return index.nearest(points, mask=mask, cap=cap, budget=budget)


def _segment_segment(p0: FloatArray, p1: FloatArray, q0: FloatArray, q1: FloatArray) -> FloatArray:
    """(K,) mm: distance between segments p0p1 and q0q1 (each (K, 3); Ericson 5.1.9, lengths > 0)."""
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a, e, f = _dot(d1, d1), _dot(d2, d2), _dot(d2, r)
    c, b = _dot(d1, r), _dot(d1, d2)
    a, e = np.maximum(a, 1e-300), np.maximum(e, 1e-300)
    denom = a * e - b * b
    s = np.where(denom > 1e-12 * a * e, np.clip((b * f - c * e) / np.where(denom > 0, denom, 1.0), 0.0, 1.0), 0.0)
    t = (b * s + f) / e
    s = np.where(t < 0, np.clip(-c / a, 0.0, 1.0), np.where(t > 1, np.clip((b - c) / a, 0.0, 1.0), s))
    t = np.clip(t, 0.0, 1.0)
    return np.linalg.norm(p0 + d1 * s[:, None] - q0 - d2 * t[:, None], axis=1)


def _crosses(origin: FloatArray, direction: FloatArray, a: FloatArray, b: FloatArray, c: FloatArray,
             t_max: float) -> BoolArray:
    """(K,) bool: origin + t·direction meets triangle abc for some 0 < t ≤ t_max (Möller–Trumbore)."""
    e1, e2 = b - a, c - a
    h = np.cross(direction, e2)
    det = _dot(e1, h)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = origin - a
    u = _dot(s, h) * inv
    q = np.cross(s, e1)
    v = _dot(q, direction) * inv
    t = _dot(q, e2) * inv
    return ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0) & (t <= t_max)


def segment_triangle_distance(p0: FloatArray, p1: FloatArray, triangles: FloatArray) -> FloatArray:
    """(K,) mm: exact distance between segment p0p1 (each (K, 3)) and triangle (K, 3, 3), pair by pair:
    0 where they meet, else the least of the ends' distances to the triangle and the segment's to its edges."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    out = np.minimum(triangle_distance(p0, a, b, c), triangle_distance(p1, a, b, c))
    for u, v in ((a, b), (b, c), (c, a)):
        out = np.minimum(out, _segment_segment(p0, p1, u, v))
    return np.where(_crosses(p0, p1 - p0, a, b, c, 1.0), 0.0, out)


def inside(points: FloatArray, triangles: FloatArray) -> BoolArray:
    """(P,) bool: the point is inside the closed mesh (crossings of a ray along :data:`RAY`, odd).

    The triangles are binned on a grid in the plane across the ray, so a point meets only those of
    its bin (the pairs are then a few per point, not every triangle)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    out = np.zeros(len(points), dtype=bool)
    if not len(points) or not len(triangles):
        return out
    across = np.stack([np.cross(RAY, [1.0, 0.0, 0.0]), np.cross(RAY, np.cross(RAY, [1.0, 0.0, 0.0]))])
    across /= np.linalg.norm(across, axis=1, keepdims=True)
    flat = triangles @ across.T                                     # (T, 3, 2)
    low, high = flat.min(axis=1), flat.max(axis=1)
    origin = low.min(axis=0)
    extent = float((high.max(axis=0) - origin).max())
    cell = max(extent / max(1.0, math.sqrt(len(triangles))), 1e-9)
    first = np.floor((low - origin) / cell).astype(np.int64)
    last = np.floor((high - origin) / cell).astype(np.int64)
    size = int(last.max()) + 1
    span = last - first + 1
    counts = span[:, 0] * span[:, 1]
    tri = np.repeat(np.arange(len(triangles)), counts)
    k = np.arange(len(tri)) - np.repeat(np.cumsum(counts) - counts, counts)
    key = ((first[tri, 0] + k // span[tri, 1]) * size + first[tri, 1] + k % span[tri, 1])
    order = np.argsort(key, kind="stable")
    key, tri = key[order], tri[order]
    where = np.floor((points @ across.T - origin) / cell).astype(np.int64)
    ok = ((where >= 0) & (where < size)).all(axis=1)
    mine = np.flatnonzero(ok)
    cell_of = where[mine, 0] * size + where[mine, 1]
    start = np.searchsorted(key, cell_of, side="left")
    n = np.searchsorted(key, cell_of, side="right") - start
    point = np.repeat(mine, n)
    pair = tri[np.repeat(start, n) + np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)]
    hits = _crosses(points[point], RAY, triangles[pair, 0], triangles[pair, 1], triangles[pair, 2], np.inf)
    out = (np.bincount(point[hits], minlength=len(points)) % 2) == 1
    return out
