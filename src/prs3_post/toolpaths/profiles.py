"""Profiles: square and round contours milled into a face, in depth passes.

Geometry, in face coordinates (u, v, w), w = outward normal:

* The *outline* is the shape as drawn: a square of side ``size`` (optionally with round corners of
  ``corner_radius`` and turned by ``rotation`` rad counter-clockwise about its centre) or a circle
  of ``diameter``, centred at ``center_uv``.
* The *tool-centre contour* is the outline itself (side ON), offset outward by the tool radius r
  (OUTSIDE: the corner radius grows by r, so a sharp square gets corners of radius r) or inward by r
  (INSIDE: the corner radius shrinks by r, so a square's inside corners must have a radius ≥ r).
* Arcs (corners, circles) are split into equal steps Δ with sagitta r(1 − cos(Δ/2)) ≤ ``tolerance``;
  straight sides are single segments. The contour is closed and starts at the middle of the square's
  +u side (before rotation) or at the circle's +u point.

Direction, with the spindle turning clockwise (M3) seen from the spindle: seen from +w looking down
at the face, (u, v) is right-handed, so *clockwise* is the negative orientation (negative signed
area). Climb milling (the tooth enters the material at full chip thickness and leaves thin) runs an
outside contour (OUTSIDE, and ON, which is treated as outside) clockwise and an inside contour
(INSIDE) counter-clockwise; conventional milling runs the other way round.

Passes: depths d_k = min(k·step_down, depth), k = 1 .. ceil(depth/step_down). The tool rapids to the
retract height above the contour start, then to the clearance height, feeds (``plunge_feed``) down
to the face (w = 0), and for each pass enters (PLUNGE: straight down at the current point; RAMP:
down the contour) and runs one full closed lap at w = −d_k (``feed``). With RAMP, each lap starts
where its ramp ended, and the feature ends there too. After the last lap: RAPID up to clearance,
then to retract.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, replace
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from prs3_post.core.errors import FeatureError
from prs3_post.core.toolpath import Toolpath
from prs3_post.core.types import FloatArray
from prs3_post.part.face import Face
from prs3_post.toolpaths.arcs import arc_points_3d
from prs3_post.toolpaths.common import (
    MIN_TOLERANCE,
    Cutting,
    ToolpathBuilder,
    approach,
    check_fits,
    check_heights,
    depart,
    end_program,
    format_uv,
    pass_depths,
    require_nonnegative,
    require_positive,
    require_tolerance,
    start_program,
    swept_region,
)
from prs3_post.toolpaths.fitting import profile_advice

if TYPE_CHECKING:
    import shapely

__all__ = [
    "Direction",
    "Entry",
    "ProfileParams",
    "RoundShape",
    "Shape",
    "Side",
    "SquareShape",
    "arc_points",
    "plan_profile",
    "tool_center_contour",
]

class Side(enum.Enum):
    """Where the tool runs relative to the outline."""

    ON = "on"
    """The tool centre follows the outline: a groove of the tool's width centred on it."""
    INSIDE = "inside"
    """The tool's edge follows the outline from inside: cuts a pocket wall / a hole of that shape."""
    OUTSIDE = "outside"
    """The tool's edge follows the outline from outside: leaves a boss of that shape standing."""


class Direction(enum.Enum):
    """Milling direction with a clockwise (M3) spindle."""

    CLIMB = "climb"
    """Down-milling: clockwise around outside contours, counter-clockwise inside (seen from the spindle)."""
    CONVENTIONAL = "conventional"
    """Up-milling: counter-clockwise around outside contours, clockwise inside (seen from the spindle)."""


class Entry(enum.Enum):
    """How the tool gets down to each pass depth."""

    PLUNGE = "plunge"
    """Straight down along the tool axis at the contour start, at the plunge feed (needs a centre-cutting tool)."""
    RAMP = "ramp"
    """Down along the contour at ``ramp_angle``, at the plunge feed (gentler on the tool)."""


@dataclass(frozen=True, slots=True)
class SquareShape:
    """A square outline in the face plane.

    Attributes
    ----------
    size : float — mm, > 0, side length (``--size``)
    corner_radius : float — mm, 0 ≤ corner_radius ≤ size/2 (``--corner-radius``); 0 = sharp corners
    rotation : float — rad, counter-clockwise about the centre, from +u (``--rotation``)

    Raises
    ------
    FeatureError
        ``--size must be > 0 mm (got 0)`` and the like.
    """

    size: float
    corner_radius: float = 0.0
    rotation: float = 0.0

    def __post_init__(self) -> None:
        require_positive("size", self.size, "mm")
        require_nonnegative("corner_radius", self.corner_radius, "mm")
        if self.corner_radius > 0.5 * self.size:
            raise FeatureError(
                f"{{corner_radius}} must be ≤ half the {{size}} (got {{corner_radius}} {self.corner_radius:.3f} mm "
                f"> {0.5 * self.size:.3f} mm)"
            )
        if not math.isfinite(self.rotation):
            raise FeatureError(f"{{rotation}} must be a finite angle (got {self.rotation:g})")

    def describe(self) -> str:
        """``square 40.000 mm``."""
        return f"square {self.size:.3f} mm"


@dataclass(frozen=True, slots=True)
class RoundShape:
    """A circular outline in the face plane.

    Attributes
    ----------
    diameter : float — mm, > 0 (``--diameter``)

    Raises
    ------
    FeatureError
        ``--diameter must be > 0 mm (got 0)``.
    """

    diameter: float

    def __post_init__(self) -> None:
        require_positive("diameter", self.diameter, "mm")

    def describe(self) -> str:
        """``round Ø30.000 mm``."""
        return f"round Ø{self.diameter:.3f} mm"


Shape = SquareShape | RoundShape


@dataclass(frozen=True, slots=True, kw_only=True)
class ProfileParams:
    """How to mill a profile (keyword-only; heights in mm along the face normal w).

    Attributes
    ----------
    side : Side — (``--side``)
    depth : float — mm, > 0, final depth below the face (``--depth``)
    step_down : float — mm, > 0, depth per pass (``--step-down``)
    direction : Direction — (``--direction``)
    entry : Entry — (``--entry``)
    ramp_angle : float — rad, 0 < angle < π/2, descent angle of a RAMP entry (``--ramp-angle``,
        given in degrees on the command line); default 3°
    clearance : float — mm, > 0, above the face, where rapids stop (``--clearance``)
    retract : float — mm, ≥ clearance, safe height before and after the feature (``--retract``)

    Raises
    ------
    FeatureError
        On a value out of range, naming its key: ``{step_down} must be > 0 mm (got 0)``.
    """

    side: Side
    depth: float
    step_down: float
    direction: Direction
    entry: Entry
    ramp_angle: float = math.radians(3.0)
    clearance: float
    retract: float

    def __post_init__(self) -> None:
        require_positive("depth", self.depth, "mm")
        require_positive("step_down", self.step_down, "mm")
        if not (math.isfinite(self.ramp_angle) and 0.0 < self.ramp_angle < 0.5 * math.pi):
            raise FeatureError(f"{{ramp_angle}} must be > 0° and < 90° (got {math.degrees(self.ramp_angle):g}°)")
        check_heights(self.clearance, self.retract)


# --------------------------------------------------------------------------------------------
# Contours
# --------------------------------------------------------------------------------------------
def arc_points(center_uv: FloatArray, radius: float, start: float, sweep: float, *, tolerance: float) -> FloatArray:
    """Points on a circular arc in the (u, v) plane, fine enough that every chord's sagitta ≤ ``tolerance``.

    The 2D case of :func:`prs3_post.toolpaths.arcs.arc_points_3d` (normal +w, counter-clockwise), which
    chooses the points: the fewest equal steps with sagitta ≤ tolerance, at least 4 for a full circle.

    Parameters
    ----------
    center_uv : (2,) float — mm
    radius : float — mm, > 0
    start : float — rad, angle of the first point from +u
    sweep : float — rad, > 0 counter-clockwise, at most 2π (2π: a full circle)
    tolerance : float — mm, > 0, largest chordal error

    Returns
    -------
    points : (n + 1, 2) float — mm, first at ``start``, last at ``start + sweep``

    >>> arc_points(np.zeros(2), 1.0, 0.0, math.pi / 2, tolerance=0.1).round(6).tolist()
    [[1.0, 0.0], [0.707107, 0.707107], [0.0, 1.0]]
    """
    centre = np.array([center_uv[0], center_uv[1], 0.0], dtype=np.float64)
    first = centre + radius * np.array([math.cos(start), math.sin(start), 0.0])
    last = first if sweep >= 2.0 * math.pi - 1e-12 else (
        centre + radius * np.array([math.cos(start + sweep), math.sin(start + sweep), 0.0]))
    return arc_points_3d(centre, _W, first, last, tolerance=tolerance)[:, :2]


#: mm, a corner radius below this is a sharp corner: its arc would be lost in the rounding of its centre
#: (a radius of 1e-54 mm puts the arc's start on its centre).
MIN_CORNER_MM = 1e-9
#: The face normal in face coordinates (u, v, w): the axis the contour's arcs turn about.
_W = np.array([0.0, 0.0, 1.0])


def _drop_repeats(points: FloatArray) -> FloatArray:
    """Remove points equal to their predecessor (zero-length sides of a square that is a circle)."""
    keep = np.ones(len(points), dtype=bool)
    keep[1:] = np.any(points[1:] != points[:-1], axis=1)
    return points[keep]


def _square_contour(half: float, corner: float, *, tolerance: float) -> FloatArray:
    """Counter-clockwise closed contour of a square centred at 0, unrotated, from (half, 0).

    ``half`` = half the side (mm), ``corner`` = corner radius (mm, 0 = sharp).
    """
    if corner < MIN_CORNER_MM:                         # below float resolution at the centres: a sharp corner
        corner = 0.0
    inner = half - corner                              # corner-arc centres at (±inner, ±inner)
    signs = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
    pieces = [np.array([[half, 0.0]])]
    for quadrant, sign in enumerate(signs):            # 4 corners; the sides join them straight
        if corner > 0:
            arc = arc_points(inner * sign, corner, quadrant * 0.5 * math.pi, 0.5 * math.pi, tolerance=tolerance)
            # exact ends: cos(π/2) is 6e-17, and the sides between corners must stay exactly straight
            arc[0] = inner * sign + corner * np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])[quadrant]
            arc[-1] = inner * sign + corner * np.array([[0.0, 1.0], [-1.0, 0.0], [0.0, -1.0], [1.0, 0.0]])[quadrant]
            pieces.append(arc)
        else:
            pieces.append((half * sign)[None, :])
    pieces.append(np.array([[half, 0.0]]))
    return _drop_repeats(np.concatenate(pieces))


def tool_center_contour(
    center_uv: FloatArray,
    shape: Shape,
    side: Side,
    direction: Direction,
    tool_diameter: float,
    *,
    tolerance: float,
) -> FloatArray:
    """The closed path of the tool centre in face (u, v), in cutting order.

    Parameters
    ----------
    center_uv : (2,) float — mm, centre of the shape in face (u, v)
    shape : SquareShape | RoundShape
    side : Side
    direction : Direction — with an M3 spindle (see the module docstring)
    tool_diameter : float — mm, > 0
    tolerance : float — mm, > 0, largest chordal error of the arcs

    Returns
    -------
    contour : (M + 1, 2) float — mm, ``contour[0] == contour[-1]``: the middle of the square's +u side
        (before rotation) or the circle's +u point; no zero-length segments

    Raises
    ------
    FeatureError
        For INSIDE when the tool does not fit in the shape, or a square's corner radius is smaller
        than the tool radius.
    """
    require_tolerance(tolerance)
    if not isinstance(shape, (SquareShape, RoundShape)):
        raise TypeError(f"tool_center_contour: shape must be SquareShape or RoundShape, got {type(shape).__name__}")
    radius = 0.5 * tool_diameter
    offset = {Side.ON: 0.0, Side.OUTSIDE: radius, Side.INSIDE: -radius}[side]
    if side is Side.INSIDE:
        if isinstance(shape, SquareShape):
            if shape.size <= tool_diameter:
                raise FeatureError(
                    f"{{side}} inside: the tool Ø{tool_diameter:.3f} mm does not fit inside the {shape.describe()} "
                    f"(use a tool smaller than Ø{shape.size:.3f})", key="side"
                )
            if shape.corner_radius < radius:
                raise FeatureError(
                    f"{{side}} inside: corner radius {shape.corner_radius:.3f} mm is smaller than the tool radius "
                    f"{radius:.3f} mm (use {{corner_radius}} ≥ {radius:.3f} or a smaller tool)", key="side"
                )
        elif shape.diameter <= tool_diameter:
            raise FeatureError(
                f"{{side}} inside: the tool Ø{tool_diameter:.3f} mm does not fit inside the {shape.describe()} "
                f"(use a tool smaller than Ø{shape.diameter:.3f})", key="side"
            )

    if isinstance(shape, SquareShape):
        local = _square_contour(0.5 * shape.size + offset, shape.corner_radius + offset, tolerance=tolerance)
        if shape.rotation != 0.0:                                        # keep unrotated sides exactly straight
            cos_r, sin_r = math.cos(shape.rotation), math.sin(shape.rotation)
            local = local @ np.array([[cos_r, sin_r], [-sin_r, cos_r]])   # rows rotated CCW by rotation
    else:
        local = arc_points(np.zeros(2), 0.5 * shape.diameter + offset, 0.0, 2.0 * math.pi, tolerance=tolerance)
        local[-1] = local[0]                                             # closed exactly
    contour = np.asarray(center_uv, dtype=np.float64) + local
    contour[-1] = contour[0]

    outside = side is not Side.INSIDE                                    # ON counts as outside
    clockwise = outside == (direction is Direction.CLIMB)
    return contour[::-1].copy() if clockwise else contour                # built counter-clockwise


# --------------------------------------------------------------------------------------------
# Walking along the contour
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class _Lap:
    """A closed contour, unrolled twice so that walks may wrap past its start.

    No two neighbouring vertices are closer than ``resolution`` (the program could not show the
    move between them), and a walk's vertices stay that far from where it starts and ends.
    """

    points: FloatArray        # (M + 1, 2) mm, closed
    arc_length: FloatArray    # (M + 1,) mm, cumulative along points, 0 … length
    unrolled: FloatArray      # (2M + 1, 2) mm, points of two laps
    unrolled_s: FloatArray    # (2M + 1,) mm, 0 … 2·length
    length: float             # mm, one lap
    resolution: float         # mm, the program's length resolution

    @staticmethod
    def of(points: FloatArray, resolution: float) -> _Lap:
        step = np.linalg.norm(np.diff(points, axis=0), axis=1)
        # a vertex reached by a step shorter than the resolution goes (and so does the last one
        # before the closing point when that step is short); the contour moves by less than that
        short = np.concatenate([[False], step[:-1] < resolution, [False]])
        short[-2] |= len(points) > 2 and step[-1] < resolution
        points = points[~short]
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
        length = float(s[-1])
        return _Lap(
            points=points,
            arc_length=s,
            unrolled=np.concatenate([points[:-1], points]),
            unrolled_s=np.concatenate([s[:-1], length + s]),
            length=length,
            resolution=resolution,
        )

    def point_at(self, s: float) -> FloatArray:
        """(2,) mm, the contour point at arc length ``s`` in [0, length]."""
        return np.array([
            np.interp(s, self.arc_length, self.points[:, 0]), np.interp(s, self.arc_length, self.points[:, 1])
        ])

    def vertices_between(self, s_from: float, s_to: float) -> tuple[FloatArray, FloatArray]:
        """Contour vertices strictly between arc lengths ``s_from`` < ``s_to`` ≤ s_from + length.

        Returns (points (n, 2) mm, their arc length (n,) mm on the unrolled contour).
        """
        # a vertex closer than the resolution to either end would make a move the program cannot show
        near = self.resolution
        inside = (self.unrolled_s > s_from + near) & (self.unrolled_s < s_to - near)
        return self.unrolled[inside], self.unrolled_s[inside]


def plan_profile(
    face: Face,
    center_uv: FloatArray,
    shape: Shape,
    params: ProfileParams,
    cutting: Cutting,
    *,
    tolerance: float,
    resolution: float = MIN_TOLERANCE,
) -> Toolpath:
    """Mill a square or round profile into ``face`` in depth passes (see the module docstring).

    Parameters
    ----------
    face : Face — frame u, v, w; w = outward normal
    center_uv : (2,) float — mm, centre of the shape in face (u, v)
    shape : SquareShape | RoundShape
    params : ProfileParams
    cutting : Cutting
    tolerance : float — mm, > 0, largest chordal error of the arcs
    resolution : float — mm, > 0, the program's length resolution: depth passes and contour points
        closer than it are merged (see :func:`~prs3_post.toolpaths.common.pass_depths`)

    Returns
    -------
    Toolpath — PART coordinates; axis = ``face.normal`` on every row; FEED rows at ``plunge_feed``
    (down to the face, plunges, ramps) or ``feed`` (laps), 0 on RAPID rows; every lap row at
    w = −d_k exactly; ``source_labels`` like ``square approach``, ``square pass 2/3 ramp``,
    ``square pass 2/3 lap``, ``square retract``; events: program comment, tool change, spindle on,
    coolant, a comment per pass (and one when a ramp has to be steeper than ``ramp_angle`` because
    one lap is too short), coolant off and spindle off at the end.

    Raises
    ------
    FeatureError
        On a centre that is not a finite (2,) point, a shape the tool cannot cut from inside (see
        :func:`tool_center_contour`), or a swept area that does not fit on the face (see
        :func:`~prs3_post.toolpaths.common.check_fits`).
    """
    center = np.asarray(center_uv, dtype=np.float64)
    if center.shape != (2,) or not np.isfinite(center).all():
        raise FeatureError(f"profile centre: expected a finite face point (u, v) in mm, got {center_uv!r}")
    contour = tool_center_contour(
        center, shape, params.side, params.direction, cutting.tool_diameter, tolerance=tolerance
    )
    what = f"{shape.describe()} at {format_uv(center)} with tool Ø{cutting.tool_diameter:.3f}"

    def region_at(at: FloatArray, size: float) -> shapely.Geometry:
        resized = replace(shape, size=size) if isinstance(shape, SquareShape) else replace(shape, diameter=size)
        path = tool_center_contour(at, resized, params.side, params.direction, cutting.tool_diameter,
                                   tolerance=tolerance)
        return swept_region(path, cutting.tool_radius)

    size, key = (shape.size, "size") if isinstance(shape, SquareShape) else (shape.diameter, "diameter")
    check_fits(face, swept_region(contour, cutting.tool_radius), what,
               advice=partial(profile_advice, face, center, size, key, region_at))

    name = "square" if isinstance(shape, SquareShape) else "round"
    lap = _Lap.of(contour, resolution)
    if len(lap.points) < 4:                           # fewer than 3 corners the program can tell apart
        travel = float(np.sum(np.linalg.norm(np.diff(contour, axis=0), axis=1)))
        raise FeatureError(f"{what}: the tool centre goes {travel:.4f} mm around, too little for the "
                           f"program's resolution of {resolution:g} mm (a larger shape, or a hole?)")
    depths = pass_depths(params.depth, params.step_down, resolution=resolution)
    passes = len(depths)
    clockwise = float(np.sum(contour[:-1, 0] * contour[1:, 1] - contour[1:, 0] * contour[:-1, 1])) < 0
    builder = ToolpathBuilder(face)
    start_program(
        builder,
        cutting,
        f"{what} on face {face.index}: {params.side.value}, {params.direction.value} "
        f"({'clockwise' if clockwise else 'counter-clockwise'}), {params.entry.value} entry, "
        f"depth {params.depth:.3f} mm in {passes} pass{'es' if passes > 1 else ''}",
    )

    start = contour[0]
    approach(builder, start, params.clearance, params.retract, f"{name} approach")
    builder.step(f"{name} down to face")
    builder.feed(np.array([start[0], start[1], 0.0]), cutting.plunge_feed)   # down to the face

    s_here = 0.0                                      # arc length of the tool's place on the contour
    here = start
    previous_depth = 0.0
    for k, pass_depth in enumerate(depths, start=1):
        depth = float(pass_depth)
        tag = f"{name} pass {k}/{passes}"
        builder.comment(f"{tag} at depth {depth:.3f} mm")
        if params.entry is Entry.PLUNGE:
            builder.step(f"{tag} plunge")
            builder.feed(np.array([here[0], here[1], -depth]), cutting.plunge_feed)
        else:
            drop = depth - previous_depth
            ramp_length = drop / math.tan(params.ramp_angle)
            if ramp_length > lap.length:              # one lap is too short: ramp steeper over one lap
                ramp_length = lap.length
                builder.comment(
                    f"{tag}: ramp steepened to {math.degrees(math.atan2(drop, ramp_length)):.3f}° "
                    f"(one lap is {lap.length:.3f} mm, {math.degrees(params.ramp_angle):.3f}° needs "
                    f"{drop / math.tan(params.ramp_angle):.3f} mm)"
                )
            s_end = s_here + ramp_length
            middle, s_middle = lap.vertices_between(s_here, s_end)
            w_middle = -previous_depth - drop * (s_middle - s_here) / ramp_length
            s_here = s_end - lap.length if s_end >= lap.length else s_end
            here = lap.point_at(s_here)
            builder.step(f"{tag} ramp")
            builder.feed(
                np.concatenate([np.column_stack([middle, w_middle]), [[here[0], here[1], -depth]]]),
                cutting.plunge_feed,
            )
        # one full lap at depth, from where the entry left the tool back to the same point
        around, _ = lap.vertices_between(s_here, s_here + lap.length)
        lap_uv = np.concatenate([around, here[None, :]])
        builder.step(f"{tag} lap")
        builder.feed(np.column_stack([lap_uv, np.full(len(lap_uv), -depth)]), cutting.feed)
        previous_depth = depth

    depart(builder, here, params.clearance, params.retract, f"{name} retract")
    end_program(builder, cutting)
    return builder.build()
