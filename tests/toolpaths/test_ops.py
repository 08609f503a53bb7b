"""Machining operations (ops/): holes and profiles on the paper's inclined wedge face.

The face is built by hand: the top of the paper's wedge, z = 300 − x/2 over x ∈ [−50, 50],
y ∈ [150, 250], normal (sin β, 0, cos β) with β = atan(1/2) = 26.5651°. Its centroid is
(0, 200, 300); face u = (cos β, 0, −sin β) (down-slope), v = (0, 1, 0); the outline is
±50/cos β = ±55.9017 in u and ±50 in v.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from numpy.testing import assert_allclose, assert_array_equal

from prs3_post.cli.options import error_text
from prs3_post.core.defaults import DEFAULT_TOLERANCE
from prs3_post.core.errors import FeatureError
from prs3_post.core.toolpath import EventKind, MoveKind, Toolpath
from prs3_post.part.face import Face, frame_from_normal
from prs3_post.toolpaths import (
    Coolant,
    Cutting,
    Direction,
    Entry,
    HoleParams,
    ProfileParams,
    RoundShape,
    Side,
    SquareShape,
    check_fits,
    plan_holes,
    plan_profile,
    tool_center_contour,
)
from prs3_post.toolpaths.common import pass_depths, swept_region

BETA = math.atan(0.5)                              # 26.5651°
PAPER_2A_PART = np.array([18.9736, 221.2132, 290.5135])   # DESIGN.md: drilling point, part coordinates
PAPER_2B_PART = np.array([13.4164, 200.0, 293.2921])      # DESIGN.md: square-profile point
PAPER_AXIS = np.array([0.447214, 0.0, 0.894427])


def make_face(boundary: shapely.Polygon | None = None) -> Face:
    normal = np.array([math.sin(BETA), 0.0, math.cos(BETA)])
    u, v = frame_from_normal(normal)
    outline = shapely.box(-55.9017, -50.0, 55.9017, 50.0) if boundary is None else boundary
    return Face(
        index=0,
        area=float(outline.area),
        normal=normal,
        origin=np.array([0.0, 200.0, 300.0]),
        u=u,
        v=v,
        inclination=BETA,
        boundary=outline,
        triangles=np.zeros(0, dtype=np.int64),
        width=float(2.0 * shapely.maximum_inscribed_circle(outline).length),
        curved=False,
    )


FACE = make_face()
CUT = Cutting(
    tool_diameter=6.0, feed=600.0, plunge_feed=200.0, spindle_rpm=8000.0, coolant=Coolant.FLOOD, tool_number=3
)


def hole_params(**changes: float) -> HoleParams:
    values = dict(depth=10.0, peck=3.0, dwell=0.5, clearance=2.0, retract=10.0)
    values.update(changes)
    return HoleParams(**values)


def profile_params(**changes: object) -> ProfileParams:
    values: dict[str, object] = dict(
        side=Side.ON, depth=5.0, step_down=2.0, direction=Direction.CLIMB, entry=Entry.PLUNGE, clearance=2.0,
        retract=10.0
    )
    values.update(changes)
    return ProfileParams(**values)  # type: ignore[arg-type]


def face_uvw(path: Toolpath) -> np.ndarray:
    return FACE.from_part(path.tip)


def labels(path: Toolpath) -> list[str]:
    return [path.describe(i) for i in range(len(path))]


def signed_area(points_uv: np.ndarray) -> float:
    u, v = points_uv[:, 0], points_uv[:, 1]
    return 0.5 * float(np.sum(u[:-1] * v[1:] - u[1:] * v[:-1]))


def assert_common_rows(path: Toolpath) -> None:
    """Axis = face normal on every row, feed 0 exactly on rapids and > 0 on feeds, frozen arrays."""
    n = len(path)
    assert path.tip.shape == (n, 3) and path.axis.shape == (n, 3)
    assert_allclose(path.axis, np.tile(FACE.normal, (n, 1)), rtol=0, atol=0)
    assert_allclose(path.axis[0], PAPER_AXIS, atol=1e-6)
    rapid = path.kind == MoveKind.RAPID
    assert_array_equal(path.feed[rapid], 0.0)
    assert np.all(path.feed[~rapid] > 0)
    assert not path.tip.flags.writeable
    assert path.source.max() < len(path.source_labels)


# ------------------------------------------------------------------------------------------------
# The face itself
# ------------------------------------------------------------------------------------------------
def test_paper_points_lie_on_the_face_at_nice_face_coordinates() -> None:
    uvw = FACE.from_part(np.stack([PAPER_2A_PART, PAPER_2B_PART]))
    # 2a is 30 mm from the centroid at 45°, 2b is 15 mm down-slope; both on the face within 3e-4 mm
    assert_allclose(uvw[:, :2], [[21.2132, 21.2132], [15.0, 0.0]], atol=3e-4)
    assert_allclose(uvw[:, 2], 0.0, atol=3e-4)


def test_pass_depths_guard_floating_error() -> None:
    assert_allclose(pass_depths(10.0, 3.0), [3.0, 6.0, 9.0, 10.0], rtol=0, atol=0)
    assert_allclose(pass_depths(0.9, 0.3), [0.3, 0.6, 0.9], rtol=0, atol=1e-15)   # 0.9/0.3 = 3.0000000000000004
    assert_allclose(pass_depths(0.7, 0.1)[-1], 0.7, rtol=0, atol=0)
    assert len(pass_depths(0.7, 0.1)) == 7
    assert_allclose(pass_depths(2.0, 5.0), [2.0], rtol=0, atol=0)


# ------------------------------------------------------------------------------------------------
# Holes
# ------------------------------------------------------------------------------------------------
def test_peck_sequence_for_a_10mm_hole_with_3mm_pecks() -> None:
    center = np.array([[5.0, -7.0]])
    path = plan_holes(FACE, center, hole_params(), CUT)
    uvw = face_uvw(path)
    # retract, clearance, peck 3; out, back to 0.5 above 3, peck 6; out, 5.5, 9; out, 8.5, 10; out, retract
    expected_w = [10.0, 2.0, -3.0, 2.0, -2.5, -6.0, 2.0, -5.5, -9.0, 2.0, -8.5, -10.0, 2.0, 10.0]
    assert_allclose(uvw[:, 2], expected_w, rtol=0, atol=1e-12)
    assert_allclose(uvw[:, :2], np.tile(center, (14, 1)), rtol=0, atol=1e-12)
    R, F = int(MoveKind.RAPID), int(MoveKind.FEED)
    assert path.kind.tolist() == [R, R, F, R, R, F, R, R, F, R, R, F, R, R]
    assert_allclose(path.feed[path.kind == F], 200.0, rtol=0, atol=0)   # plunge feed
    assert labels(path) == [
        "hole 1 approach", "hole 1 approach",
        "hole 1 peck 1 feed",
        "hole 1 peck 1 clear", "hole 1 peck 2 reapproach", "hole 1 peck 2 feed",
        "hole 1 peck 2 clear", "hole 1 peck 3 reapproach", "hole 1 peck 3 feed",
        "hole 1 peck 3 clear", "hole 1 peck 4 reapproach", "hole 1 peck 4 feed",
        "hole 1 retract", "hole 1 retract",
    ]
    assert_common_rows(path)


def test_hole_events_spindle_coolant_dwell_and_end() -> None:
    path = plan_holes(FACE, np.array([[5.0, -7.0]]), hole_params(), CUT)
    events = [(e.before, e.kind, e.value, e.text) for e in path.events]
    assert events == [
        (0, EventKind.COMMENT, 0.0, "drill 1 hole Ø6.000 on face 0: depth 10.000 mm, pecks of 3.000 mm, dwell 0.5 s"),
        (0, EventKind.TOOL_CHANGE, 3.0, "Ø6.000 mm tool"),
        (0, EventKind.SPINDLE_ON, 8000.0, ""),
        (0, EventKind.COOLANT_ON, 0.0, "flood"),
        (0, EventKind.COMMENT, 0.0, "hole 1/1 at (u 5.000, v -7.000)"),
        (12, EventKind.DWELL, 0.5, ""),             # after the last feed (row 11), before the way out
        (14, EventKind.COOLANT_OFF, 0.0, ""),
        (14, EventKind.SPINDLE_OFF, 0.0, ""),
    ]


def test_hole_without_pecking_dwell_or_coolant() -> None:
    dry = Cutting(tool_diameter=6.0, feed=600.0, plunge_feed=150.0, spindle_rpm=5000.0, coolant=Coolant.OFF,
                  tool_number=1)
    path = plan_holes(FACE, np.array([[0.0, 0.0]]), hole_params(peck=0.0, dwell=0.0), dry)
    assert_allclose(face_uvw(path)[:, 2], [10.0, 2.0, -10.0, 2.0, 10.0], rtol=0, atol=1e-12)
    assert labels(path) == ["hole 1 approach", "hole 1 approach", "hole 1 feed", "hole 1 retract", "hole 1 retract"]
    kinds = [e.kind for e in path.events]
    assert EventKind.DWELL not in kinds and EventKind.COOLANT_ON not in kinds and EventKind.COOLANT_OFF not in kinds
    assert kinds[-1] is EventKind.SPINDLE_OFF and path.events[-1].before == 5
    assert_allclose(path.feed[path.kind == MoveKind.FEED], 150.0, rtol=0, atol=0)


def test_mist_coolant_event_text() -> None:
    mist = Cutting(tool_diameter=6.0, feed=600.0, plunge_feed=150.0, spindle_rpm=5000.0, coolant=Coolant.MIST,
                   tool_number=1)
    path = plan_holes(FACE, np.array([[0.0, 0.0]]), hole_params(), mist)
    assert [e.text for e in path.events if e.kind is EventKind.COOLANT_ON] == ["mist"]


def test_hole_at_the_papers_drilling_point() -> None:
    center_uv = FACE.from_part(PAPER_2A_PART)[:, :2]
    path = plan_holes(FACE, center_uv, hole_params(peck=0.0), CUT)
    first_feed = int(np.argmax(path.kind == MoveKind.FEED))
    start, end = path.tip[first_feed - 1], path.tip[first_feed]
    # the feed starts at clearance straight above the paper's point, on the tool axis (the face normal)
    assert_allclose(start, PAPER_2A_PART + 2.0 * FACE.normal, atol=3e-4)
    assert_allclose(end, PAPER_2A_PART - 10.0 * FACE.normal, atol=3e-4)
    # and enters the face (w = 0) exactly at the hole's face point, which is the paper's point
    w_start, w_end = FACE.from_part(np.stack([start, end]))[:, 2]
    entry = start + (end - start) * (w_start / (w_start - w_end))
    assert_allclose(FACE.from_part(entry)[0], [*center_uv[0], 0.0], atol=1e-12)
    assert_allclose(entry, PAPER_2A_PART, atol=3e-4)
    assert_allclose(path.axis, np.tile(PAPER_AXIS, (len(path), 1)), atol=1e-6)


def test_holes_drilled_in_the_given_order_moving_at_retract_height() -> None:
    centers = np.array([[20.0, 10.0], [-20.0, 10.0], [0.0, -30.0]])
    path = plan_holes(FACE, centers, hole_params(peck=0.0, dwell=0.0), CUT)
    uvw = face_uvw(path)
    assert len(path) == 15
    assert_allclose(uvw[0::5, :2], centers, rtol=0, atol=1e-12)                 # each hole starts above it
    assert_allclose(uvw[0::5, 2], 10.0, rtol=0, atol=1e-12)                     # ... at the retract height
    assert_allclose(uvw[4::5, 2], 10.0, rtol=0, atol=1e-12)                     # and leaves at it
    assert labels(path)[5] == "hole 2 approach"
    comments = [e.text for e in path.events if e.kind is EventKind.COMMENT]
    assert comments[1:] == [
        "hole 1/3 at (u 20.000, v 10.000)", "hole 2/3 at (u -20.000, v 10.000)", "hole 3/3 at (u 0.000, v -30.000)"
    ]
    assert_common_rows(path)


def test_one_hole_at_the_edge_does_not_fit_and_says_by_how_much() -> None:
    # disc of radius 3 around u = 54 reaches u = 57; the face edge is at 55.9017: 1.0983 mm over
    with pytest.raises(FeatureError) as err:
        plan_holes(FACE, np.array([[0.0, 0.0], [54.0, 0.0]]), hole_params(), CUT)
    assert error_text(err.value) == (
        "hole 2 at (u 54.000, v 0.000) with tool Ø6.000: does not fit on face 0: overshoots its edge by 1.098 mm; "
        # issue 20 §3: what fits instead (the tool's room is 55.9017 - 3 = 52.9017 from the centre)
        "the largest tool that fits at (u 54.000, v 0.000) is Ø3.803 (--tool-diameter 3.803); Ø6.000 fits at "
        "(u 52.901, v 0.000), the nearest place where it does (--at 52.901,0)"
    )


def test_hole_near_a_hole_in_the_face() -> None:
    with_opening = make_face(
        shapely.box(-55.9017, -50.0, 55.9017, 50.0).difference(shapely.box(-35.0, -5.0, -25.0, 5.0))
    )
    with pytest.raises(FeatureError) as err:   # reaches u = -26.5: 1.5 mm into the opening that starts at -25
        plan_holes(with_opening, np.array([[-23.5, 0.0]]), hole_params(), CUT)
    assert error_text(err.value) == (
        "hole 1 at (u -23.500, v 0.000) with tool Ø6.000: does not fit on face 0: "
        "cuts 1.500 mm into the hole in the face at (u -30.000, v 0.000); the largest tool that fits at "
        "(u -23.500, v 0.000) is Ø2.999 (--tool-diameter 2.999); Ø6.000 fits at (u -21.999, v 0.000), the nearest "
        "place where it does (--at -21.999,0)"      # Ø3 and u -22 touch the opening: refused as such
    )
    with pytest.raises(FeatureError) as err:   # reaches u = -25 exactly
        plan_holes(with_opening, np.array([[-22.0, 0.0]]), hole_params(), CUT)
    assert error_text(err.value) == (
        "hole 1 at (u -22.000, v 0.000) with tool Ø6.000: does not fit on face 0: "
        "touches the hole in the face at (u -30.000, v 0.000); the largest tool that fits at (u -22.000, v 0.000) is "
        "Ø5.999 (--tool-diameter 5.999); Ø6.000 fits at (u -21.999, v 0.000), the nearest place where it does "
        "(--at -21.999,0)"
    )
    with pytest.raises(FeatureError) as err:   # a big tool swallows the whole opening: 5 mm (its half-width)
        plan_holes(with_opening, np.array([[-30.0, 0.0]]), hole_params(),
                   Cutting(30.0, 600.0, 200.0, 8000.0, Coolant.OFF, 1))
    assert error_text(err.value) == (
        "hole 1 at (u -30.000, v 0.000) with tool Ø30.000: does not fit on face 0: "
        "cuts 5.000 mm into the hole in the face at (u -30.000, v 0.000); Ø30.000 fits at (u -30.000, v -20.001), the "
        "nearest place where it does (--at -30,-20.001)"     # beside the opening (v -5 to 5), by 0.001 mm
    )
    plan_holes(with_opening, np.array([[-21.0, 0.0]]), hole_params(), CUT)   # 1 mm of material left: fits


def test_check_fits_far_outside_and_inside() -> None:
    check_fits(FACE, swept_region(np.array([[0.0, 0.0]]), 3.0), "x")
    with pytest.raises(FeatureError) as err:   # a disc of radius 1 centred 10 mm beyond the v edge: 11 mm
        check_fits(FACE, swept_region(np.array([[0.0, 60.0]]), 1.0), "probe")
    assert error_text(err.value) == "probe: does not fit on face 0: overshoots its edge by 11.000 mm"


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (dict(depth=0.0), "--depth must be > 0 mm (got 0)"),
        (dict(depth=-2.0), "--depth must be > 0 mm (got -2)"),
        (dict(depth=math.nan), "--depth must be > 0 mm (got nan)"),
        (dict(peck=-1.0), "--peck must be ≥ 0 mm (got -1)"),
        (dict(dwell=-0.5), "--dwell must be ≥ 0 s (got -0.5)"),
        (dict(clearance=0.0), "--clearance must be > 0 mm (got 0)"),
        (dict(retract=1.0), "--retract must be ≥ --clearance (got --retract 1.000 mm < --clearance 2.000 mm)"),
        (
            dict(peck=0.5),
            "--reapproach-gap must be < --peck when pecking (got --reapproach-gap 0.5 mm ≥ --peck 0.5 mm; "
            "use a smaller gap, a larger peck, or --peck 0 for no pecking)",
        ),
        (
            dict(peck=1e-9),                       # was printed as '--peck 0.000 mm'
            "--reapproach-gap must be < --peck when pecking (got --reapproach-gap 0.5 mm ≥ --peck 1e-09 mm; "
            "use a smaller gap, a larger peck, or --peck 0 for no pecking)",
        ),
        (dict(reapproach_gap=-0.1), "--reapproach-gap must be ≥ 0 mm (got -0.1)"),
    ],
)
def test_hole_params_refused(changes: dict[str, float], message: str) -> None:
    with pytest.raises(FeatureError) as err:
        hole_params(**changes)
    assert error_text(err.value) == message


@pytest.mark.parametrize(
    ("centers", "message"),
    [
        (np.zeros((0, 2)), "no hole positions given: nothing to drill (give at least one hole)"),
        (np.zeros(2), "hole positions: expected (K, 2) face (u, v) in mm, got shape (2,)"),
        (np.array([[0.0, 0.0], [1.0, math.inf]]), "hole 2: position (u 1.000, v inf) is not a finite number"),
    ],
)
def test_hole_positions_refused(centers: np.ndarray, message: str) -> None:
    with pytest.raises(FeatureError) as err:
        plan_holes(FACE, centers, hole_params(), CUT)
    assert error_text(err.value) == message


@pytest.mark.parametrize(
    ("centers", "message"),
    [
        (np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 0.0]]),
         "hole 3 at (u 0.000, v 0.000) is hole 1 at (u 0.000, v 0.000) again (closer than the program's resolution, "
         "0.001 mm): it would be drilled twice; give each position once (--at, --at-xyz)"),
        (np.array([[5.0, 5.0], [5.0007, 4.9995]]),         # 0.00086 mm apart: the same hole within 0.001 mm
         "hole 2 at (u 5.001, v 5.000) is hole 1 at (u 5.000, v 5.000) again (closer than the program's resolution, "
         "0.001 mm): it would be drilled twice; give each position once (--at, --at-xyz)"),
    ],
)
def test_the_same_hole_twice_is_refused(centers: np.ndarray, message: str) -> None:
    with pytest.raises(FeatureError) as err:
        plan_holes(FACE, centers, hole_params(), CUT, resolution=0.001)
    assert error_text(err.value) == message


def test_holes_one_output_unit_apart_are_two_holes() -> None:
    centers = np.array([[5.0, 5.0], [5.001, 5.0], [5.0, 5.001]])
    path = plan_holes(FACE, centers, hole_params(), CUT, resolution=0.001)
    assert [e.text for e in path.events if e.kind is EventKind.COMMENT][1:] == [
        "hole 1/3 at (u 5.000, v 5.000)", "hole 2/3 at (u 5.001, v 5.000)", "hole 3/3 at (u 5.000, v 5.001)"]


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (dict(tool_diameter=0.0), "--tool-diameter must be from 0.01 to 500 mm (got 0)"),
        (dict(tool_diameter=1e-9), "--tool-diameter must be from 0.01 to 500 mm (got 1e-09)"),
        (dict(tool_diameter=float("nan")), "--tool-diameter must be from 0.01 to 500 mm (got nan)"),
        (dict(feed=0.0), "--feed must be > 0 mm/min (got 0)"),
        (dict(feed=-100.0), "--feed must be > 0 mm/min (got -100)"),
        (dict(feed=math.inf), "--feed must be > 0 mm/min (got inf)"),
        (dict(plunge_feed=0.0), "--plunge-feed must be > 0 mm/min (got 0)"),
        (dict(spindle_rpm=0.0), "--spindle must be > 0 rpm (got 0)"),
        (dict(tool_number=0), "--tool-number must be an integer ≥ 1 (got 0)"),
        (dict(tool_number=1.5), "--tool-number must be an integer ≥ 1 (got 1.5)"),
    ],
)
def test_cutting_refused(changes: dict[str, float], message: str) -> None:
    values: dict[str, object] = dict(
        tool_diameter=6.0, feed=600.0, plunge_feed=200.0, spindle_rpm=8000.0, coolant=Coolant.FLOOD, tool_number=1
    )
    values.update(changes)
    with pytest.raises(FeatureError) as err:
        Cutting(**values)  # type: ignore[arg-type]
    assert error_text(err.value) == message


# ------------------------------------------------------------------------------------------------
# Profile contours
# ------------------------------------------------------------------------------------------------
def max_sagitta(points: np.ndarray, center: np.ndarray, radius: float) -> float:
    """Largest distance between each chord and the exact circle (at the chord's middle)."""
    middles = 0.5 * (points[1:] + points[:-1])
    return float(np.max(radius - np.linalg.norm(middles - center, axis=1)))


def test_round_contour_points_and_chordal_error() -> None:
    center = np.array([4.0, -3.0])
    contour = tool_center_contour(center, RoundShape(30.0), Side.ON, Direction.CONVENTIONAL, 6.0, tolerance=0.002)
    # step ≤ 2·acos(1 − 0.002/15) = 0.032660 rad: 2π/0.032660 = 192.38 → 193 segments
    assert contour.shape == (194, 2)
    assert_allclose(contour[0], [19.0, -3.0], rtol=0, atol=1e-12)             # the +u point
    assert_array_equal(contour[-1], contour[0])                                # closed exactly
    assert_allclose(np.linalg.norm(contour - center, axis=1), 15.0, rtol=0, atol=1e-12)
    sagitta = max_sagitta(contour, center, 15.0)
    assert 0.0019 < sagitta <= 0.002 + 1e-12                                   # just within, not wasteful
    steps = np.linalg.norm(np.diff(contour, axis=0), axis=1)
    assert_allclose(steps, steps[0], rtol=0, atol=1e-12)                       # evenly spaced
    assert signed_area(contour) > 0                                            # conventional outside: CCW


@pytest.mark.parametrize(("side", "radius", "segments"), [(Side.OUTSIDE, 18.0, 211), (Side.INSIDE, 12.0, 173)])
def test_round_contour_offset_by_the_tool_radius(side: Side, radius: float, segments: int) -> None:
    contour = tool_center_contour(np.zeros(2), RoundShape(30.0), side, Direction.CLIMB, 6.0, tolerance=0.002)
    assert contour.shape == (segments + 1, 2)
    assert_allclose(np.linalg.norm(contour, axis=1), radius, rtol=0, atol=1e-12)
    assert max_sagitta(contour, np.zeros(2), radius) <= 0.002 + 1e-12


def test_rounded_square_outside_contour() -> None:
    # square 40 with 2 mm corners, tool Ø6 outside: tool centre on a 46 mm square with 5 mm corners,
    # corner centres at (±18, ±18); 28 steps per quarter (1.5708 / (2·acos(1 − 0.002/5)) = 27.77)
    center = np.array([10.0, 5.0])
    contour = tool_center_contour(
        center, SquareShape(40.0, corner_radius=2.0), Side.OUTSIDE, Direction.CONVENTIONAL, 6.0
    , tolerance=DEFAULT_TOLERANCE)
    assert contour.shape == (1 + 4 * 29 + 1, 2)
    assert_allclose(contour[0], center + np.array([23.0, 0.0]), rtol=0, atol=1e-12)
    assert_array_equal(contour[-1], contour[0])
    local = contour - center
    corner_centers = 18.0 * np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]])
    for quadrant, corner in enumerate(corner_centers):
        arc = local[1 + 29 * quadrant : 1 + 29 * (quadrant + 1)]
        assert_allclose(np.linalg.norm(arc - corner, axis=1), 5.0, rtol=0, atol=1e-12)
        assert max_sagitta(arc, corner, 5.0) <= 0.002 + 1e-12
    # straight sides are single segments between the arcs, exactly on the offset lines
    assert_allclose(local[[0, 1, -2, -1], 0], 23.0, rtol=0, atol=1e-12)       # the +u side: start, arc ends
    assert_allclose(local[[29, 30], 1], 23.0, rtol=0, atol=1e-12)             # the +v side
    assert signed_area(contour) > 0


def test_sharp_square_on_the_outline_and_its_direction() -> None:
    climb = tool_center_contour(np.zeros(2), SquareShape(30.0), Side.ON, Direction.CLIMB, 6.0,
                                tolerance=DEFAULT_TOLERANCE)
    # ON runs as an outside contour: climb is clockwise seen from the spindle (negative area in u, v)
    assert_allclose(climb, [[15, 0], [15, -15], [-15, -15], [-15, 15], [15, 15], [15, 0]], rtol=0, atol=0)
    assert signed_area(climb) == pytest.approx(-900.0, abs=1e-9)


def test_inside_square_with_corner_radius_equal_to_the_tool_radius_has_sharp_centre_corners() -> None:
    contour = tool_center_contour(np.zeros(2), SquareShape(40.0, corner_radius=3.0), Side.INSIDE, Direction.CLIMB, 6.0,
                                  tolerance=DEFAULT_TOLERANCE)
    assert_allclose(contour, [[17, 0], [17, 17], [-17, 17], [-17, -17], [17, -17], [17, 0]], rtol=0, atol=0)
    assert signed_area(contour) > 0                                           # climb inside: counter-clockwise


def test_square_that_is_a_circle_has_no_zero_length_sides() -> None:
    contour = tool_center_contour(np.zeros(2), SquareShape(20.0, corner_radius=10.0), Side.ON, Direction.CLIMB, 6.0,
                                  tolerance=DEFAULT_TOLERANCE)
    assert np.all(np.linalg.norm(np.diff(contour, axis=0), axis=1) > 1e-6)
    assert_allclose(np.linalg.norm(contour, axis=1), 10.0, rtol=0, atol=1e-12)


def test_rotated_square_starts_at_the_rotated_side_middle() -> None:
    rotation = math.radians(30.0)
    contour = tool_center_contour(
        np.array([1.0, 2.0]), SquareShape(30.0, rotation=rotation), Side.ON, Direction.CLIMB, 6.0
    , tolerance=DEFAULT_TOLERANCE)
    assert_allclose(contour[0], [1.0 + 15.0 * math.cos(rotation), 2.0 + 15.0 * math.sin(rotation)], rtol=0, atol=1e-12)
    corner = np.array([math.cos(rotation) + math.sin(rotation), math.sin(rotation) - math.cos(rotation)])
    assert_allclose(contour[1], [1.0, 2.0] + 15.0 * corner, atol=1e-12)


@pytest.mark.parametrize(
    ("side", "direction", "clockwise"),
    [
        (Side.OUTSIDE, Direction.CLIMB, True),
        (Side.ON, Direction.CLIMB, True),
        (Side.INSIDE, Direction.CLIMB, False),
        (Side.OUTSIDE, Direction.CONVENTIONAL, False),
        (Side.ON, Direction.CONVENTIONAL, False),
        (Side.INSIDE, Direction.CONVENTIONAL, True),
    ],
)
def test_lap_direction_in_the_toolpath(side: Side, direction: Direction, clockwise: bool) -> None:
    path = plan_profile(
        FACE, np.zeros(2), RoundShape(30.0), profile_params(side=side, direction=direction, depth=2.0), CUT
    , tolerance=DEFAULT_TOLERANCE)
    lap = face_uvw(path)[[i for i, name in enumerate(labels(path)) if name.endswith("lap")]]
    start = face_uvw(path)[[i for i, name in enumerate(labels(path)) if name.endswith("plunge")]]
    area = signed_area(np.concatenate([start[:, :2], lap[:, :2]]))
    assert (area < 0) == clockwise


# ------------------------------------------------------------------------------------------------
# Profile toolpaths
# ------------------------------------------------------------------------------------------------
def rows_labelled(path: Toolpath, suffix: str) -> np.ndarray:
    return np.array([i for i, name in enumerate(labels(path)) if name.endswith(suffix)], dtype=np.int64)


def test_plunge_profile_passes_sit_at_the_programmed_depths() -> None:
    path = plan_profile(FACE, np.zeros(2), SquareShape(30.0), profile_params(), CUT, tolerance=DEFAULT_TOLERANCE)
    uvw = face_uvw(path)
    assert len(path) == 3 + 3 * (1 + 5) + 2                                   # approach+face, 3×(plunge+lap), out
    # feed moves of a profile sit at the programmed depth: w = −d_k exactly on every lap row
    for k, depth in enumerate([2.0, 4.0, 5.0], start=1):
        lap = np.array([i for i, name in enumerate(labels(path)) if name == f"square pass {k}/3 lap"])
        assert len(lap) == 5
        assert_allclose(uvw[lap, 2], -depth, rtol=0, atol=1e-12)
        assert_allclose(path.feed[lap], 600.0, rtol=0, atol=0)
        assert_allclose(uvw[lap[-1], :2], [15.0, 0.0], atol=1e-12)           # each lap closes at the start
        plunge = np.array([i for i, name in enumerate(labels(path)) if name == f"square pass {k}/3 plunge"])
        assert_allclose(uvw[plunge], [[15.0, 0.0, -depth]], rtol=0, atol=1e-12)
        assert_allclose(path.feed[plunge], 200.0, rtol=0, atol=0)
    assert_allclose(uvw[:3], [[15, 0, 10], [15, 0, 2], [15, 0, 0]], rtol=0, atol=1e-12)   # retract, clearance, face
    assert labels(path)[:3] == ["square approach", "square approach", "square down to face"]
    assert_allclose(uvw[-2:], [[15, 0, 2], [15, 0, 10]], rtol=0, atol=1e-12)
    assert_common_rows(path)
    comments = [(e.before, e.text) for e in path.events if e.kind is EventKind.COMMENT]
    assert comments == [
        (0, "square 30.000 mm at (u 0.000, v 0.000) with tool Ø6.000 on face 0: on, climb (clockwise), "
            "plunge entry, depth 5.000 mm in 3 passes"),
        (3, "square pass 1/3 at depth 2.000 mm"),
        (9, "square pass 2/3 at depth 4.000 mm"),
        (15, "square pass 3/3 at depth 5.000 mm"),
    ]
    assert [e.kind for e in path.events[-2:]] == [EventKind.COOLANT_OFF, EventKind.SPINDLE_OFF]
    assert path.events[-1].before == len(path)


def test_square_profile_starts_at_the_papers_profile_point() -> None:
    path = plan_profile(FACE, np.zeros(2), SquareShape(30.0), profile_params(), CUT, tolerance=DEFAULT_TOLERANCE)
    face_row = int(rows_labelled(path, "down to face")[0])
    assert_allclose(face_uvw(path)[face_row], [15.0, 0.0, 0.0], rtol=0, atol=1e-12)
    # the paper's point is printed to 4 decimals and lies 2.7e-4 mm off the face (3.0e-4 mm in z)
    assert_allclose(path.tip[face_row], PAPER_2B_PART, atol=3.1e-4)
    assert_allclose(path.tip[face_row], [15.0 * math.cos(BETA), 200.0, 300.0 - 15.0 * math.sin(BETA)],
                    rtol=0, atol=1e-12)


def test_step_down_with_floating_error_makes_no_extra_pass() -> None:
    path = plan_profile(FACE, np.zeros(2), RoundShape(20.0), profile_params(depth=0.9, step_down=0.3), CUT,
                        tolerance=DEFAULT_TOLERANCE)
    assert labels(path)[-3] == "round pass 3/3 lap"
    assert_allclose(face_uvw(path)[rows_labelled(path, "3/3 lap"), 2], -0.9, rtol=0, atol=1e-12)


def test_ramp_entry_follows_the_contour_and_the_feature_ends_where_the_ramp_did() -> None:
    ramp_angle = math.radians(3.0)
    path = plan_profile(
        FACE, np.zeros(2), SquareShape(30.0), profile_params(entry=Entry.RAMP, ramp_angle=ramp_angle), CUT
    , tolerance=DEFAULT_TOLERANCE)
    uvw = face_uvw(path)
    names = labels(path)
    # pass 1 from (15, 0, 0): 2/tan 3° = 38.1623 mm clockwise: 15 mm down the +u side, 23.1623 along −v side
    ramp1 = rows_labelled(path, "pass 1/3 ramp")
    length1 = 2.0 / math.tan(ramp_angle)
    assert_allclose(uvw[ramp1], [[15.0, -15.0, -2.0 * 15.0 / length1], [15.0 - (length1 - 15.0), -15.0, -2.0]],
                    rtol=0, atol=1e-12)
    assert_allclose(path.feed[ramp1], 200.0, rtol=0, atol=0)
    for k, depth in enumerate([2.0, 4.0, 5.0], start=1):
        ramp, lap = rows_labelled(path, f"pass {k}/3 ramp"), rows_labelled(path, f"pass {k}/3 lap")
        previous = uvw[ramp[0] - 1]
        # the ramp descends linearly in arc length, at exactly 3° (no pass needs more than one lap)
        steps = np.linalg.norm(np.diff(np.concatenate([previous[None, :2], uvw[ramp, :2]]), axis=0), axis=1)
        drops = -np.diff(np.concatenate([[previous[2]], uvw[ramp, 2]]))
        assert_allclose(drops, steps * math.tan(ramp_angle), rtol=0, atol=1e-12)
        assert_allclose(uvw[ramp[-1], 2], -depth, rtol=0, atol=1e-12)
        # the lap is at depth and returns exactly to where the ramp ended
        assert_allclose(uvw[lap, 2], -depth, rtol=0, atol=1e-12)
        assert_allclose(uvw[lap[-1]], uvw[ramp[-1]], rtol=0, atol=1e-12)
        lap_uv = uvw[np.r_[ramp[-1], lap], :2]
        assert_allclose(np.sum(np.linalg.norm(np.diff(lap_uv, axis=0), axis=1)), 120.0, atol=1e-9)
    # the feature ends at the last lap's end, then goes straight up along +w
    end = uvw[rows_labelled(path, "pass 3/3 lap")[-1]]
    assert names[-2:] == ["square retract", "square retract"]
    assert_allclose(uvw[-2:], [[end[0], end[1], 2.0], [end[0], end[1], 10.0]], rtol=0, atol=1e-12)
    # ramps of 2, 2 and 1 mm: 2.5·38.1623 = 95.4056 mm clockwise from (15, 0), i.e. 20.4056 mm along +v side
    assert_allclose(end[:2], [-15.0 + (2.5 * length1 - 75.0), 15.0], rtol=0, atol=1e-12)
    assert_common_rows(path)


def test_ramp_longer_than_a_lap_is_steepened_and_says_so() -> None:
    # Ø10 on the outline: one lap is 31.416 mm (and a bit less as a polygon); 2 mm at 3° needs 38.162 mm
    path = plan_profile(FACE, np.zeros(2), RoundShape(10.0), profile_params(entry=Entry.RAMP, depth=2.0), CUT,
                        tolerance=DEFAULT_TOLERANCE)
    uvw = face_uvw(path)
    ramp = rows_labelled(path, "ramp")
    contour = tool_center_contour(np.zeros(2), RoundShape(10.0), Side.ON, Direction.CLIMB, 6.0,
                                  tolerance=DEFAULT_TOLERANCE)
    lap_length = float(np.sum(np.linalg.norm(np.diff(contour, axis=0), axis=1)))
    assert_allclose(uvw[ramp[-1]], [5.0, 0.0, -2.0], rtol=0, atol=1e-12)    # a whole lap down, back at the start
    assert_allclose(uvw[ramp, :2], contour[1:], rtol=0, atol=1e-12)
    steeper = math.degrees(math.atan2(2.0, lap_length))
    texts = [e.text for e in path.events if e.kind is EventKind.COMMENT]
    assert (f"round pass 1/1: ramp steepened to {steeper:.3f}° "
            f"(one lap is {lap_length:.3f} mm, 3.000° needs 38.162 mm)") in texts
    assert f"{steeper:.3f}" == "3.643"


def test_outside_profile_that_overshoots_the_face_edge() -> None:
    # square 40 at u = 40 on the outline: its +u side at u = 60, the tool reaches 63; edge at 55.9017
    with pytest.raises(FeatureError) as err:
        plan_profile(FACE, np.array([40.0, 0.0]), SquareShape(40.0), profile_params(), CUT, tolerance=DEFAULT_TOLERANCE)
    assert error_text(err.value) == (
        "square 40.000 mm at (u 40.000, v 0.000) with tool Ø6.000: does not fit on face 0: "
        "overshoots its edge by 7.098 mm; the largest that fits at (u 40.000, v 0.000) is 25.803 mm (--size 25.803); "
        "it fits at (u -5.902, v 0.000), where the face is widest (--at -5.902,0)"
    )
    with pytest.raises(FeatureError) as err:   # outside a Ø30 at u = 40: tool centre radius 18, reach 21 → u 61
        plan_profile(FACE, np.array([40.0, 0.0]), RoundShape(30.0), profile_params(side=Side.OUTSIDE), CUT,
                     tolerance=DEFAULT_TOLERANCE)
    assert error_text(err.value) == (
        "round Ø30.000 mm at (u 40.000, v 0.000) with tool Ø6.000: does not fit on face 0: "
        "overshoots its edge by 5.098 mm; the largest that fits at (u 40.000, v 0.000) is 19.803 mm (--diameter "
        "19.803); it fits at (u -5.902, v 0.000), where the face is widest (--at -5.902,0)"
    )


@pytest.mark.parametrize(
    ("shape", "message"),
    [
        (
            SquareShape(40.0, corner_radius=2.0),
            "--side inside: corner radius 2.000 mm is smaller than the tool radius 3.000 mm "
            "(use --corner-radius ≥ 3.000 or a smaller tool)",
        ),
        (
            SquareShape(40.0),
            "--side inside: corner radius 0.000 mm is smaller than the tool radius 3.000 mm "
            "(use --corner-radius ≥ 3.000 or a smaller tool)",
        ),
        (
            SquareShape(6.0, corner_radius=3.0),
            "--side inside: the tool Ø6.000 mm does not fit inside the square 6.000 mm "
            "(use a tool smaller than Ø6.000)",
        ),
        (
            RoundShape(6.0),
            "--side inside: the tool Ø6.000 mm does not fit inside the round Ø6.000 mm "
            "(use a tool smaller than Ø6.000)",
        ),
        (
            RoundShape(4.0),
            "--side inside: the tool Ø6.000 mm does not fit inside the round Ø4.000 mm "
            "(use a tool smaller than Ø4.000)",
        ),
    ],
)
def test_inside_profiles_the_tool_cannot_cut(shape: SquareShape | RoundShape, message: str) -> None:
    with pytest.raises(FeatureError) as err:
        plan_profile(FACE, np.zeros(2), shape, profile_params(side=Side.INSIDE), CUT, tolerance=DEFAULT_TOLERANCE)
    assert error_text(err.value) == message


def test_smallest_inside_round_still_plans() -> None:
    path = plan_profile(FACE, np.zeros(2), RoundShape(6.01), profile_params(side=Side.INSIDE, depth=1.0), CUT,
                        tolerance=DEFAULT_TOLERANCE)
    lap = face_uvw(path)[rows_labelled(path, "lap")]
    assert_allclose(np.linalg.norm(lap[:, :2], axis=1), 0.005, rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: SquareShape(0.0), "--size must be > 0 mm (got 0)"),
        (lambda: SquareShape(-5.0), "--size must be > 0 mm (got -5)"),
        (lambda: SquareShape(10.0, corner_radius=-1.0), "--corner-radius must be ≥ 0 mm (got -1)"),
        (
            lambda: SquareShape(10.0, corner_radius=6.0),
            "--corner-radius must be ≤ half the --size (got --corner-radius 6.000 mm > 5.000 mm)",
        ),
        (lambda: SquareShape(10.0, rotation=math.nan), "--rotation must be a finite angle (got nan)"),
        (lambda: RoundShape(0.0), "--diameter must be > 0 mm (got 0)"),
        (lambda: profile_params(depth=0.0), "--depth must be > 0 mm (got 0)"),
        (lambda: profile_params(depth=-1.0), "--depth must be > 0 mm (got -1)"),
        (lambda: profile_params(step_down=0.0), "--step-down must be > 0 mm (got 0)"),
        (lambda: profile_params(ramp_angle=0.0), "--ramp-angle must be > 0° and < 90° (got 0°)"),
        (lambda: profile_params(ramp_angle=math.pi / 2), "--ramp-angle must be > 0° and < 90° (got 90°)"),
        (lambda: profile_params(retract=1.0),
         "--retract must be ≥ --clearance (got --retract 1.000 mm < --clearance 2.000 mm)"),
        (
            lambda: plan_profile(FACE, np.zeros(2), RoundShape(10.0), profile_params(), CUT, tolerance=0.0),
            "--tolerance must be from 0.0001 mm (the resolution of the program) to 1 mm (got 0)",
        ),
        (
            lambda: plan_profile(FACE, np.zeros(3), RoundShape(10.0), profile_params(), CUT,
                                 tolerance=DEFAULT_TOLERANCE),
            "profile centre: expected a finite face point (u, v) in mm, got array([0., 0., 0.])",
        ),
    ],
)
def test_profile_options_refused(make: object, message: str) -> None:
    with pytest.raises(FeatureError) as err:
        make()  # type: ignore[operator]
    assert error_text(err.value) == message


@pytest.mark.parametrize(("call", "message"), [
    (lambda: pass_depths(1e6, 1e-6), "--depth 1e+06 mm in --step-down 1e-06 mm steps would take 1e+12 passes "
                                     "(at most 10000): use a larger --step-down"),
    (lambda: pass_depths(5.0, 1e-6, key="peck"), "--depth 5 mm in --peck 1e-06 mm steps would take 5e+06 passes "
                                                       "(at most 10000): use a larger --peck"),
])
def test_absurd_pass_counts_are_refused(call, message):
    with pytest.raises(FeatureError) as caught:
        call()
    assert error_text(caught.value) == message
    assert len(pass_depths(10_000.0, 1.0)) == 10_000                  # the limit itself is allowed


def test_overshoot_of_a_far_away_feature_terminates():
    """The overshoot bisection works to the float spacing at the feature's size, not only to 1e-6 mm
    (which a float near 1e10 cannot resolve: the search used to loop for ever)."""
    with pytest.raises(FeatureError) as caught:
        plan_holes(FACE, np.array([[1e10, 0.0]]), HoleParams(depth=5, peck=0, dwell=0, clearance=2, retract=10), CUT)
    assert error_text(caught.value).startswith(
        "hole 1 at (u 10000000000.000, v 0.000) with tool Ø6.000: does not fit on face 0: "
                                        "overshoots its edge by 99999999")


def test_absurd_lengths_are_refused():
    with pytest.raises(FeatureError) as caught:
        SquareShape(size=1e300)
    assert error_text(caught.value) == "--size must be ≤ 1e+06 mm (got 1e+300)"
