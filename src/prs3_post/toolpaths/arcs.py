"""Circular arcs in 3D, expanded into straight segments within a chordal tolerance.

One implementation for every source of arcs: APT ``CIRCLE/`` records, G-code G2/G3 in any plane
(I J K and R forms, once the caller has found the centre) and the round corners of the
operations. An arc cannot run in joint space (DESIGN.md), so every arc becomes G1 segments.

Geometry
--------
The arc turns counter-clockwise about ``normal`` (right-hand rule: thumb along ``normal``) from
``start`` to ``end``; for a clockwise arc pass ``-normal``. Positions are split into a radial
part in the plane through ``centre`` normal to ``normal`` and a height along ``normal``:

    p(t) = centre + h(t)·n + r(t)·(cos(t·sweep)·u + sin(t·sweep)·v),  t ∈ [0, 1]

with u the unit radial direction of ``start``, v = n × u, and r, h interpolated linearly from the
start's to the end's values. A true circle has r and h constant; a helix (G2/G3 with a move along
the normal) has h changing; input whose start and end radii differ by rounding gets a spiral
that meets both points exactly instead of a jump at the end. Checking that the end lies on the
circle is the caller's job (it knows the file, line and what tolerance the input's decimals allow).

Segment count: a chord of an arc of radius r spanning the angle Δ is off the arc by the sagitta
r·(1 − cos(Δ/2)); the count is the smallest that keeps it ≤ ``tolerance`` at the larger radius.
The height change is linear in the angle, so it adds no chordal error.

:func:`prs3_post.toolpaths.profiles.arc_points` (the round corners and circles of the operations) is the
2D case: a call to :func:`arc_points_3d` with normal +w, its ``[:, :2]``.
"""

from __future__ import annotations

import math

import numpy as np

from prs3_post.core.types import FloatArray

__all__ = ["arc_points_3d", "arc_segment_count", "arc_sweep"]


def _plane_parts(centre: FloatArray, normal: FloatArray, point: FloatArray) -> tuple[float, FloatArray]:
    """Height of ``point`` along ``normal`` above ``centre``, and its radial vector (3,) in the plane."""
    offset = point - centre
    height = float(offset @ normal)
    return height, offset - height * normal


def arc_sweep(centre: FloatArray, normal: FloatArray, start: FloatArray, end: FloatArray, *,
              full_turn_tol: float = 1e-9) -> float:
    """Angle (rad) from ``start`` to ``end`` counter-clockwise about ``normal``, in (0, 2π].

    Parameters
    ----------
    centre, normal, start, end : (3,) float — mm; ``normal`` a unit vector
    full_turn_tol : float — mm; when the radial positions of start and end are this close, the arc
        is a full turn (2π), as CL data and G-code write a full circle (end = start)

    Returns
    -------
    sweep : float — rad, in (0, 2π]

    Raises
    ------
    ValueError
        When start or end lies on the axis (radius 0): the arc has no defined direction there.

    >>> round(arc_sweep(np.zeros(3), np.array([0.0, 0, 1]), np.array([1.0, 0, 0]), np.array([0.0, 1, 0])), 6)
    1.570796
    >>> round(arc_sweep(np.zeros(3), np.array([0.0, 0, -1]), np.array([1.0, 0, 0]), np.array([0.0, 1, 0])), 6)
    4.712389
    """
    centre, normal, start, end = (np.asarray(v, dtype=np.float64) for v in (centre, normal, start, end))
    _, radial_start = _plane_parts(centre, normal, start)
    _, radial_end = _plane_parts(centre, normal, end)
    if np.linalg.norm(radial_start) == 0.0 or np.linalg.norm(radial_end) == 0.0:
        raise ValueError("arc_sweep: start or end lies on the arc's axis (radius 0)")
    if np.linalg.norm(radial_end - radial_start) <= full_turn_tol:
        return 2.0 * math.pi
    angle = math.atan2(float(np.cross(radial_start, radial_end) @ normal), float(radial_start @ radial_end))
    return angle if angle > 0.0 else angle + 2.0 * math.pi


#: The most segments one arc may become (a radius of about 4 km at 0.002 mm, or thousands of turns: a typo,
#: not a part); the readers refuse an arc that needs more, naming its line.
MAX_ARC_SEGMENTS = 100_000


def arc_segment_count(radius: float, sweep: float, *, tolerance: float) -> int:
    """Fewest equal segments of an arc of ``radius`` (mm) and ``sweep`` (rad) with sagitta ≤ ``tolerance`` (mm).

    At least 1, and no segment spans more than a quarter turn (so a full turn has at least 4).

    >>> arc_segment_count(1.0, math.pi / 2, tolerance=0.1)
    2
    """
    if not (radius > 0.0 and tolerance > 0.0 and sweep > 0.0):
        raise ValueError(f"arc_segment_count: need radius, sweep, tolerance > 0, got {radius}, {sweep}, {tolerance}")
    # sagitta r·(1 − cos(Δ/2)) = 2r·sin²(Δ/4) ≤ tolerance; asin stays accurate where acos(1 − tiny)
    # loses digits (large radius, small tolerance). A quarter turn at most, so that the direction of
    # the arc stays clear from its points (this also covers a tolerance of more than the diameter).
    max_step = min(4.0 * math.asin(min(1.0, math.sqrt(tolerance / (2.0 * radius)))), 0.5 * math.pi)
    return max(1, math.ceil(sweep / max_step - 1e-12))


def arc_points_3d(centre: FloatArray, normal: FloatArray, start: FloatArray, end: FloatArray, *,
                  tolerance: float, turns: int = 0, full_turn_tol: float = 1e-9) -> FloatArray:
    """Points along an arc from ``start`` to ``end``, counter-clockwise about ``normal``.

    Parameters
    ----------
    centre : (3,) float — mm, any point on the arc's axis
    normal : (3,) float — the axis direction (normalized here); the arc turns counter-clockwise
        about it (right-hand rule); pass ``-normal`` for a clockwise arc
    start, end : (3,) float — mm; neither on the axis
    tolerance : float — mm, > 0, largest chordal error (sagitta) of a segment
    turns : int — ≥ 0, extra full turns before reaching ``end`` (G2/G3 ``P`` − 1)
    full_turn_tol : float — mm, see :func:`arc_sweep` (end = start is a full turn)

    Returns
    -------
    points : (n + 1, 3) float — mm; ``points[0]`` is ``start`` and ``points[-1]`` is ``end``,
        exactly (bit for bit), with n ≥ 1 segments between them

    Raises
    ------
    ValueError
        On a zero normal, a start or end on the axis, a tolerance ≤ 0 or negative ``turns``.

    >>> arc_points_3d(np.zeros(3), np.array([0.0, 0, 1]), np.array([1.0, 0, 0]), np.array([0.0, 1, 0]),
    ...               tolerance=0.1).round(6).tolist()
    [[1.0, 0.0, 0.0], [0.707107, 0.707107, 0.0], [0.0, 1.0, 0.0]]
    """
    centre, normal, start, end = (np.asarray(v, dtype=np.float64).reshape(3) for v in (centre, normal, start, end))
    length = float(np.linalg.norm(normal))
    if not (length > 0.0 and math.isfinite(length)):
        raise ValueError(f"arc_points_3d: the normal must be a finite non-zero vector, got {normal.tolist()}")
    if turns < 0:
        raise ValueError(f"arc_points_3d: turns must be ≥ 0, got {turns}")
    normal = normal / length
    sweep = arc_sweep(centre, normal, start, end, full_turn_tol=full_turn_tol) + 2.0 * math.pi * turns
    height_start, radial_start = _plane_parts(centre, normal, start)
    height_end, radial_end = _plane_parts(centre, normal, end)
    radius_start = float(np.linalg.norm(radial_start))
    radius_end = float(np.linalg.norm(radial_end))
    count = arc_segment_count(max(radius_start, radius_end), sweep, tolerance=tolerance)
    u = radial_start / radius_start
    v = np.cross(normal, u)
    t = np.linspace(0.0, 1.0, count + 1)
    angle = t * sweep
    radius = radius_start + (radius_end - radius_start) * t
    height = height_start + (height_end - height_start) * t
    points = (centre + height[:, None] * normal
              + (radius * np.cos(angle))[:, None] * u + (radius * np.sin(angle))[:, None] * v)
    points[0] = start
    points[-1] = end
    return points
