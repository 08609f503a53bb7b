"""The calibration maths: the error model, its Jacobian (against plain finite differences of forward
kinematics), the identifiability analysis, the fit (with an unknown measurement frame) and the plan."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from prs3_post.kinematics.calibration.identify import identify, select_parameters
from prs3_post.kinematics.calibration.parameters import (
    ERROR_SIZES,
    Observations,
    error_model,
    parameter_names,
    rotation,
)
from prs3_post.kinematics.calibration.plan import plan_poses
from prs3_post.kinematics.calibration.residuals import AXIS_LEVER_MM, jacobian, predict, rigid_fit
from prs3_post.kinematics.prs3.forward import forward
from prs3_post.machine.loading import load_machine

MACHINE = load_machine("patel2020")


def _rows(strokes, *, tool_length=None, has_axis=True, tip=None, axis=None, stage=None):
    n = len(strokes)
    return Observations(strokes=np.asarray(strokes, dtype=float), stage=np.zeros((n, 2)) if stage is None else stage,
                        tool_length=np.full(n, MACHINE.geometry.tool_length) if tool_length is None else tool_length,
                        tip=np.full((n, 3), np.nan) if tip is None else tip,
                        axis=np.full((n, 3), np.nan) if axis is None else axis, has_axis=has_axis)


def _poses(count, seed):
    """``count`` stroke settings of the nominal head with the tool within 40° of vertical."""
    rng = np.random.default_rng(seed)
    strokes = rng.uniform(0.0, 300.0, (4 * count, 3))
    fk = forward(MACHINE.geometry, strokes)
    keep = fk.converged & (fk.axis[:, 2] > math.cos(math.radians(40.0)))
    return strokes[keep][:count]


def test_the_parameters_and_their_scales():
    model = error_model(MACHINE.geometry)
    assert model.names == parameter_names()
    assert len(model.names) == 41 and model.names[11] == "leg1.stroke_offset" and model.names[-1] == "tool_axis.y"
    assert [p.unit for p in model.parameters[:12]] == ["mm"] * 3 + ["deg"] * 4 + ["mm"] * 5
    assert_allclose(model.scales[:12], [0.5] * 3 + [math.radians(0.1)] * 4 + [0.2, 0.3, 0.3, 0.3, 0.5], atol=0)
    assert ERROR_SIZES["rail_point"] == 0.5
    # on the ideal head "radial" is outward and "tangential" is the revolute axis t_i
    p, q, d = model.bases[2, :3]
    assert_allclose([p, q, d], [[0, 1, 0], [-1, 0, 0], [0, 0, -1]], atol=1e-15)


def test_zero_parameters_are_the_nominal_head():
    model = error_model(MACHINE.geometry)
    strokes = _poses(50, 1)
    ours = predict(model, np.zeros(41), _rows(strokes))
    ideal = forward(MACHINE.geometry, strokes)
    assert ours.converged.all()
    assert_allclose(ours.tip, ideal.tip, atol=1e-9)
    assert_allclose(ours.axis, ideal.axis, atol=1e-12)


def test_a_stroke_offset_moves_the_tip_as_a_longer_stroke():
    model = error_model(MACHINE.geometry)
    u = np.zeros(41)
    u[11] = 1.0                                                # leg 1's encoder zero +0.5 mm
    strokes = _poses(5, 2)
    moved = predict(model, u, _rows(strokes)).tip
    longer = forward(MACHINE.geometry, strokes + np.array([0.5, 0.0, 0.0])).tip
    assert_allclose(moved, longer, atol=1e-9)


@pytest.mark.parametrize("fit_frame", [False, True])
def test_the_jacobian_is_the_derivative_of_forward_kinematics(fit_frame):
    """The implicit-differentiation Jacobian against central differences of whole forward kinematics."""
    model = error_model(MACHINE.geometry, fit_frame=fit_frame)
    if fit_frame:
        model = model.with_frame(rotation(np.array([0.3, -0.2, 1.0])), np.array([100.0, 20.0, -5.0]))
    rng = np.random.default_rng(3)
    u = rng.uniform(-1.0, 1.0, len(model.parameters))
    strokes = _poses(12, 4)
    obs = _rows(strokes, tool_length=rng.choice([175.0, 200.0], len(strokes)), stage=rng.uniform(-10, 10, (12, 2)))
    ours = jacobian(model, u, obs)
    columns = []
    for k in range(len(u)):
        sides = []
        for sign in (1.0, -1.0):
            moved = u.copy()
            moved[k] += sign * 1e-3
            p = predict(model, moved, obs)
            sides.append(np.concatenate([p.tip.ravel(), p.axis.ravel() * AXIS_LEVER_MM]))
        columns.append((sides[0] - sides[1]) / 2e-3)
    assert ours.shape == (72, len(u))
    assert_allclose(ours, np.column_stack(columns), atol=1e-7)


def test_rigid_fit_recovers_a_transform():
    rng = np.random.default_rng(5)
    points = rng.uniform(-500, 500, (20, 3))
    turn = rotation(np.array([0.1, 1.2, -0.4]))
    found_rotation, found_shift = rigid_fit(points, points @ turn.T + [1.0, 2.0, 3.0])
    assert_allclose(found_rotation, turn, atol=1e-12)
    assert_allclose(found_shift, [1.0, 2.0, 3.0], atol=1e-9)


def _held(model, found):
    return {model.names[h]: why for h, why in zip(found.held, found.combinations, strict=True)}


def test_what_no_measurement_separates():
    """On many poses with tips and axes, exactly the structural combinations are held: each rail point
    along its rail (the encoder zero), and six of the platform joints (the platform frame's placement,
    which the tool fixes too); without axes the tool axis too, which two tool lengths bring back."""
    model = error_model(MACHINE.geometry)
    strokes = _poses(300, 6)
    held = _held(model, select_parameters(model, jacobian(model, np.zeros(41), _rows(strokes)), noise=1e-9))
    assert held == {
        "leg1.rail_point.along_rail": "moves the tool like leg1.stroke_offset +1 mm/mm",
        "leg2.rail_point.along_rail": "moves the tool like leg2.stroke_offset +1 mm/mm",
        "leg3.rail_point.along_rail": "moves the tool like leg3.stroke_offset +1 mm/mm",
    } | {name: held[name] for name in ("leg1.platform_joint.z", "leg2.platform_joint.y", "leg2.platform_joint.z",
                                       "leg3.platform_joint.x", "leg3.platform_joint.y", "leg3.platform_joint.z")}
    tips = _held(model, select_parameters(model, jacobian(model, np.zeros(41), _rows(strokes, has_axis=False)),
                                          noise=1e-9))
    assert set(tips) - set(held) == {"tool_axis.x", "tool_axis.y"}
    assert tips["tool_axis.x"] == tips["tool_axis.y"] == "not seen by these measurements"
    two = _rows(np.tile(strokes, (2, 1)), has_axis=False, tool_length=np.repeat([175.0, 225.0], len(strokes)))
    assert set(_held(model, select_parameters(model, jacobian(model, np.zeros(41), two), noise=1e-9))) == set(held)


def test_identify_recovers_the_head_and_an_unknown_frame():
    """Noise-free tips and axes of a head with errors, measured in a frame turned 30° and shifted
    1 m: the fit finds the frame (up to the base's own small turn: the frame and the base share a
    gauge, and six base parameters are held) and every tip to 1e-6 mm; told the noise is 5 µm, it
    holds the combinations seen worse than that and still finds the tips to 0.001 mm."""
    rng = np.random.default_rng(7)
    model = error_model(MACHINE.geometry, fit_frame=True)
    true = np.zeros(47)
    true[:41] = rng.uniform(-1.0, 1.0, 41)
    turn, shift = rotation(np.array([0.0, 0.2, math.radians(30.0)])), np.array([1000.0, -200.0, 50.0])
    strokes = _poses(60, 8)
    measured = predict(model.with_frame(turn, shift), true, _rows(strokes))
    rows = _rows(strokes, tip=measured.tip, axis=measured.axis)
    exact = identify(model, rows, noise=1e-7)
    assert 0.1 < exact.before.tip_rms < 0.2               # the nominal head in its best rigid frame
    assert exact.after.tip_rms < 1e-6
    assert len(exact.identifiability.fitted) == 32 and exact.identifiability.weak == ()
    rotation_found, _ = exact.model.frame(exact.scaled)
    assert_allclose(rotation_found, turn, atol=5e-3)
    noisy = identify(model, rows, noise=0.005)
    assert noisy.after.tip_rms < 1e-3 and len(noisy.identifiability.weak) > 0


def test_plan_chooses_distinct_poses_and_predicts_uncertainties():
    model = error_model(MACHINE.geometry)
    strokes = _poses(400, 9)
    plan = plan_poses(model, _rows(strokes), 40, noise=0.005)
    assert len(plan.index) == len(set(plan.index.tolist())) == 40
    assert len(plan.identifiability.fitted) >= 24
    fitted = plan.std[plan.identifiability.fitted]
    assert np.isfinite(fitted).all() and (fitted < model.scales[plan.identifiability.fitted] / 3).all()
    random = plan_poses(model, _rows(strokes[:40]), 40, noise=0.005)         # every candidate: no choice
    assert plan.log_det > random.log_det
