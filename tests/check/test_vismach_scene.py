"""The vismach model's scene is machine_pose's bodies (our FK), with the stage moving the table."""

from __future__ import annotations

import numpy as np
from numpy.testing import assert_allclose

from prs3_post.check.machine_pose import machine_pose
from prs3_post.check.vismach_scene import vismach_scene
from prs3_post.machine.loading import load_machine

#: The paper's case 2a: strokes and stage (DESIGN.md).
CASE_2A = np.array([36.2244, 170.3886, 88.9519])
STAGE_2A = np.array([-2.7639, 12.0703])


def test_the_head_is_machine_pose_s() -> None:
    machine = load_machine("patel2020")
    scene = vismach_scene(machine, CASE_2A, STAGE_2A)
    pose = machine_pose(machine, CASE_2A[None], STAGE_2A[None])
    ends = dict.fromkeys(scene.kinds)
    for kind in ends:
        ends[kind] = scene.cylinders[[k == kind for k in scene.kinds]]
    assert scene.kinds.count("rail") == 3 and scene.kinds.count("link") == 3
    assert_allclose(ends["rail"], pose.rails, atol=1e-12)
    assert_allclose(ends["link"][:, 0], pose.sliders[0], atol=1e-12)
    assert_allclose(ends["link"][:, 1], pose.spherical[0], atol=1e-12)
    assert_allclose(ends["tool"][0], pose.body_segments()[0, 0], atol=1e-12)
    assert_allclose(ends["spindle nose"][0], pose.body_segments()[0, 2], atol=1e-12)
    assert_allclose(scene.platform, pose.spherical[0], atol=1e-12)
    assert_allclose(scene.tip, pose.tip[0], atol=1e-12)
    # the head's tip is the paper's point 2a less the stage (the stage moves the part, not the head)
    assert_allclose(scene.tip + np.append(STAGE_2A, 0.0), [-81.0264, 21.2132, -679.4865], atol=2e-4)
    # the table and its top's centre move by (−X, −Y); the bed stays
    assert scene.box_kinds == ("bed", "saddle", "table")
    assert_allclose(scene.work, [2.7639, -12.0703, -970.0], atol=1e-12)
    table = scene.boxes[2]
    assert_allclose(table[1, :2] + table[0, :2], 2 * -STAGE_2A, atol=1e-9)
    assert_allclose(vismach_scene(machine, CASE_2A).boxes[0], scene.boxes[0], atol=0)


def test_the_tool_drawn_is_the_machine_s_tool() -> None:
    machine = load_machine("patel2020")
    longer = machine.with_tool_length(machine.geometry.gauge_offset + 80.0)
    short, long = vismach_scene(machine, CASE_2A), vismach_scene(longer, CASE_2A, tool_diameter=10.0)
    axis = machine_pose(machine, CASE_2A[None]).axis[0]
    assert_allclose(long.tip, short.tip - 25.0 * axis, atol=1e-9)      # 80 mm against the machine's 55 mm tool
    assert long.radii[long.kinds.index("tool")] == 5.0
    assert_allclose(long.platform, short.platform, atol=1e-12)          # the head itself does not move


def test_joints_without_a_pose_draw_no_head() -> None:
    scene = vismach_scene(load_machine("patel2020"), np.array([0.0, 400.0, -100.0]))
    assert not scene.converged
    assert scene.kinds == ("base", "rail", "rail", "rail")
    assert scene.spheres.shape == (0, 4)


def test_a_head_without_a_stage_has_a_fixed_bed() -> None:
    scene = vismach_scene(load_machine("patel2020-head"), np.array([300.0, 300.0, 300.0]), np.array([50.0, 0.0]))
    assert scene.box_kinds == ("bed",)
    assert_allclose(scene.work[:2], [0.0, 0.0], atol=0)
