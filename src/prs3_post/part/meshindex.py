"""A bounding-volume hierarchy over a mesh's triangles, built and walked with numpy (pure, no I/O).

The triangles are sorted along a Morton curve of their boxes' centres and cut into leaves of
:data:`LEAF` consecutive triangles; each level above groups :data:`FANOUT` consecutive nodes of the
one below, up to at most :data:`FANOUT` nodes at the top. A node is its box (the union of its
triangles' boxes), so a node is an array row and its children are the rows ``FANOUT·n`` ..
``FANOUT·n + FANOUT − 1`` of the level below: the memory is a few floats per triangle (the boxes of
every level, T/7 rows in all, and the permutation), whatever the queries.

A query walks the levels top down for many query rows at once: the (query, node) pairs whose boxes
may hold what is asked are expanded into the children's pairs and the others dropped, a stack of
pieces of at most ``budget`` pairs at a time (memory: proportional to the pairs near the queries,
never to queries × triangles). The pruning is conservative: a node is dropped only where no
triangle in it can be what is asked, with a slack far larger than the rounding of the boxes'
distances, and what is finally measured (:func:`triangle_distance`, pair by
pair) is the same number for a pair whoever asks; so a query answers exactly as every pair measured.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import numpy.typing as npt

from prs3_post.core.types import BoolArray, FloatArray, IntArray

__all__ = ["FANOUT", "LEAF", "TriangleIndex", "triangle_distance"]

#: Triangles per leaf.
LEAF = 8
#: Children per node above the leaves.
FANOUT = 8
#: Relative to |p|² + |q|² (mm²): how much a square distance's rounding is taken to be, far more than
#: its few ulps (meshdist's pruning uses the same), so that the pruning never drops a triangle it needs.
SQUARE_SLACK = 1e-9
#: Pairs walked at a time by default (memory: a few hundred bytes each while walked).
BUDGET = 1 << 17


def _spread_bits(q: IntArray) -> npt.NDArray[np.uint64]:
    """10-bit integers with two zero bits inserted after each bit (a Morton code's one axis)."""
    x = q.astype(np.uint64) & np.uint64(0x3FF)
    x = (x | (x << np.uint64(16))) & np.uint64(0x030000FF)
    x = (x | (x << np.uint64(8))) & np.uint64(0x0300F00F)
    x = (x | (x << np.uint64(4))) & np.uint64(0x030C30C3)
    x = (x | (x << np.uint64(2))) & np.uint64(0x09249249)
    return x


def _gap2(x: FloatArray, low: FloatArray, high: FloatArray) -> FloatArray:
    """(K,) mm²: the square distance from points ``x`` to boxes [low, high] (each (3, K): a row per axis)."""
    gap = np.maximum(np.maximum(low - x, x - high), 0.0)
    return _sum3(gap * gap)


def _box_gap2(x_low: FloatArray, x_high: FloatArray, low: FloatArray, high: FloatArray) -> FloatArray:
    """(K,) mm²: the square distance between boxes [x_low, x_high] and [low, high] (each (3, K))."""
    gap = np.maximum(np.maximum(low - x_high, x_low - high), 0.0)
    return _sum3(gap * gap)


def _sum3(rows: FloatArray) -> FloatArray:
    """(K,): the sum of the 3 rows of ``rows`` (3, K) (numpy's reduction over so short an axis is slow)."""
    out: FloatArray = rows[0] + rows[1] + rows[2]
    return out


def _cols(rows: FloatArray, at: IntArray) -> FloatArray:
    """(3, K): the columns ``at`` of ``rows`` (3, N) (``take`` is far faster than ``rows[:, at]``)."""
    out: FloatArray = np.take(rows, at, axis=1)
    return out


def _pieces(level: int, rows: IntArray, node: IntArray, step: int) -> list[tuple[int, IntArray, IntArray]]:
    """The pairs (``rows``, ``node``) at ``level`` cut into pieces of at most ``step``, the first last
    (a stack: the first is walked first)."""
    return [(level, rows[k:k + step], node[k:k + step]) for k in range(0, len(rows), step)][::-1]


def _dot(x: FloatArray, y: FloatArray) -> FloatArray:
    return (x * y).sum(-1)


def triangle_distance(p: FloatArray, a: FloatArray, b: FloatArray, c: FloatArray) -> FloatArray:
    """mm: exact distance from points ``p`` to triangles ``a b c`` (each (..., 3), broadcast together;
    Ericson's Voronoi regions)."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = _dot(ab, ap), _dot(ac, ap)
    bp = p - b
    d3, d4 = _dot(ab, bp), _dot(ac, bp)
    cp = p - c
    d5, d6 = _dot(ab, cp), _dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v = vb / denom
        w = vc / denom
        closest = a + ab * v[..., None] + ac * w[..., None]                  # inside the face
        t_ab = np.clip(d1 / (d1 - d3), 0, 1)
        t_ac = np.clip(d2 / (d2 - d6), 0, 1)
        t_bc = np.clip((d4 - d3) / ((d4 - d3) + (d5 - d6)), 0, 1)
    on_ab = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
    on_ac = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
    on_bc = (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)
    closest = np.where(on_bc[..., None], b + (c - b) * t_bc[..., None], closest)
    closest = np.where(on_ac[..., None], a + ac * t_ac[..., None], closest)
    closest = np.where(on_ab[..., None], a + ab * t_ab[..., None], closest)
    closest = np.where(((d6 >= 0) & (d5 <= d6))[..., None], c, closest)
    closest = np.where(((d3 >= 0) & (d4 <= d3))[..., None], b, closest)
    closest = np.where(((d1 <= 0) & (d2 <= 0))[..., None], a, closest)
    return np.linalg.norm(p - closest, axis=-1)


class TriangleIndex:
    """The hierarchy of boxes over triangles (T, 3, 3) mm (module docstring).

    Attributes
    ----------
    triangles : (T, 3, 3) float — mm, as given (not copied)
    low, high : (T, 3) float — mm, each triangle's box
    order : (T,) int — the triangles along the curve: leaf ``k`` holds ``order[LEAF·k : LEAF·k + LEAF]``
    levels : list of ((3, N_k), (3, N_k), (3, N_k)) float — each node's box (low, high) and the corner
        of one of its triangles nearest the box's centre, a row per axis; the leaves first, the top last
    """

    def __init__(self, triangles: FloatArray):
        self.triangles = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
        n = len(self.triangles)
        self.low = self.triangles.min(axis=1)
        self.high = self.triangles.max(axis=1)
        self.levels: list[tuple[FloatArray, FloatArray, FloatArray]] = []
        self.order = np.zeros(0, dtype=np.int64)
        #: mm²: the corners' largest square norm (the slack's scale)
        self.scale2 = float((self.triangles.reshape(-1, 3) ** 2).sum(axis=1).max()) if n else 0.0
        if not n:
            return
        centre = 0.5 * (self.low + self.high)
        least, most = centre.min(axis=0), centre.max(axis=0)
        cell = np.where(most > least, (most - least) / 1023.0, 1.0)
        q = np.clip(np.floor((centre - least) / cell), 0, 1023).astype(np.int64)
        code = _spread_bits(q[:, 0]) | (_spread_bits(q[:, 1]) << np.uint64(1)) | (_spread_bits(q[:, 2]) << np.uint64(2))
        self.order = np.argsort(code, kind="stable").astype(np.int64)
        low, high = self.low[self.order], self.high[self.order]
        starts = np.arange(0, n, LEAF)
        low, high = np.minimum.reduceat(low, starts), np.maximum.reduceat(high, starts)
        # each leaf's corner nearest its box's centre (one of its triangles': above their nearest), a
        # corner of the triangles at a time (memory: a few (T, 3) arrays, not (3T, 3) ones)
        centre = (0.5 * (low + high))[np.arange(n) // LEAF]
        far = np.full((len(starts) * LEAF, 3), np.inf)
        for c in range(3):
            far[:n, c] = ((self.triangles[self.order, c] - centre) ** 2).sum(axis=1)
        del centre
        pick = far.reshape(len(starts), 3 * LEAF).argmin(axis=1)              # (triangle, corner) in the leaf
        corners = self.triangles[self.order[starts + pick // 3], pick % 3]
        self.levels.append((low.T.copy(), high.T.copy(), corners.T.copy()))
        while len(low) > FANOUT:                        # each node: its children's, and the corner nearest its centre
            starts = np.arange(0, len(low), FANOUT)
            low, high = np.minimum.reduceat(low, starts), np.maximum.reduceat(high, starts)
            gap = np.full(len(starts) * FANOUT, np.inf)
            gap[:len(corners)] = ((corners - (0.5 * (low + high))[np.arange(len(corners)) // FANOUT]) ** 2).sum(axis=1)
            corners = corners[starts + gap.reshape(len(starts), FANOUT).argmin(axis=1)]
            self.levels.append((low.T.copy(), high.T.copy(), corners.T.copy()))

    @staticmethod
    def _boxes(corner: FloatArray, tri: IntArray) -> FloatArray:
        """(3, K): rows ``tri`` of a (T, 3) array of the triangles' box corners, a row per axis."""
        out: FloatArray = np.take(corner, tri, axis=0).T
        return out

    def _counts(self, mask: BoolArray | None) -> list[IntArray] | None:
        """Per level, the triangles that count under each node (None: every triangle counts)."""
        if mask is None:
            return None
        allowed = np.asarray(mask, dtype=bool)[self.order].astype(np.int64)
        counts = []
        width = LEAF
        for _ in self.levels:
            allowed = np.add.reduceat(allowed, np.arange(0, len(allowed), width))
            counts.append(allowed)
            width = FANOUT
        return counts

    def _children(self, level: int, node: IntArray) -> IntArray:
        """(K·FANOUT,) the children of nodes ``node`` at ``level`` > 0 (−1 past the last one)."""
        child = (node[:, None] * FANOUT + np.arange(FANOUT)).ravel()
        return np.where(child < self.levels[level - 1][0].shape[1], child, -1)

    def _leaf_triangles(self, node: IntArray) -> IntArray:
        """(K·LEAF,) the triangles of leaves ``node`` (−1 past the last one)."""
        at = (node[:, None] * LEAF + np.arange(LEAF)).ravel()
        ok = at < len(self.order)
        return np.where(ok, self.order[np.where(ok, at, 0)], -1)

    def _top(self, n: int) -> tuple[int, IntArray, IntArray]:
        """Every query row ``n`` against every top node: the walk's start."""
        top = len(self.levels) - 1
        n_top = self.levels[top][0].shape[1]
        return top, np.repeat(np.arange(n), n_top), np.tile(np.arange(n_top), n)

    def pairs_near(self, query_low: FloatArray, query_high: FloatArray, radius: FloatArray | float, *,
                   mask: BoolArray | None = None, budget: int = BUDGET) -> Iterator[tuple[IntArray, IntArray]]:
        """The (query, triangle) pairs whose boxes are within ``radius`` of each other, in pieces of at
        most ``max(budget, LEAF)`` pairs (in no particular order; every such pair once).

        Parameters
        ----------
        query_low, query_high : (Q, 3) float — mm, the queries' boxes (a point: the same row twice)
        radius : (Q,) or scalar float — mm, how far from its box a query looks; the test is widened by a slack
            far larger than its rounding (a superset: the caller measures the pairs)
        mask : (T,) bool, optional — the triangles that count (default: all)
        budget : int — pairs walked at a time
        """
        q_low = np.asarray(query_low, dtype=np.float64).reshape(-1, 3)
        q_high = np.asarray(query_high, dtype=np.float64).reshape(-1, 3)
        radius = np.broadcast_to(np.asarray(radius, dtype=np.float64), (len(q_low),))
        if not len(q_low) or not self.levels:
            return
        own = np.maximum((q_low ** 2).sum(axis=1), (q_high ** 2).sum(axis=1))
        reach2 = radius ** 2 + SQUARE_SLACK * (own + radius ** 2 + self.scale2 + 1.0)       # (Q,) mm², widened
        q_low, q_high = q_low.T.copy(), q_high.T.copy()
        counts = self._counts(mask)
        allowed = None if mask is None else np.asarray(mask, dtype=bool)
        stack = [self._top(q_low.shape[1])]
        step = max(1, budget // max(LEAF, FANOUT))
        while stack:
            level, query, node = stack.pop()
            if len(query) > step:                       # its expansion would pass the budget: in pieces
                stack += _pieces(level, query, node, step)
                continue
            low, high, _ = self.levels[level]
            gap2 = _box_gap2(_cols(q_low, query), _cols(q_high, query), _cols(low, node), _cols(high, node))
            keep = gap2 <= reach2[query]
            if counts is not None:
                keep &= counts[level][node] > 0
            query, node = query[keep], node[keep]
            if not len(query):
                continue
            pairs = self._descend(level, query, node, allowed, stack)
            if pairs is None:
                continue
            query, tri = pairs
            gap2 = _box_gap2(_cols(q_low, query), _cols(q_high, query), self._boxes(self.low, tri),
                             self._boxes(self.high, tri))
            close = gap2 <= reach2[query]
            if close.any():
                yield query[close], tri[close]

    def _descend(self, level: int, query: IntArray, node: IntArray, allowed: BoolArray | None,
                 stack: list[tuple[int, IntArray, IntArray]]) -> tuple[IntArray, IntArray] | None:
        """One step down for the (query row, node) pairs kept at ``level``: above the leaves, their
        children's pairs go on ``stack`` (None is returned); at the leaves, the (query row, triangle)
        pairs whose triangle counts (``allowed``; None: all) are returned."""
        if level > 0:
            child = self._children(level, node)
            query = np.repeat(query, FANOUT)
            ok = child >= 0
            stack.append((level - 1, query[ok], child[ok]))
            return None
        tri = self._leaf_triangles(node)
        query = np.repeat(query, LEAF)
        ok = tri >= 0
        if allowed is not None:
            ok[ok] = allowed[tri[ok]]
        return query[ok], tri[ok]

    def nearest(self, points: FloatArray, *, mask: BoolArray | None = None, cap: FloatArray | None = None,
                budget: int = BUDGET) -> FloatArray:
        """(P,) mm: each point's (P, 3) distance to the nearest triangle that counts (``mask``, default
        all; inf: none), exactly the least of :func:`triangle_distance` over them.

        A node is dropped where its box is farther than a triangle's corner (the one kept for each
        node; with a ``mask``, the farthest corner of a box that holds one that counts), widened by
        the slack: the nearest triangle never is. ``cap`` (P,) mm: where a point's nearest is farther
        than its cap, inf instead (the walk drops what is farther from the start). ``budget``: pairs
        walked, and measured, at a time."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        out = np.full(len(points), np.inf)
        if not len(points) or not self.levels:
            return out
        if mask is not None and np.all(mask):
            mask = None                                 # every triangle: each node's corner bounds it
        counts = self._counts(mask)
        allowed = None if mask is None else np.asarray(mask, dtype=bool)
        if counts is not None and not counts[-1].sum():
            return out
        slack = SQUARE_SLACK * ((points * points).sum(axis=1) + self.scale2 + 1.0)           # (P,) mm²
        # mm²: above each point's nearest (or its cap)
        upper = np.full(len(points), np.inf) if cap is None else np.square(np.asarray(cap, dtype=np.float64))
        points_t = points.T.copy()
        stack = [self._top(len(points))]
        step = max(1, budget // max(LEAF, FANOUT))
        while stack:
            level, point, node = stack.pop()
            if len(point) > step:
                stack += _pieces(level, point, node, step)
                continue
            low, high, corner = self.levels[level]
            x, lo, hi = _cols(points_t, point), _cols(low, node), _cols(high, node)
            if counts is None:                          # a triangle's corner: above the nearest
                holds = np.ones(len(node), dtype=bool)
                above = _sum3((x - _cols(corner, node)) ** 2)
            else:                                       # the farthest corner of a box that holds one that counts
                holds = counts[level][node] > 0
                far = np.maximum(np.abs(x - lo), np.abs(x - hi))
                above = np.where(holds, _sum3(far * far), np.inf)
            np.minimum.at(upper, point, above)
            keep = holds & (_gap2(x, lo, hi) <= upper[point] + slack[point])
            point, node = point[keep], node[keep]
            if not len(point):
                continue
            pairs = self._descend(level, point, node, allowed, stack)
            if pairs is None:
                continue
            point, tri = pairs
            x = _cols(points_t, point)
            corners = np.take(self.triangles, tri, axis=0).transpose(1, 2, 0)                # (3, 3, K)
            nearest_corner = np.minimum(np.minimum(_sum3((corners[0] - x) ** 2), _sum3((corners[1] - x) ** 2)),
                                        _sum3((corners[2] - x) ** 2))
            np.minimum.at(upper, point, nearest_corner)                                     # a corner: above
            close = _gap2(x, self._boxes(self.low, tri), self._boxes(self.high, tri)) <= upper[point] + slack[point]
            point, tri = point[close], tri[close]
            for k in range(0, len(point), max(1, budget)):
                p, t = point[k:k + budget], tri[k:k + budget]
                c = self.triangles[t]
                np.minimum.at(out, p, triangle_distance(points[p], c[:, 0], c[:, 1], c[:, 2]))
        if cap is not None:
            out = np.where(out <= cap, out, np.inf)
        return out
