"""meshdist's nearest distance: the same numbers as every pair measured, in blocks of a fixed budget."""

from __future__ import annotations

import numpy as np
import pytest

from prs3_post.part import meshdist, meshindex
from prs3_post.part.meshdist import nearest_distance, point_triangle_distance


def _mesh(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, 3, 3) mm: small triangles scattered in a 100 mm box, a few degenerate (a point, a line)."""
    centre = rng.uniform(-50.0, 50.0, (n, 1, 3))
    tri = centre + rng.normal(0.0, 3.0, (n, 3, 3))
    tri[0] = tri[0, 0]                                        # all three corners one point
    tri[1, 2] = 0.5 * (tri[1, 0] + tri[1, 1])                 # a corner on the opposite edge
    return tri


@pytest.mark.parametrize("budget", [5, 64, 1 << 17])
def test_nearest_distance_is_the_least_of_every_pair_exactly(budget):
    rng = np.random.default_rng(3)
    tri = _mesh(rng, 60)
    points = np.concatenate([rng.uniform(-80.0, 80.0, (200, 3)), tri[5:8, 1], [[1e4, -3e3, 2e4]]])
    every = point_triangle_distance(points, tri).min(axis=1)
    assert nearest_distance(points, tri, budget=budget).tolist() == every.tolist()   # bit for bit


def test_nearest_distance_of_no_points_or_no_triangles():
    tri = _mesh(np.random.default_rng(4), 5)
    assert nearest_distance(np.zeros((0, 3)), tri).shape == (0,)
    assert nearest_distance(np.ones((2, 3)), np.zeros((0, 3, 3))).tolist() == [np.inf, np.inf]


def test_nearest_distance_asks_for_at_most_the_budget_of_pairs_at_a_time(monkeypatch):
    seen: list[int] = []
    kernel = meshdist.triangle_distance

    def spy(p, a, b, c):
        seen.append(int(np.prod(np.broadcast_shapes(np.shape(p), np.shape(a))[:-1])))
        return kernel(p, a, b, c)

    monkeypatch.setattr(meshdist, "triangle_distance", spy)
    monkeypatch.setattr(meshindex, "triangle_distance", spy)     # the index measures its own pairs
    rng = np.random.default_rng(5)
    tri = _mesh(rng, 40)
    points = rng.uniform(-1e3, 1e3, (500, 3))            # far: the boxes prune little
    nearest_distance(points, tri, budget=100)
    assert seen and max(seen) <= 100
    seen.clear()
    nearest_distance(points, tri, budget=16)                # fewer than the triangles: they go in pieces too
    assert seen and max(seen) <= 16
