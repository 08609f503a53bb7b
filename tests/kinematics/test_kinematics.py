"""Kinematics: the paper's tables, the exact model's proofs, and the paper-vs-exact figures.

Numbers come from DESIGN.md ("The paper's numbers (checked)"), with the paper's typos corrected.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from prs3_post.core.defaults import LIMIT_TOLERANCE
from prs3_post.core.errors import LimitError
from prs3_post.kinematics import HEAD_XY_TOL, IKModel, PoseError, _named_problems, forward, inverse, unit_axes
from prs3_post.kinematics.protocol import tilt_of
from prs3_post.kinematics.prs3.exact import AxisMemo, inverse_exact, platform_centre_xy, spherical_joints
from prs3_post.kinematics.prs3.paper import inverse_paper, paper_joints
from prs3_post.machine.loading import load_machine
from prs3_post.post.limits import check_limits, raise_first_violation, within_limits

MACHINE = load_machine("patel2020")
GEO = MACHINE.geometry
AXIS_2A = np.array([0.447214, 0.0, 0.894427])
TIP_2A = np.array([-81.0264, 21.2132, -679.4865])
TIP_2B = np.array([-86.5836, 0.0, -676.7079])
TIPS = np.array([TIP_2A, TIP_2B])
AXES = unit_axes(TIPS, np.array([AXIS_2A, AXIS_2A]))

# ------------------------------------------------------------------ the paper's tables (paper model)

PAPER_JOINTS = np.array([
    [[-131.1507, -75.7199, -458.7683], [127.0333, -73.3427, -587.8606], [0.0, 194.3907, -524.3438]],
    [[-144.1769, -83.2405, -452.2552], [131.0382, -75.6549, -589.8631], [0.0, 172.9550, -524.3438]],
])
PAPER_THETA_DEG = np.array([[60.0586, 59.4042, 65.7949], [62.1014, 60.0407, 62.9687]])
PAPER_STROKES = np.array([[41.0978, 172.9648, 84.7195], [26.2745, 172.2674, 94.9981]])


def test_paper_model_reproduces_tables_2_and_3():
    result = inverse(GEO, TIPS, AXES, model=IKModel.PAPER)
    assert_allclose(result.strokes, PAPER_STROKES, atol=5e-4)
    assert_allclose(np.degrees(result.link_angle), PAPER_THETA_DEG, atol=1e-3)
    assert_allclose(paper_joints(GEO, TIPS, AXES), PAPER_JOINTS, atol=2e-4)
    assert_allclose(result.stage, 0.0, atol=0.0)


def test_paper_platform_centre_case_2a():
    # M = tip + TL a; the paper prints z -522.6918, a typo for -522.9618
    assert_allclose(TIP_2A + GEO.tool_length * AXES[0], [-2.7639, 21.2132, -522.9618], atol=1e-4)


def test_paper_joints_are_not_a_rigid_platform():
    joints = paper_joints(GEO, TIPS[:1], AXES[:1])[0]
    sides = [np.linalg.norm(joints[i] - joints[(i + 1) % 3]) for i in range(3)]
    assert_allclose(sides, [288.668, 303.073, 307.344], atol=1e-3)   # DESIGN: 288.7 / 303.0 / 307.4


# ------------------------------------------------------------------ paper vs exact (DESIGN.md figures)


def test_exact_stage_positions_for_cases_2a_2b():
    result = inverse(GEO, TIPS, AXES)
    assert_allclose(result.stage, [[-2.7639, 12.0703], [-8.3211, -9.1429]], atol=1e-4)
    assert result.reachable.all()


def test_paper_minus_exact_strokes():
    paper = inverse(GEO, TIPS, AXES, model=IKModel.PAPER)
    exact = inverse(GEO, TIPS, AXES)
    assert_allclose(paper.strokes - exact.strokes, [[4.87, 2.58, -4.23], [-7.17, 4.66, 8.82]], atol=5e-3)


def test_rigid_machine_driven_with_paper_strokes_tilts_the_tool():
    paper = inverse(GEO, TIPS, AXES, model=IKModel.PAPER)
    fk = forward(GEO, paper.strokes)
    assert fk.converged.all()
    error_deg = np.degrees(np.arccos(np.clip(np.sum(fk.axis * AXES, axis=1), -1, 1)))
    assert_allclose(error_deg, [2.27, 4.89], atol=5e-3)


# ------------------------------------------------------------------ exact model: round trip proofs


def poses_from(tilt_deg, azimuth_deg, tip):
    tilt, azimuth = np.radians(tilt_deg), np.radians(azimuth_deg)
    axis = np.column_stack([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)])
    return np.asarray(tip, dtype=np.float64).reshape(-1, 3), axis


# The test workspace: tilt <= 45 deg any azimuth, tip x, y in [-150, 150], z in [-750, -600] mm.
# Every pose in it respects every limit of patel2020 (asserted below, not assumed).
workspace = st.tuples(
    st.floats(0.0, 45.0),
    st.floats(0.0, 360.0),
    st.floats(-150.0, 150.0),
    st.floats(-150.0, 150.0),
    st.floats(-750.0, -600.0),
)


@settings(deadline=None, max_examples=300)
@given(workspace)
@example((45.0, 30.0, -150.0, 150.0, -750.0))      # worst condition number, extreme corner
@example((0.0, 0.0, 0.0, 0.0, -600.0))             # untilted: c = 1/2, no parasitic motion
def test_fk_of_ik_round_trip(pose):
    tilt, azimuth, x, y, z = pose
    tip, axis = poses_from(tilt, azimuth, [x, y, z])
    ik = inverse(GEO, tip, axis)
    assert check_limits(MACHINE, ik, axis).ok.all()
    fk = forward(GEO, ik.strokes, ik.stage)
    assert fk.converged.all()
    assert_allclose(fk.tip, tip, atol=1e-9)
    assert_allclose(fk.axis, axis, atol=1e-12)
    assert_allclose(fk.link_angle, ik.link_angle, atol=1e-10)
    # the rigid platform's joints stay in their legs' planes and 300 mm apart
    head_tip = tip - np.column_stack([ik.stage, np.zeros(1)])
    joints = spherical_joints(GEO, head_tip, axis)[0]
    for leg, alpha in enumerate(GEO.leg_azimuth):
        assert abs(joints[leg] @ [-math.sin(alpha), math.cos(alpha), 0.0]) <= 1e-9
    sides = [np.linalg.norm(joints[i] - joints[(i + 1) % 3]) for i in range(3)]
    assert_allclose(sides, 300.0, atol=1e-9)
    # and the legs (eq. 1 from the strokes and link angles) meet exactly those joints
    alpha = np.asarray(GEO.leg_azimuth)
    radius = GEO.guide_radius - GEO.link_length * np.cos(ik.link_angle[0])
    from_legs = np.column_stack([radius * np.cos(alpha), radius * np.sin(alpha),
                                 -ik.strokes[0] - GEO.link_length * np.sin(ik.link_angle[0])])
    assert_allclose(from_legs, joints, atol=1e-9)


def test_round_trip_in_bulk():
    rng = np.random.default_rng(7)
    n = 20000
    tip, axis = poses_from(rng.uniform(0, 45, n), rng.uniform(0, 360, n),
                           np.column_stack([rng.uniform(-150, 150, n), rng.uniform(-150, 150, n),
                                            rng.uniform(-750, -600, n)]))
    ik = inverse(GEO, tip, axis)
    fk = forward(GEO, ik.strokes, ik.stage, block_rows=4096)
    assert fk.converged.all()
    assert_allclose(fk.tip, tip, atol=1e-9)
    assert_allclose(fk.axis, axis, atol=1e-12)
    assert fk.iterations.max() <= 8
    assert fk.residual.max() < 1e-11


# ------------------------------------------------------------------ oracles: plain per-point versions


def scalar_ik(tip, axis):
    """Plain per-point exact IK straight from DESIGN.md (legs at 210/330/90 deg)."""
    ax, ay, az = axis
    rp, k, u, tl = GEO.platform_radius, GEO.guide_radius, GEO.link_length, GEO.tool_length
    px, py = rp * ax * ay / (1 + az), rp * (ax * ax - ay * ay) / (2 * (1 + az))
    centre = np.array([px, py, tip[2] + tl * az])
    v = np.cross([0.0, 0.0, 1.0], axis)
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    rot = np.eye(3) + vx + vx @ vx / (1 + az)
    strokes, angles = [], []
    for alpha in GEO.leg_azimuth:
        e = np.array([math.cos(alpha), math.sin(alpha), 0.0])
        s = centre + rp * rot @ e
        theta = math.acos((k - s @ e) / u)
        strokes.append(-s[2] - u * math.sin(theta))
        angles.append(theta)
    stage = [tip[0] - (px - tl * ax), tip[1] - (py - tl * ay)]
    return stage, strokes, angles


def scalar_jacobian(tip, axis, h=1e-6):
    """dT/d(M_z, r_p a_x, r_p a_y) by central differences, (3, 3)."""
    rp, tl = GEO.platform_radius, GEO.tool_length

    def strokes(p):
        mz, u, v = p
        ax, ay = u / rp, v / rp
        az = math.sqrt(1 - ax * ax - ay * ay)
        return np.array(scalar_ik([0.0, 0.0, mz - tl * az], [ax, ay, az])[1])

    p0 = np.array([tip[2] + tl * axis[2], rp * axis[0], rp * axis[1]])
    return np.column_stack([(strokes(p0 + d) - strokes(p0 - d)) / (2 * h) for d in np.eye(3) * h])


def scalar_condition(tip, axis):
    return np.linalg.cond(scalar_jacobian(tip, axis))


@pytest.mark.parametrize("n", [0, 1, 5000])
def test_vectorized_ik_equals_scalar_reference(n):
    rng = np.random.default_rng(n)
    tip, axis = poses_from(rng.uniform(0, 45, n), rng.uniform(0, 360, n),
                           np.column_stack([rng.uniform(-150, 150, n), rng.uniform(-150, 150, n),
                                            rng.uniform(-750, -600, n)]))
    result = inverse_exact(GEO, tip, axis, block_rows=777)      # odd block size: blocks must not matter
    assert result.strokes.shape == (n, 3) and result.stage.shape == (n, 2) and result.condition.shape == (n,)
    for i in range(n):
        stage, strokes, angles = scalar_ik(tip[i], axis[i])
        assert_allclose(result.stage[i], stage, atol=1e-9)
        assert_allclose(result.strokes[i], strokes, atol=1e-9)
        assert_allclose(result.link_angle[i], angles, atol=1e-12)
    for i in range(min(n, 200)):
        assert_allclose(result.condition[i], scalar_condition(tip[i], axis[i]), rtol=1e-5)


@pytest.mark.parametrize(("n", "tilt_deg", "reachable"), [(2, 30.0, True), (5000, 30.0, True), (5, 100.0, False)])
def test_constant_axis_block_gives_the_bits_of_row_by_row(n, tilt_deg, reachable):
    """A block whose rows share one axis (3+2 programs) computes the axis terms once: every value
    is the one each row gets alone, bit for bit (an axis pointing down: NaN, unreachable)."""
    rng = np.random.default_rng(n)
    tip, axis = poses_from(np.full(n, tilt_deg), np.full(n, 75.0),
                           np.column_stack([rng.uniform(-150, 150, n), rng.uniform(-150, 150, n),
                                            rng.uniform(-750, -600, n)]))
    together = inverse_exact(GEO, tip, axis, block_rows=777)
    mixed = axis.copy()
    mixed[::2] = unit_axes(tip[::2], np.tile([0.1, 0.2, 1.0], (len(mixed[::2]), 1)))   # no constant block
    alone = [inverse_exact(GEO, tip[i:i + 1], axis[i:i + 1]) for i in range(n)]
    for name in ("stage", "strokes", "link_angle", "condition", "reachable"):
        np.testing.assert_array_equal(getattr(together, name), np.concatenate([getattr(r, name) for r in alone]))
    assert (together.reachable == reachable).all()
    varying = inverse_exact(GEO, tip, mixed, block_rows=777)
    np.testing.assert_array_equal(varying.strokes[1::2], together.strokes[1::2])


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), sizes=st.lists(st.integers(1, 400), min_size=1, max_size=6),
       tilts=st.lists(st.sampled_from([0.0, 12.5, 30.0, 44.0, 60.0, 100.0]), min_size=1, max_size=3))
def test_axis_memo_gives_the_bits_of_each_chunk_alone(seed, sizes, tilts):
    """Chunks of a 3+2 program (one axis each, axes coming back, one pointing down, a chunk of
    varying axes among them) through one memo: every value is the chunk's own without the memo and
    each row's alone, bit for bit; a memo made for another geometry changes nothing either."""
    rng = np.random.default_rng(seed)
    memo = AxisMemo(GEO)
    head = dataclasses.replace(GEO, tool_length=GEO.tool_length + 25.0)
    for k, n in enumerate(sizes):
        tilt = tilts[k % len(tilts)]
        tip, axis = poses_from(np.full(n, tilt), np.full(n, 75.0),
                               np.column_stack([rng.uniform(-150, 150, n), rng.uniform(-150, 150, n),
                                                rng.uniform(-750, -600, n)]))
        if k == 2:                                     # one chunk whose axes vary
            axis = poses_from(rng.uniform(0, 40, n), rng.uniform(0, 360, n), tip)[1]
        geometry = head if k == 3 else GEO
        with_memo = inverse(geometry, tip, axis, memo=memo)
        alone = inverse(geometry, tip, axis)
        rows = [inverse(geometry, tip[i:i + 1], axis[i:i + 1]) for i in range(0, n, max(1, n // 7))]
        def bits(values):
            return np.ascontiguousarray(values).view(np.uint8)

        for name in ("stage", "strokes", "link_angle", "condition", "reachable"):
            got = getattr(with_memo, name)
            np.testing.assert_array_equal(bits(got), bits(getattr(alone, name)))
            np.testing.assert_array_equal(bits(got[::max(1, n // 7)]),
                                          bits(np.concatenate([getattr(r, name) for r in rows])))


def scalar_paper_ik(tip, axis):
    """The paper's method for one pose, as it reads: circle ∩ leg plane, with cross products."""
    rp, k, u = GEO.platform_radius, GEO.guide_radius, GEO.link_length
    centre = np.asarray(tip) + GEO.tool_length * np.asarray(axis)
    strokes, angles = [], []
    for alpha in GEO.leg_azimuth:
        e = np.array([math.cos(alpha), math.sin(alpha), 0.0])
        t = np.array([-math.sin(alpha), math.cos(alpha), 0.0])
        normal = t - (t @ axis) * axis
        foot = centre - (centre @ t) / (normal @ normal) * normal
        along = np.cross(axis, t)
        along /= np.linalg.norm(along)
        s = foot + math.copysign(1.0, along @ e) * math.sqrt(rp * rp - (foot - centre) @ (foot - centre)) * along
        theta = math.acos((k - s @ e) / u)
        strokes.append(-s[2] - u * math.sin(theta))
        angles.append(theta)
    return strokes, angles


@pytest.mark.parametrize("n", [0, 1, 5000])
def test_vectorized_paper_ik_equals_scalar_reference(n):
    rng = np.random.default_rng(n)
    tip, axis = poses_from(rng.uniform(0, 40, n), rng.uniform(0, 360, n),
                           np.column_stack([rng.uniform(-100, 100, n), rng.uniform(-100, 100, n),
                                            rng.uniform(-720, -640, n)]))
    result = inverse_paper(GEO, tip, axis, block_rows=777)     # odd block size: blocks must not matter
    assert result.strokes.shape == (n, 3) and result.stage.shape == (n, 2) and result.condition.shape == (n,)
    assert_allclose(result.condition, inverse_exact(GEO, tip, axis).condition, atol=0.0)
    exact_reach = inverse_exact(GEO, tip, axis).reachable
    for i in range(n):
        try:
            strokes, angles = scalar_paper_ik(tip[i], axis[i])
        except ValueError:                                  # sqrt or acos out of its domain: no joint
            assert not result.reachable[i] and np.isnan(result.strokes[i]).all()
            continue
        assert result.reachable[i] == exact_reach[i]
        if result.reachable[i]:
            assert_allclose(result.strokes[i], strokes, atol=1e-9)
            assert_allclose(result.link_angle[i], angles, atol=1e-12)
    assert result.reachable.sum() >= 0.9 * n


@pytest.mark.parametrize("n", [0, 1, 5000])
def test_paper_condition_and_reach_are_the_exact_models_bit_for_bit(n):
    """The paper model takes the exact model's condition and reachability from its axis part alone:
    the values of the whole exact IK, bit for bit, in any blocks (a constant-axis stretch, axes
    tilted past the exact model's reach, one pointing down)."""
    rng = np.random.default_rng(n + 1)
    tip, axis = poses_from(rng.uniform(0, 70, n), rng.uniform(0, 360, n),
                           np.column_stack([rng.uniform(-150, 150, n), rng.uniform(-150, 150, n),
                                            rng.uniform(-750, -600, n)]))
    if n > 1:
        axis[1000:2600] = axis[1000]                            # blocks of one axis (777 rows: two whole ones)
        axis[7] = -axis[7]                                      # pointing down: NaN, unreachable in both
    exact = inverse_exact(GEO, tip, axis)
    joints = paper_joints(GEO, tip, axis)
    radial = joints[:, :, 0] * np.cos(GEO.leg_azimuth) + joints[:, :, 1] * np.sin(GEO.leg_azimuth)
    with np.errstate(invalid="ignore"):
        own = (np.abs((GEO.guide_radius - radial) / GEO.link_length) <= 1.0).all(axis=1)
    for block_rows in (777, 65536):
        paper = inverse_paper(GEO, tip, axis, block_rows=block_rows)
        np.testing.assert_array_equal(paper.condition.view(np.uint64), exact.condition.view(np.uint64))
        np.testing.assert_array_equal(paper.reachable, own & exact.reachable)
    if n > 1:
        assert (own & ~exact.reachable).any() and (~own & exact.reachable).any() and exact.reachable.sum() > n / 2


def scalar_fk(strokes, guess):
    """Plain per-point FK: Newton with a finite-difference Jacobian on |S_i - S_j| = q."""
    k, u, q = GEO.guide_radius, GEO.link_length, GEO.platform_radius * math.sqrt(3)
    alpha = GEO.leg_azimuth

    def joints(theta):
        return [np.array([(k - u * math.cos(t)) * math.cos(a), (k - u * math.cos(t)) * math.sin(a),
                          -s - u * math.sin(t)]) for t, a, s in zip(theta, alpha, strokes, strict=False)]

    def residual(theta):
        j = joints(theta)
        return np.array([np.linalg.norm(j[i] - j[(i + 1) % 3]) - q for i in range(3)])

    theta = np.array(guess, dtype=float)
    for _ in range(50):
        r = residual(theta)
        if np.abs(r).max() < 1e-12:
            break
        jac = np.column_stack([(residual(theta + d) - residual(theta - d)) / 2e-7 for d in np.eye(3) * 1e-7])
        theta = theta - np.linalg.solve(jac, r)
    j = joints(theta)
    normal = np.cross(j[1] - j[0], j[2] - j[0])
    axis = normal / np.linalg.norm(normal)
    return sum(j) / 3 - GEO.tool_length * axis, axis


@pytest.mark.parametrize("n", [0, 1, 5000])
def test_vectorized_fk_equals_scalar_reference(n):
    rng = np.random.default_rng(100 + n)
    tip, axis = poses_from(rng.uniform(0, 40, n), rng.uniform(0, 360, n),
                           np.column_stack([np.zeros(n), np.zeros(n), rng.uniform(-750, -600, n)]))
    strokes = inverse(GEO, tip, axis).strokes + rng.uniform(-5.0, 5.0, (n, 3))   # not from any one pose
    result = forward(GEO, strokes, block_rows=999)
    assert result.tip.shape == (n, 3) and result.axis.shape == (n, 3) and result.converged.shape == (n,)
    assert result.converged.all()
    for i in range(0, n, 10):
        tip, axis = scalar_fk(strokes[i], result.link_angle[i] + 0.01)
        assert_allclose(result.tip[i], tip, atol=1e-8)
        assert_allclose(result.axis[i], axis, atol=1e-10)


# ------------------------------------------------------------------ condition number and singularity


def worst_condition(tilt_deg):
    tip, axis = poses_from(np.full(360, tilt_deg), np.arange(360.0), np.tile([0.0, 0.0, -680.0], (360, 1)))
    cond = inverse(GEO, tip, axis).condition
    return cond.max(), float(np.arange(360.0)[np.argmax(cond)])


def test_condition_numbers_of_design_md():
    assert_allclose(worst_condition(0.0)[0], math.sqrt(2), atol=1e-12)
    assert_allclose(worst_condition(35.0), (2.796019, 30.0), atol=1e-5)
    assert_allclose(worst_condition(45.0), (7.199175, 30.0), atol=1e-5)


def test_singularity_first_reached_at_49_82_deg_away_from_a_leg():
    def det_sign(tilt):
        tip, axis = poses_from([tilt], [30.0], [[0.0, 0.0, -680.0]])
        return np.sign(np.linalg.det(scalar_jacobian(tip[0], axis[0])))

    low, high = 45.0, 50.0
    assert det_sign(low) != det_sign(high)
    for _ in range(30):                                   # bisect the tilt where det J changes sign
        mid = 0.5 * (low + high)
        low, high = (mid, high) if det_sign(mid) == det_sign(45.0) else (low, mid)
    assert_allclose(low, 49.82, atol=5e-3)
    for azimuth in (30.0, 150.0, 270.0):
        tip, axis = poses_from([49.819], [azimuth], [[0.0, 0.0, -680.0]])
        assert inverse(GEO, tip, axis).condition[0] > 1e3
    tip, axis = poses_from([49.819], [90.0], [[0.0, 0.0, -680.0]])   # toward a leg: far from singular
    assert inverse(GEO, tip, axis).condition[0] < 10


# ------------------------------------------------------------------ head model, bad poses, non-assembly


def test_head_model_reports_the_missing_xy():
    head = load_machine("patel2020-head").geometry
    result = inverse(head, TIPS[:1], AXES[:1], model=IKModel.HEAD)
    assert not result.reachable[0]
    assert_allclose(result.stage[0], [-2.7639, 12.0703], atol=1e-4)
    # the pose whose tip is exactly where the head puts it is reachable
    on_target = TIPS[:1] - np.append(result.stage[0], 0.0)
    ok = inverse(head, on_target, AXES[:1], model=IKModel.HEAD)
    assert ok.reachable[0] and np.hypot(*ok.stage[0]) <= HEAD_XY_TOL
    assert_allclose(ok.strokes, inverse(GEO, TIPS[:1], AXES[:1]).strokes, atol=1e-9)


def test_parasitic_centre_matches_design_closed_form():
    _tip, axis = poses_from(np.array([10.0, 30.0, 45.0]), np.array([0.0, 77.0, 200.0]), np.zeros((3, 3)))
    ax, ay, az = axis.T
    expected = np.column_stack([GEO.platform_radius * ax * ay / (1 + az),
                                GEO.platform_radius * (ax**2 - ay**2) / (2 * (1 + az))])
    assert_allclose(platform_centre_xy(GEO, axis), expected, atol=1e-12)


def test_bad_poses_are_named_by_row():
    tip = np.array([[0, 0, -680], [np.nan, 0, -680], [0, 0, -680], [0, 0, -680], [0, 0, -680.0]])
    axis = np.array([[0, 0, 1], [0, 0, 1], [0, 0, 0], [0, 0.5, -1], [1, 0, 0.0]])
    with pytest.raises(PoseError) as caught:
        unit_axes(tip, axis)
    assert str(caught.value) == (
        "row 1: a value is NaN or infinite; row 2: the axis has zero length; "
        "rows 3, 4: the axis points away from the spindle (axis z must be > 0)"
    )


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), rows=st.integers(2, 60), scale=st.floats(1e-6, 1e6),
       bad=st.sampled_from(["none", "nan tip", "inf tip", "zero axis", "downward axis", "one row apart"]))
@example(seed=1, rows=2, scale=1.0, bad="none")
def test_unit_axes_of_one_axis_are_the_bits_and_errors_of_row_by_row(seed: int, rows: int, scale: float,
                                                                    bad: str) -> None:
    """A chunk whose rows share one axis (3+2) scales it once: the unit axes are each row's alone, bit
    for bit, and a bad chunk names the same rows with the same message as row by row."""
    rng = np.random.default_rng(seed)
    tip = rng.uniform(-500.0, 500.0, (rows, 3))
    axis = np.tile(rng.uniform(-1.0, 1.0, 3) * scale + [0.0, 0.0, 2.0 * scale], (rows, 1))
    row = int(rng.integers(rows))
    if bad == "nan tip":
        tip[row, 1] = np.nan
    elif bad == "inf tip":
        tip[row, 2] = -np.inf
    elif bad == "zero axis":
        axis[:] = 0.0
    elif bad == "downward axis":
        axis[:, 2] = -axis[:, 2]
    elif bad == "one row apart":                      # not one axis: the row-by-row path
        axis[row] = axis[row] * 2.0
    numbers = np.arange(rows) * 3 + 7
    try:
        alone = np.concatenate([unit_axes(tip[i:i + 1], axis[i:i + 1]) for i in range(rows)])
    except PoseError:
        with pytest.raises(PoseError) as together:
            unit_axes(tip, axis, row_name="line", row_numbers=numbers)
        with pytest.raises(PoseError) as plain:
            _named_problems(tip, axis, "line", numbers)
        assert str(together.value) == str(plain.value)
        assert bad != "none"
        return
    got = unit_axes(tip, axis, row_name="line", row_numbers=numbers)
    assert got.shape == (rows, 3)
    np.testing.assert_array_equal(got.view(np.int64), alone.view(np.int64))
    np.testing.assert_array_equal(got.view(np.int64), (axis / np.linalg.norm(axis, axis=1)[:, None]).view(np.int64))


def test_unreachable_pose_is_nan_not_garbage():
    short_links = dataclasses.replace(GEO, link_length=230.0)       # K - r_p = 218.8 mm: barely assembles
    tip, axis = poses_from([0.0, 20.0], [90.0, 90.0], [[0.0, 0.0, -680.0]] * 2)
    result = inverse(short_links, tip, axis)
    assert result.reachable.tolist() == [True, False]              # leg 3 would need cos θ > 1
    assert np.isnan(result.strokes[1]).all() and np.isnan(result.stage[1]).all()
    assert np.isnan(result.condition[1]) and np.isfinite(result.strokes[0]).all()


def test_fk_reports_strokes_that_do_not_assemble():
    # 2000 mm apart: no triangle of side 300 fits; 900: a platform fits, but not in the working mode
    result = forward(GEO, np.array([[0.0, 0.0, 2000.0], [0.0, 0.0, 900.0], [36.2244, 170.3886, 88.9519]]))
    assert result.converged.tolist() == [False, False, True]
    assert np.isnan(result.tip[:2]).all() and np.isnan(result.axis[:2]).all()
    assert result.iterations[0] == 30 and result.residual[0] > 1.0


# ------------------------------------------------------------------ limits fire exactly at the boundary


def _report_with(limits_change=None, stage_change=None):
    machine = MACHINE
    if limits_change:
        machine = dataclasses.replace(machine, limits=dataclasses.replace(machine.limits, **limits_change))
    if stage_change:
        machine = dataclasses.replace(machine, stage=dataclasses.replace(machine.stage, **stage_change))
    ik = inverse(GEO, TIPS[:1], AXES[:1])
    return check_limits(machine, ik, AXES[:1]), ik


def _past(bound, toward, angle=False):
    """``bound`` moved toward ``toward`` by twice LIMIT_TOLERANCE (in rad for an angle): a value at the old
    bound is beyond the new one by more than float noise."""
    step = 2.0 * (math.radians(LIMIT_TOLERANCE) if angle else LIMIT_TOLERANCE)
    return bound + math.copysign(step, toward - bound)


def _one_float(bound, toward, angle=False):
    """``bound`` moved one float toward ``toward``: a value at the old bound is beyond it by float noise."""
    return float(np.nextafter(bound, toward))


@pytest.mark.parametrize(("limit", "broken"), [
    ("stroke_max", ["T2 stroke"]), ("stroke_min", ["T1 stroke"]),
    ("link_min", ["θ1 link angle", "θ2 link angle"]),           # case 2a: θ1 = θ2 exactly (pose symmetric in x)
    ("link_max", ["θ3 link angle"]), ("tilt", ["tilt"]), ("condition", ["condition number"]),
    ("stage_x", ["stage X"]), ("stage_y", ["stage Y"]),
])
def test_each_limit_fires_exactly_at_its_boundary(limit, broken):
    """A value at a bound is inside; one float past it too (float noise, within LIMIT_TOLERANCE); past it by
    more than LIMIT_TOLERANCE it breaks that limit and only that one."""
    _, ik = _report_with()
    t2, t1 = ik.strokes[0, 1], ik.strokes[0, 0]
    th_max, th_min = ik.link_angle[0].max(), ik.link_angle[0].min()
    tilt = math.acos(AXES[0, 2])
    x, y = ik.stage[0]

    def changes(past):
        return {
            "stroke_max": {"stroke": (-100.0, past(t2, -np.inf))},
            "stroke_min": {"stroke": (past(t1, np.inf), 400.0)},
            "link_min": {"link_angle": (past(th_min, 9, True), 1.4)},
            "link_max": {"link_angle": (0.5, past(th_max, 0, True))},
            "tilt": {"max_tilt": past(tilt, 0, True)},
            "condition": {"max_condition": past(ik.condition[0], 0)},
            "stage_x": {"travel_x": (past(x, 9), 300.0)},
            "stage_y": {"travel_y": (-300.0, past(y, 0))},
        }[limit]

    key = "stage_change" if limit.startswith("stage") else "limits_change"
    inside, _ = _report_with(**{key: changes(lambda bound, toward, angle=False: bound)})
    noise, _ = _report_with(**{key: changes(_one_float)})
    outside, _ = _report_with(**{key: changes(_past)})
    assert inside.ok[0] and noise.ok[0] and not outside.ok[0]
    assert [outside.names[c] for c in np.flatnonzero(outside.margin[0] < 0)] == broken


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), rows=st.integers(0, 30), one_axis=st.booleans(), column=st.integers(0, 9),
       edge=st.sampled_from(["inside", "at the top", "past the top", "at the bottom", "past the bottom", "nan",
                             "inf", "-inf"]))
def test_within_limits_is_the_reports_ok_all(seed, rows, one_axis, column, edge):
    """The stream's quick test (each limit's least and greatest value) says what the report's ok.all()
    says: bounds at a column's extreme value or past it by more than LIMIT_TOLERANCE, NaN and ±inf among the
    values."""
    rng = np.random.default_rng(seed)
    tilt = np.full(rows, 20.0) if one_axis else rng.uniform(0.0, 40.0, rows)
    tip, axis = poses_from(tilt, np.full(rows, 75.0) if one_axis else rng.uniform(0, 360, rows),
                           np.column_stack([rng.uniform(-150, 150, rows), rng.uniform(-150, 150, rows),
                                            rng.uniform(-750, -600, rows)]))
    ik = inverse(GEO, tip, axis)
    machine = MACHINE
    if rows:
        group = {0: slice(0, 3), 1: slice(3, 6)}.get(column // 3, slice(column, column + 1))   # one bound's columns
        values = check_limits(MACHINE, ik, axis).value[:, group]
        top, bottom = float(values.max()), float(values.min())
        angle = 3 <= column < 7                        # link angles and tilt: rad
        bound = {"at the top": (-1e9, top), "past the top": (-1e9, _past(top, -np.inf, angle)),
                 "at the bottom": (bottom, 1e9), "past the bottom": (_past(bottom, np.inf, angle), 1e9)}.get(edge)
        if bound is not None:
            if column < 3:
                machine = dataclasses.replace(machine, limits=dataclasses.replace(machine.limits, stroke=bound))
            elif column < 6:
                machine = dataclasses.replace(machine, limits=dataclasses.replace(machine.limits, link_angle=bound))
            elif column in (6, 7) and edge.endswith("top"):
                key = "max_tilt" if column == 6 else "max_condition"
                machine = dataclasses.replace(machine, limits=dataclasses.replace(machine.limits, **{key: bound[1]}))
            elif column >= 8:
                key = "travel_x" if column == 8 else "travel_y"
                machine = dataclasses.replace(machine, stage=dataclasses.replace(machine.stage, **{key: bound}))
        if edge in ("nan", "inf", "-inf"):
            name, index = [("strokes", column % 3), ("link_angle", column % 3), ("condition", None),
                           ("stage", column % 2)][min(column // 3, 3)]
            changed = getattr(ik, name).copy()
            if index is None:
                changed[int(rng.integers(rows))] = float(edge)
            else:
                changed[int(rng.integers(rows)), index] = float(edge)
            ik = dataclasses.replace(ik, **{name: changed})
    within = within_limits(machine, ik, axis)
    with np.errstate(invalid="ignore"):                # inf − inf in the report's margins
        assert within == bool(check_limits(machine, ik, axis).ok.all())
    assert within == (edge in ("inside", "at the top", "at the bottom") or not rows
                      or (edge.startswith("past") and column in (6, 7) and edge.endswith("bottom")))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), rows=st.integers(2, 80), tilt=st.floats(0.0, 60.0))
def test_tilt_of_one_axis_is_each_rows_own_bit_for_bit(seed, rows, tilt):
    rng = np.random.default_rng(seed)
    _, axis = poses_from(np.full(rows, tilt), np.full(rows, rng.uniform(0, 360)), np.zeros((rows, 3)))
    alone = np.concatenate([tilt_of(axis[i:i + 1]) for i in range(rows)])
    np.testing.assert_array_equal(tilt_of(axis).view(np.int64), alone.view(np.int64))
    np.testing.assert_array_equal(tilt_of(axis).view(np.int64), np.arccos(np.clip(axis[:, 2], -1, 1)).view(np.int64))


def test_limit_error_message_names_step_limit_value_and_margin():
    report, _ = _report_with(limits_change={"stroke": (-100.0, 170.0)})
    with pytest.raises(LimitError) as caught:
        raise_first_violation(report, lambda row: "hole 1 feed")
    assert str(caught.value) == "hole 1 feed: T2 stroke 170.3886 mm is above the maximum 170.0000 mm by 0.3886 mm"
