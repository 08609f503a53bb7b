"""The 3D arc expander: exact end points, direction, chordal tolerance in any plane."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from prs3_post.toolpaths.arcs import arc_points_3d, arc_segment_count, arc_sweep
from prs3_post.toolpaths.profiles import arc_points

Z = np.array([0.0, 0.0, 1.0])


def _frame(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(normal, helper)
    u /= np.linalg.norm(u)
    return u, np.cross(normal, u)


def _sagitta(points: np.ndarray, centre: np.ndarray, normal: np.ndarray, radius: float) -> float:
    """Largest distance from a chord's midpoint to the circle (points on a circle in a plane)."""
    mid = 0.5 * (points[1:] + points[:-1]) - centre
    radial = mid - np.outer(mid @ normal, normal)
    return float(np.max(radius - np.linalg.norm(radial, axis=1)))


def test_quarter_circle_in_xy_counter_clockwise() -> None:
    points = arc_points_3d(np.zeros(3), Z, np.array([1.0, 0, 0]), np.array([0.0, 1, 0]), tolerance=0.1)
    assert_allclose(points, [[1, 0, 0], [math.sqrt(0.5), math.sqrt(0.5), 0], [0, 1, 0]], atol=1e-15)


def test_negative_normal_goes_the_other_way_round() -> None:
    points = arc_points_3d(np.zeros(3), -Z, np.array([1.0, 0, 0]), np.array([0.0, 1, 0]), tolerance=0.1)
    # three quarters clockwise seen from +z, 6 segments of 45°: halfway is at -135°
    assert len(points) == 7
    assert_allclose(points[3], [-math.sqrt(0.5), -math.sqrt(0.5), 0], atol=1e-15)


def test_end_equal_to_start_is_a_full_turn() -> None:
    start = np.array([2.0, 0.0, 5.0])
    points = arc_points_3d(np.array([0.0, 0, 5]), Z, start, start, tolerance=0.01)
    assert arc_sweep(np.array([0.0, 0, 5]), Z, start, start) == 2 * math.pi
    assert len(points) - 1 == arc_segment_count(2.0, 2 * math.pi, tolerance=0.01) == 32
    assert_allclose(np.linalg.norm(points[:, :2], axis=1), 2.0, atol=1e-12)


def test_helix_rises_linearly_with_the_angle() -> None:
    points = arc_points_3d(np.zeros(3), Z, np.array([1.0, 0, 0]), np.array([-1.0, 0, 3.0]), tolerance=0.001)
    angle = np.unwrap(np.arctan2(points[:, 1], points[:, 0]))
    assert_allclose(points[:, 2], 3.0 * angle / math.pi, atol=1e-12)


def test_extra_turns() -> None:
    points = arc_points_3d(np.zeros(3), Z, np.array([1.0, 0, 0]), np.array([0.0, 1, 0]), tolerance=0.1, turns=1)
    assert len(points) - 1 == arc_segment_count(1.0, 2.5 * math.pi, tolerance=0.1) == 9


def test_spiral_meets_both_radii() -> None:
    points = arc_points_3d(np.zeros(3), Z, np.array([1.0, 0, 0]), np.array([0.0, 1.0001, 0]), tolerance=1e-4)
    radius = np.linalg.norm(points, axis=1)
    assert radius[0] == 1.0 and radius[-1] == 1.0001
    assert np.all(np.diff(radius) > 0)


@pytest.mark.parametrize(("normal", "start"), [((0.0, 0.0, 0.0), (1.0, 0, 0)), ((0.0, 0, 1), (0.0, 0, 3))])
def test_degenerate_arcs_are_refused(normal: tuple[float, ...], start: tuple[float, ...]) -> None:
    with pytest.raises(ValueError):
        arc_points_3d(np.zeros(3), np.array(normal), np.array(start), np.array([0.0, 1, 0]), tolerance=0.1)


def test_the_2d_profile_arcs_are_the_special_case() -> None:
    """ops.profiles.arc_points (plane z = 0, start by angle) gives the same points."""
    centre, radius, start, sweep = np.array([3.0, -2.0]), 7.5, 0.3, 1.9
    flat = arc_points(centre, radius, start, sweep, tolerance=0.002)
    c3 = np.array([*centre, 0.0])
    ends = [c3 + radius * np.array([math.cos(a), math.sin(a), 0.0]) for a in (start, start + sweep)]
    points = arc_points_3d(c3, Z, ends[0], ends[1], tolerance=0.002)
    assert_allclose(points[:, :2], flat, atol=1e-12)


unit = st.floats(-1.0, 1.0)


@settings(max_examples=60, deadline=None)
@given(nx=unit, ny=unit, nz=unit, a0=st.floats(0.0, 2 * math.pi), a1=st.floats(0.0, 2 * math.pi),
       radius=st.floats(0.05, 500.0), tolerance=st.floats(1e-4, 0.1), flip=st.booleans())
def test_any_plane_points_on_circle_within_tolerance(nx: float, ny: float, nz: float, a0: float, a1: float,
                                                      radius: float, tolerance: float, flip: bool) -> None:
    normal = np.array([nx, ny, nz])
    if np.linalg.norm(normal) < 0.1:
        normal = Z
    normal = normal / np.linalg.norm(normal)
    u, v = _frame(normal)
    centre = np.array([10.0, -20.0, 30.0])
    start = centre + radius * (math.cos(a0) * u + math.sin(a0) * v)
    end = centre + radius * (math.cos(a1) * u + math.sin(a1) * v)
    direction = -normal if flip else normal
    points = arc_points_3d(centre, direction, start, end, tolerance=tolerance)
    assert np.array_equal(points[0], start) and np.array_equal(points[-1], end)
    assert_allclose(np.linalg.norm(points - centre, axis=1), radius, atol=1e-9 * max(1.0, radius))
    assert_allclose((points - centre) @ normal, 0.0, atol=1e-9 * max(1.0, radius))
    assert _sagitta(points, centre, normal, radius) <= tolerance + 1e-9 * radius
    turning = np.cross(points[:-1] - centre, points[1:] - centre) @ direction
    assert np.all(turning > -1e-9 * radius**2)
    # no more segments than needed: one fewer would break the tolerance
    count = len(points) - 1
    sweep = arc_sweep(centre, direction, start, end)
    if count > 4:
        assert radius * (1 - math.cos(sweep / (count - 1) / 2)) > tolerance
