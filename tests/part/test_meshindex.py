"""The triangle index: its queries give exactly what every pair measured gives (random meshes and points)."""

from __future__ import annotations

import functools
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import example, given, settings
from hypothesis import strategies as st

from prs3_post.check.collision import body_cylinders, clearance
from prs3_post.check.collision_distance import cylinder_penetration
from prs3_post.core.defaults import DEFAULT_CLEARANCE_MIN
from prs3_post.machine.loading import load_machine
from prs3_post.part.face import Face
from prs3_post.part.faces import find_faces, select_face
from prs3_post.part.meshdist import point_triangle_distance
from prs3_post.part.meshindex import LEAF, TriangleIndex
from prs3_post.part.stl import load_part


def _mesh(rng: np.random.Generator, n: int, spread: float) -> np.ndarray:
    """(n, 3, 3) mm: triangles of about ``spread`` mm scattered in a 100 mm box, the first two degenerate
    (a point; a corner on the opposite edge) where there are that many."""
    centre = rng.uniform(-50.0, 50.0, (n, 1, 3))
    tri = centre + rng.normal(0.0, spread, (n, 3, 3))
    if n > 0:
        tri[0] = tri[0, 0]
    if n > 1:
        tri[1, 2] = 0.5 * (tri[1, 0] + tri[1, 1])
    return tri


def _points(rng: np.random.Generator, tri: np.ndarray, n: int) -> np.ndarray:
    """(n + a few, 3) mm: points in and round the box, some on the triangles' corners, one far."""
    corners = tri.reshape(-1, 3)[:3]
    return np.concatenate([rng.uniform(-90.0, 90.0, (n, 3)), corners, [[1e4, -3e3, 2e4]]])


@settings(deadline=None, max_examples=60)
@given(seed=st.integers(0, 2 ** 32 - 1), triangles=st.integers(0, 300), points=st.integers(0, 120),
       spread=st.sampled_from([0.01, 1.0, 6.0, 40.0]), budget=st.sampled_from([3, 64, 1 << 17]))
@example(seed=0, triangles=LEAF * 8 + 1, points=50, spread=1.0, budget=3)     # a leaf and a node past full ones
def test_nearest_is_the_least_of_every_pair_bit_for_bit(seed, triangles, points, spread, budget):
    rng = np.random.default_rng(seed)
    tri = _mesh(rng, triangles, spread)
    p = _points(rng, tri, points) if triangles else rng.uniform(-90.0, 90.0, (points, 3))
    every = point_triangle_distance(p, tri).min(axis=1) if triangles else np.full(len(p), np.inf)
    assert TriangleIndex(tri).nearest(p, budget=budget).tolist() == every.tolist()


@settings(deadline=None, max_examples=40)
@given(seed=st.integers(0, 2 ** 32 - 1), triangles=st.integers(1, 300), points=st.integers(1, 120),
       keep=st.floats(0.0, 1.0))
def test_nearest_among_a_mask_and_under_a_cap(seed, triangles, points, keep):
    rng = np.random.default_rng(seed)
    tri = _mesh(rng, triangles, 3.0)
    p = _points(rng, tri, points)
    mask = rng.uniform(size=triangles) < keep
    every = point_triangle_distance(p, tri)[:, mask].min(axis=1, initial=np.inf)
    index = TriangleIndex(tri)
    assert index.nearest(p, mask=mask).tolist() == every.tolist()
    cap = rng.uniform(0.0, 60.0, len(p))                  # exact where within the cap, else inf
    assert index.nearest(p, mask=mask, cap=cap).tolist() == np.where(every <= cap, every, np.inf).tolist()


@settings(deadline=None, max_examples=40)
@given(seed=st.integers(0, 2 ** 32 - 1), triangles=st.integers(0, 300), queries=st.integers(0, 60),
       budget=st.sampled_from([3, 64, 1 << 17]))
def test_pairs_near_are_every_pair_whose_boxes_are_that_close_once(seed, triangles, queries, budget):
    rng = np.random.default_rng(seed)
    tri = _mesh(rng, triangles, 3.0)
    low = rng.uniform(-80.0, 80.0, (queries, 3))
    high = low + rng.uniform(0.0, 20.0, (queries, 3)) * (rng.uniform(size=(queries, 1)) < 0.5)   # half points
    radius = rng.uniform(0.0, 30.0, queries)
    mask = rng.uniform(size=triangles) < 0.8
    gap = np.maximum(np.maximum(tri.min(axis=1)[None] - high[:, None], low[:, None] - tri.max(axis=1)[None]), 0.0)
    square = (gap * gap).sum(axis=2)                                    # (Q, T) mm²
    found = list(TriangleIndex(tri).pairs_near(low, high, radius, mask=mask, budget=budget))
    assert all(len(q) <= max(budget, LEAF) for q, _ in found)
    pairs = sorted((int(q), int(t)) for qs, ts in found for q, t in zip(qs, ts, strict=True))
    assert len(pairs) == len(set(pairs))                                # each pair once
    # every pair within the radius is there; those past it only within the slack (far under a micrometre)
    within = {(int(q), int(t)) for q, t in zip(*np.nonzero((square <= radius[:, None] ** 2) & mask), strict=True)}
    assert within <= set(pairs)
    extra = [(q, t) for q, t in pairs if (q, t) not in within]
    assert all(mask[t] and np.sqrt(square[q, t]) - radius[q] < 1e-4 for q, t in extra)


def test_no_triangles_or_no_queries():
    empty = TriangleIndex(np.zeros((0, 3, 3)))
    assert empty.nearest(np.ones((2, 3))).tolist() == [np.inf, np.inf]
    assert list(empty.pairs_near(np.zeros((1, 3)), np.zeros((1, 3)), np.ones(1))) == []
    one = TriangleIndex(np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]]))
    assert one.nearest(np.zeros((0, 3))).shape == (0,)
    assert one.nearest(np.array([[0.25, 0.25, 2.0]])).tolist() == [2.0]
    assert one.nearest(np.array([[0.25, 0.25, 2.0]]), mask=np.zeros(1, dtype=bool)).tolist() == [np.inf]


@pytest.mark.parametrize("n", [1, LEAF, LEAF * 8, LEAF * 8 + 1, 5000])
def test_every_triangle_is_in_one_leaf_and_every_node_holds_its_children(n):
    tri = _mesh(np.random.default_rng(n), n, 2.0)
    index = TriangleIndex(tri)
    assert sorted(index.order.tolist()) == list(range(n))
    low, high, corner = index.levels[0]
    for k in range(low.shape[1]):                                       # a leaf's box is its triangles'
        mine = index.order[k * LEAF:(k + 1) * LEAF]
        assert low[:, k].tolist() == tri[mine].reshape(-1, 3).min(axis=0).tolist()
        assert high[:, k].tolist() == tri[mine].reshape(-1, 3).max(axis=0).tolist()
        assert any(np.array_equal(corner[:, k], c) for c in tri[mine].reshape(-1, 3))    # one of its corners
    assert index.levels[-1][0].shape[1] <= 8


# --- the collision check with the index gives what it gave measuring every pair ----------------------------

def _brute_pairs_near(index, query_low, query_high, radius, *, mask=None, budget=0):
    """Every (query, triangle) pair (of those that count): what the bounds measured before the index."""
    q, t = np.meshgrid(np.arange(len(query_low)), np.arange(len(index.triangles)), indexing="ij")
    q, t = q.ravel(), t.ravel()
    keep = np.ones(len(t), dtype=bool) if mask is None else np.asarray(mask)[t]
    yield q[keep], t[keep]


def _brute_nearest(index, points, *, mask=None, cap=None, budget=0):
    """The least of every pair, every point measured (no cap)."""
    every = point_triangle_distance(np.asarray(points).reshape(-1, 3), index.triangles)
    if mask is not None:
        every = every[:, np.asarray(mask, dtype=bool)]
    return every.min(axis=1, initial=np.inf)


@functools.cache
def _wall_part() -> tuple[np.ndarray, Face, np.ndarray]:
    """wall30.stl with each triangle cut in four (80: triangle k's are 4k .. 4k + 3), its worked face,
    and the default tool's bodies."""
    mesh = load_part(str(Path(__file__).resolve().parents[2] / "fixtures" / "parts" / "wall30.stl"), units="mm")
    face, _ = select_face(find_faces(mesh), None, min_width=6.0)
    fine = trimesh.Trimesh(mesh.vertices, mesh.faces).subdivide()
    quarters = (4 * np.asarray(face.triangles)[:, None] + np.arange(4)).ravel()
    holder = load_machine("patel2020").holder
    return (np.asarray(fine.triangles, dtype=np.float64), replace(face, triangles=quarters),
            body_cylinders(6.0, 55.0, holder))


@settings(deadline=None, max_examples=10)
@given(seed=st.integers(0, 2 ** 32 - 1), poses=st.integers(1, 12), height=st.floats(-2.0, 40.0))
def test_clearance_with_the_index_is_what_every_pair_gave(seed, poses, height):
    triangles, face, bodies = _wall_part()
    rng = np.random.default_rng(seed)
    uv = np.cumsum(rng.normal(0.0, 4.0, (poses, 2)), axis=0) + rng.uniform(-30.0, 30.0, 2)   # a wandering path
    tip = face.origin + uv[:, :1] * face.u + uv[:, 1:] * face.v + (height + rng.uniform(0.0, 3.0, (poses, 1))) \
        * face.normal
    axis = face.normal + rng.normal(0.0, 0.1, (poses, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    connected = rng.uniform(size=poses) < 0.8

    def run() -> tuple[list, ...]:
        found = clearance(triangles, tip, axis, bodies, None if seed % 3 == 0 else face, tip[: poses // 2],
                          refine_max=2, block=4, connected=connected, clearance_min=DEFAULT_CLEARANCE_MIN)
        return found.distance.tolist(), found.sample.tolist(), found.point.tolist(), found.exact.tolist()

    indexed = run()
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(TriangleIndex, "pairs_near", _brute_pairs_near)
        patch.setattr(TriangleIndex, "nearest", _brute_nearest)
        assert run() == indexed


@settings(deadline=None, max_examples=60)
@given(seed=st.integers(0, 2 ** 32 - 1), triangles=st.integers(1, 200), spread=st.sampled_from([0.5, 3.0, 20.0]))
def test_the_triangles_near_a_cylinders_box_give_its_whole_penetration(seed, triangles, spread):
    """collision._solid measures a body's solid cylinder against the triangles the index finds near its
    box only: every triangle that enters it is one of those, so the depth is the same number."""
    rng = np.random.default_rng(seed)
    tri = _mesh(rng, triangles, spread) * 0.4                   # in a 40 mm box: many enter the cylinder
    tip = rng.uniform(-20.0, 20.0, 3)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    cylinder = np.array([rng.uniform(0.5, 15.0), rng.uniform(-5.0, 5.0), rng.uniform(5.0, 40.0)])
    ends = np.stack([tip + cylinder[1] * axis, tip + cylinder[2] * axis])
    found = list(TriangleIndex(tri).pairs_near(ends.min(axis=0)[None] - cylinder[0],
                                               ends.max(axis=0)[None] + cylinder[0], 0.0))
    near = np.sort(np.concatenate([np.zeros(0, dtype=np.int64), *(t for _, t in found)]))
    assert cylinder_penetration(tip, axis, cylinder, tri[near]) == cylinder_penetration(tip, axis, cylinder, tri)


@settings(deadline=None, max_examples=25)
@given(seed=st.integers(0, 2 ** 32 - 1), poses=st.integers(1, 70), height=st.floats(-2.0, 30.0),
       spread=st.booleans())
def test_the_groups_plane_bound_drops_only_pairs_no_pose_bounds_under_the_reach(seed, poses, height, spread):
    """pose_bounds gives the same bounds and near pairs with the groups' plane test (collision._plane_gap) as
    without it, for poses one at a time and for the scan's groups (a spread round each)."""
    from prs3_post.check import collision_distance as collision

    triangles, face, bodies = _wall_part()
    part = collision.Part.of(triangles, face, 1.0)
    rng = np.random.default_rng(seed)
    uv = np.cumsum(rng.normal(0.0, 1.5, (poses, 2)), axis=0) + rng.uniform(-30.0, 30.0, 2)
    tip = face.origin + uv[:, :1] * face.u + uv[:, 1:] * face.v + (height + np.cumsum(
        rng.normal(0.0, 0.3, (poses, 1)), axis=0)) * face.normal
    axis = face.normal + np.cumsum(rng.normal(0.0, 0.01, (poses, 3)), axis=0)
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    cutting = rng.uniform(size=poses) < 0.5
    group = collision.Spread(frame=np.stack([face.u, face.v, face.normal]), half=rng.uniform(0.0, 2.0, (poses, 3)),
                             turn=rng.uniform(0.0, 0.01, poses)) if spread else None

    def run() -> tuple[list, ...]:
        out, key, tri = collision.pose_bounds(part, tip, axis, cutting & (group is None), collision.body_pieces(bodies),
                                              reach=11.0, near=3.0, spread=group)
        return out.tolist(), key.tolist(), tri.tolist()

    pruned = run()
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(collision, "_plane_gap", lambda *args: np.full(len(args[-1]), -np.inf))
        assert run() == pruned
