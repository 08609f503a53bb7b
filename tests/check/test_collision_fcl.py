"""The collision check's clearance against an independent library: python-fcl (the Flexible Collision
Library's exact distance between a cylinder and a triangle mesh) on the bodies as the check models them
(:func:`~prs3_post.check.collision_bodies.body_cylinders`: the tool, the holder and the spindle nose as
cylinders on the tool axis), at a few poses: a golden program's closest approach, a pose near contact,
and the holder beside a part's edge.

The tolerance, and why it is one-sided: our clearance is the smallest exact point–triangle distance over
points sampled on each body's surface (:func:`~prs3_post.check.collision_bodies.surface_points`: rings
every 2 mm, 24 points a ring, and rings on the end discs). Every sample lies on the body, so no sample
is closer to the part than the body is: ours ≥ fcl's. And the sample s nearest to the body point p that
fcl finds closest is at most |s − p| farther from the part than p is (the triangle inequality), so
ours ≤ fcl's + |s − p|. Each pose is asserted within exactly that band, widened by 1e-5 mm for fcl's own
iterative (GJK) solver, whose distances here agree with exact ones to about 2e-7 mm.

That band is the general guarantee, and it is wide (0.2 to 1.7 mm here) where a whole disc or a whole
generator line of a body is equally close, since fcl then names any point of it. Where the closest
feature is one a sample meets (a disc parallel to the face, the holder's side parallel to a wall's
edge), the two agree to the header's 0.001 mm as well; where it falls between samples (a tilted rim),
our clearance can be over by at most the rim's sagitta toward the face, r · sin(tilt) · (1 − cos 7.5°).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from prs3_post.app.verify import open_program
from prs3_post.check.collision_bodies import body_cylinders, frames, surface_points
from prs3_post.check.collision_distance import clearance
from prs3_post.core.toolpath import MoveKind
from prs3_post.core.types import FloatArray
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.machine.loading import load_machine
from prs3_post.part.stl import load_part

fcl = pytest.importorskip("fcl", reason="python-fcl is a test dependency: pip install -e '.[test]'")

REPO = Path(__file__).resolve().parents[2]
#: mm: fcl's solver tolerance (its distances are iterative; exact ones agree to about 2e-7 mm here).
FCL_SLACK_MM = 1e-5
MACHINE = load_machine("patel2020")
TOOL_LENGTH = MACHINE.geometry.tool_length - MACHINE.geometry.gauge_offset   # gauge line to tip, mm
assert MACHINE.holder is not None
CYLINDERS = body_cylinders(6.0, TOOL_LENGTH, MACHINE.holder)                 # the 6 mm tool, holder, nose


def _triangles(name: str) -> FloatArray:
    return np.asarray(load_part(REPO / "fixtures" / "parts" / name).triangles, dtype=np.float64)


def _fcl_distances(triangles: FloatArray, tip: FloatArray, axis: FloatArray) -> list[tuple[float, FloatArray]]:
    """Each body's distance from the part by fcl, and the body's point closest to it (part frame)."""
    model = fcl.BVHModel()
    model.beginModel(3 * len(triangles), len(triangles))
    model.addSubModel(triangles.reshape(-1, 3), np.arange(3 * len(triangles)).reshape(-1, 3))
    model.endModel()
    part = fcl.CollisionObject(model, fcl.Transform())
    x, y = frames(axis[None])
    rotation = np.column_stack([x[0], y[0], axis])                  # the cylinder's z along the tool axis
    found = []
    for radius, z0, z1 in CYLINDERS:
        body = fcl.CollisionObject(fcl.Cylinder(radius, z1 - z0), fcl.Transform(rotation, tip + axis * (z0 + z1) / 2))
        result = fcl.DistanceResult()
        distance = fcl.distance(part, body, fcl.DistanceRequest(enable_nearest_points=True), result)
        found.append((float(distance), np.asarray(result.nearest_points[1], dtype=np.float64)))
    return found


def _compare(triangles: FloatArray, tip: FloatArray, axis: FloatArray) -> list[tuple[float, float, float]]:
    """Per body: our clearance at the pose, fcl's, and the band's width |s − p| (module docstring)."""
    ours = clearance(triangles, tip[None], axis[None], CYLINDERS, None, np.zeros((0, 3)), clearance_min=200.0)
    assert ours.exact.all()                                          # measured on the samples, not bounded
    points, body = surface_points(CYLINDERS)
    x, y = frames(axis[None])
    samples = tip + points[:, :1] * x + points[:, 1:2] * y + points[:, 2:] * axis
    rows = []
    for b, (theirs, nearest) in enumerate(_fcl_distances(triangles, tip, axis)):
        gap = float(np.linalg.norm(samples[body == b] - nearest, axis=1).min())
        rows.append((float(ours.distance[b]), theirs, gap))
    return rows


def _assert_within_band(rows: list[tuple[float, float, float]]) -> None:
    for ours, theirs, gap in rows:
        assert theirs - FCL_SLACK_MM <= ours <= theirs + gap + FCL_SLACK_MM, (ours, theirs, gap)


def _poses(program_path: Path) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The end pose of every move of a program (part frame), and which are rapids."""
    context = open_program(str(program_path))
    moves = context.program.moves
    fk = kinematics_of(context.machine).forward(moves.strokes, moves.stage)
    return (context.setup.points_to_part(fk.tip), context.setup.axes_to_part(fk.axis),
            moves.kind == MoveKind.RAPID)


def test_a_golden_programs_closest_approach() -> None:
    """wedge-square-case2a: over its rapids' end poses the tool comes closest, 2 mm over the face (the
    retract plane); there every body agrees with fcl within the band."""
    tip, axis, rapid = _poses(REPO / "fixtures" / "golden" / "wedge-square-case2a.ngc")
    triangles = _triangles("wedge.stl")
    over_all = clearance(triangles, tip[rapid], axis[rapid], CYLINDERS, None, np.zeros((0, 3)), clearance_min=200.0)
    k = int(over_all.sample[over_all.worst()])
    rows = _compare(triangles, tip[rapid][k], axis[rapid][k])
    _assert_within_band(rows)
    np.testing.assert_allclose([r[1] for r in rows], [2.0, 22.0, 57.0], atol=1e-4)   # tool, holder, nose
    np.testing.assert_allclose([r[0] for r in rows], [r[1] for r in rows], atol=1e-3)  # discs parallel to the face


def test_a_pose_near_contact() -> None:
    """The same pose with the axis tilted 3° off the face normal, toward an azimuth between two of the
    rim's samples, and lowered until the tool's rim is 0.05 mm from the face."""
    tip, axis, rapid = _poses(REPO / "fixtures" / "golden" / "wedge-square-case2a.ngc")
    normal = axis[rapid][0]
    x, y = frames(normal[None])
    azimuth, tilt = np.radians(7.5 / 2 + 30.0), np.radians(3.0)
    tilted = np.cos(tilt) * normal + np.sin(tilt) * (np.cos(azimuth) * x[0] + np.sin(azimuth) * y[0])
    triangles = _triangles("wedge.stl")
    start = tip[rapid][1]
    first = _fcl_distances(triangles, start, tilted)[0][0]
    near = start - (first - 0.05) * normal
    rows = _compare(triangles, near, tilted)
    _assert_within_band(rows)
    assert rows[0][1] == pytest.approx(0.05, abs=1e-4)
    sagitta = CYLINDERS[0, 0] * np.sin(tilt) * (1 - np.cos(np.radians(7.5)))   # 0.0013 mm: 24 samples on the rim
    assert 0.0 <= rows[0][0] - rows[0][1] <= sagitta + FCL_SLACK_MM


def test_the_holder_beside_a_part_edge(tmp_path: Path) -> None:
    """wall30 face 4, a hole 15.735 mm from the wall (issue 20 §4.10): the holder's closest pose is
    beside the wall's edge, about 1 mm from it."""
    from click.testing import CliRunner

    from prs3_post.cli.main import main

    program = tmp_path / "wall.ngc"
    made = CliRunner().invoke(main, ["run", str(REPO / "fixtures" / "parts" / "wall30.stl"), "--face", "4",
                                     "--profile", "hole", "--at", "15.735,0", "--depth", "5", "--tool-diameter", "6",
                                     "-o", str(program)])
    assert made.exit_code == 0, made.output
    tip, axis, _ = _poses(program)
    triangles = _triangles("wall30.stl")
    holders = [_compare(triangles, t, a)[1] for t, a in zip(tip, axis, strict=True)]
    closest = min(holders, key=lambda row: row[1])
    for row in holders:
        _assert_within_band([row])
    assert closest[1] == pytest.approx(1.0, abs=2e-3)
    assert closest[0] == pytest.approx(closest[1], abs=1e-3)          # the side parallel to the edge: sampled
