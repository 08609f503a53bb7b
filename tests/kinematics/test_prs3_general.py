"""The general 3-PRS head (each leg its own geometry): its FK and IK against the ideal closed form on
the ideal head, against the leg constraints themselves on a perturbed head, and round trips."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from prs3_post.core.errors import PoseError
from prs3_post.kinematics import IKModel, forward
from prs3_post.kinematics.prs3.exact import inverse_exact
from prs3_post.kinematics.prs3_general.forward import forward_general
from prs3_post.kinematics.prs3_general.inverse import inverse_general
from prs3_post.kinematics.prs3_general.kinematics import Prs3GeneralKinematics
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.machine.loading import load_machine
from prs3_post.machine.model import GeneralGeometry, general_from_ideal

IDEAL = load_machine("patel2020").geometry


def perturbed(general: GeneralGeometry) -> GeneralGeometry:
    """A head as built: every kind of parameter off by a few tenths (mm) or a tenth of a degree."""
    def unit(v: tuple[float, float, float], dx: float, dy: float, dz: float) -> tuple[float, float, float]:
        w = np.array(v) + np.array([dx, dy, dz])
        w /= np.linalg.norm(w)
        return (float(w[0]), float(w[1]), float(w[2]))

    l1, l2, l3 = general.legs
    l1 = dataclasses.replace(l1, rail_point=(l1.rail_point[0] + 0.3, l1.rail_point[1] - 0.1, 0.2),
                             revolute_axis=unit(l1.revolute_axis, 0.0015, 0.0, 0.001))
    l2 = dataclasses.replace(l2, link_length=l2.link_length - 0.2, stroke_offset=0.4,
                             rail_direction=unit(l2.rail_direction, 0.0017, -0.001, 0.0))
    l3 = dataclasses.replace(l3, platform_joint=(0.3, l3.platform_joint[1] - 0.2, 0.1),
                             rail_direction=unit(l3.rail_direction, 0.0, 0.0012, 0.0))
    return GeneralGeometry(legs=(l1, l2, l3), tool_tip=(0.1, -0.2, -175.3), tool_axis=unit((0, 0, 1), 0.001, 0, 0))


GENERAL = general_from_ideal(IDEAL)
BUILT = perturbed(GENERAL)


def poses(n: int, seed: int = 1, max_tilt_deg: float = 40.0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    tilt = rng.uniform(0.0, np.radians(max_tilt_deg), n)
    azimuth = rng.uniform(0.0, 2.0 * np.pi, n)
    axis = np.column_stack([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)])
    tip = np.column_stack([rng.uniform(-100, 100, n), rng.uniform(-100, 100, n), rng.uniform(-740, -620, n)])
    return tip, axis


def leg_errors(general: GeneralGeometry, strokes: np.ndarray, joints: np.ndarray) -> np.ndarray:
    """(N,) mm: the worst |S_i − A_i| − U_i and (S_i − A_i)·r_i, leg by leg in plain Python terms."""
    worst = np.zeros(len(strokes))
    for i, leg in enumerate(general.legs):
        revolute = np.array(leg.rail_point) + (strokes[:, i:i + 1] + leg.stroke_offset) * np.array(leg.rail_direction)
        link = joints[:, i] - revolute
        worst = np.maximum(worst, np.abs(np.linalg.norm(link, axis=1) - leg.link_length))
        worst = np.maximum(worst, np.abs(link @ np.array(leg.revolute_axis)))
    return worst


def test_general_from_ideal_is_the_ideal_head():
    leg = GENERAL.legs[0]
    assert_allclose(leg.rail_point, (-339.4932, -196.0065, 0.0), atol=1e-4)
    assert_allclose(leg.revolute_axis, (0.5, -np.sqrt(3) / 2, 0.0), atol=1e-15)
    assert_allclose(leg.platform_joint, (-150.0, -86.60254, 0.0), atol=1e-5)
    assert (leg.rail_direction, leg.link_length, leg.stroke_offset) == ((0.0, 0.0, -1.0), 482.0, 0.0)
    assert (GENERAL.tool_tip, GENERAL.tool_axis) == ((0.0, 0.0, -175.0), (0.0, 0.0, 1.0))


@pytest.mark.parametrize("n", [0, 1, 5000])
def test_fk_of_the_ideal_head_is_the_ideal_fk(n):
    strokes = np.random.default_rng(n).uniform(0.0, 200.0, (n, 3))
    stage = np.random.default_rng(n + 1).uniform(-50.0, 50.0, (n, 2))
    ideal, general = forward(IDEAL, strokes, stage), forward_general(GENERAL, strokes, stage)
    assert general.tip.shape == (n, 3) and general.rotation.shape == (n, 3, 3)
    assert (general.converged == ideal.converged).all()
    ok = ideal.converged
    assert_allclose(general.tip[ok], ideal.tip[ok], atol=1e-9)
    assert_allclose(general.axis[ok], ideal.axis[ok], atol=1e-12)
    assert_allclose(general.link_angle[ok], ideal.link_angle[ok], atol=1e-12)
    assert_allclose(general.joints[ok], ideal.joints[ok], atol=1e-9)
    assert (general.residual[ok] < 1e-11).all()


@pytest.mark.parametrize("n", [0, 1, 5000])
def test_ik_of_the_ideal_head_is_the_closed_form(n):
    tip, axis = poses(n)
    ideal, general = inverse_exact(IDEAL, tip, axis), inverse_general(GENERAL, tip, axis)
    assert general.strokes.shape == (n, 3) and general.stage.shape == (n, 2)
    assert (general.reachable == ideal.reachable).all() and ideal.reachable.all()
    assert_allclose(general.strokes, ideal.strokes, atol=1e-9)
    assert_allclose(general.stage, ideal.stage, atol=1e-9)
    assert_allclose(general.link_angle, ideal.link_angle, atol=1e-12)
    assert_allclose(general.condition, ideal.condition, rtol=1e-8)
    assert (general.iterations == 0).all()           # the closed form is already the answer
    assert_allclose(general.torsion, 0.0, atol=1e-15)


def test_ik_of_a_head_as_built_meets_every_leg_constraint_and_round_trips():
    tip, axis = poses(4000, seed=7)
    ik = inverse_general(BUILT, tip, axis)
    assert ik.reachable.all() and (ik.iterations <= 4).all() and (ik.residual < 1e-11).all()
    fk = forward_general(BUILT, ik.strokes, ik.stage)
    assert fk.converged.all()
    assert_allclose(fk.tip, tip, atol=1e-9)
    assert_allclose(fk.axis, axis, atol=1e-12)
    assert_allclose(fk.centre, ik.centre, atol=1e-9)
    assert leg_errors(BUILT, ik.strokes, fk.joints).max() < 1e-9
    # the head as built needs other strokes than the nominal one: tenths of a millimetre
    nominal = inverse_exact(IDEAL, tip, axis)
    assert 0.1 < np.abs(ik.strokes - nominal.strokes).max() < 3.0


def test_fk_of_a_head_as_built_meets_every_leg_constraint():
    strokes = np.random.default_rng(3).uniform(20.0, 200.0, (3000, 3))
    fk = forward_general(BUILT, strokes)
    ok = fk.converged
    assert ok.mean() > 0.9
    assert leg_errors(BUILT, strokes[ok], fk.joints[ok]).max() < 1e-9
    # the platform is rigid: its joints are the platform frame's points moved by (centre, rotation)
    platform = np.array([leg.platform_joint for leg in BUILT.legs])
    moved = fk.centre[ok, None, :] + np.einsum("nij,kj->nki", fk.rotation[ok], platform)
    assert_allclose(moved, fk.joints[ok], atol=1e-9)
    identity = np.broadcast_to(np.eye(3), (ok.sum(), 3, 3))
    assert_allclose(np.einsum("nij,nik->njk", fk.rotation[ok], fk.rotation[ok]), identity, atol=1e-12)
    tip = fk.centre[ok] + fk.rotation[ok] @ np.array(BUILT.tool_tip)
    assert_allclose(fk.tip[ok], tip, atol=1e-9)


@settings(deadline=None, max_examples=60)
@given(tilt=st.floats(0.0, 44.0), azimuth=st.floats(0.0, 360.0), x=st.floats(-150, 150), y=st.floats(-150, 150),
       z=st.floats(-760.0, -600.0))
def test_round_trip_property(tilt, azimuth, x, y, z):
    t, a = np.radians(tilt), np.radians(azimuth)
    axis = np.array([[np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), np.cos(t)]])
    tip = np.array([[x, y, z]])
    ik = inverse_general(BUILT, tip, axis)
    if not ik.reachable[0]:
        assert np.isnan(ik.strokes).all()
        return
    fk = forward_general(BUILT, ik.strokes, ik.stage)
    assert fk.converged[0]
    assert_allclose(fk.tip, tip, atol=1e-9)
    assert_allclose(fk.axis, axis, atol=1e-12)


def test_what_cannot_be_reached_is_nan_not_a_guess():
    ik = inverse_general(BUILT, np.array([[0.0, 0.0, -680.0], [0.0, 0.0, -680.0], [0.0, 0.0, -680.0]]),
                         np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]))
    assert ik.reachable.tolist() == [False, True, False]
    assert np.isnan(ik.strokes[[0, 2]]).all() and np.isnan(ik.condition[[0, 2]]).all()
    fk = forward_general(BUILT, np.array([[0.0, 0.0, 900.0], [50.0, 50.0, 50.0]]))
    assert fk.converged.tolist() == [False, True]
    assert np.isnan(fk.tip[0]).all() and np.isnan(fk.rotation[0]).all()


def test_registered_as_3_prs_general():
    machine = dataclasses.replace(load_machine("patel2020"), kinematics="3-prs-general")
    kin = kinematics_of(machine)
    assert isinstance(kin, Prs3GeneralKinematics) and kin.joint_names == ("T1", "T2", "T3")
    tip, axis = poses(50)
    assert_allclose(kin.inverse(tip, axis).strokes, inverse_exact(IDEAL, tip, axis).strokes, atol=1e-9)
    with pytest.raises(PoseError, match=r"^the paper's IK model exists for the ideal head only"):
        kin.inverse(tip, axis, model=IKModel.PAPER)
    head = kin.inverse(tip, axis, model=IKModel.HEAD)
    assert not head.reachable.any()                  # a tilted platform drifts: no stage, no pose


def test_another_tool_moves_the_tip_along_the_tool_axis():
    geometry = dataclasses.replace(IDEAL, general=BUILT)
    longer = geometry.with_tool_length(geometry.tool_length + 10.0)
    assert longer.general is not None
    assert_allclose(np.array(longer.general.tool_tip) - BUILT.tool_tip, -10.0 * np.array(BUILT.tool_axis), atol=1e-12)


@pytest.mark.parametrize(("shift", "deviation"), [(5.0, 7.621e-08), (50.0, 7.622e-06), (150.0, 6.863e-05)])
def test_a_common_stroke_change_on_rails_not_parallel_is_bounded_by_its_second_difference(shift, deviation):
    """On rails that are not parallel a common stroke change moves the head along them and turns it a
    little: the replay's bound of such a move (sampled at its end only when the bound is small) is
    SAFETY (2) times the tip's true deviation from its chord, here found on 401 samples."""
    from pathlib import Path

    from prs3_post.kinematics import replay

    machine = load_machine(str(Path(__file__).resolve().parents[2] / "fixtures" / "machines"
                               / "patel2020-as-built.toml"))
    kin = kinematics_of(machine)
    assert kin.shift_direction is None
    axis = np.array([[0.3, 0.1, 0.9]]) / np.linalg.norm([0.3, 0.1, 0.9])
    ik = kin.inverse(np.array([[0.0, 0.0, -680.0]]), axis)
    start = np.concatenate([ik.stage[0], ik.strokes[0]])
    joints = np.stack([start, start + np.array([10.0, 5.0, shift, shift, shift])])
    bound = replay.translation_bound(machine, joints, replay._poses(machine, joints))
    t = np.linspace(0.0, 1.0, 401)[:, None]
    samples = joints[0] + t * (joints[1] - joints[0])
    tip = kin.forward(samples[:, 2:], samples[:, :2]).tip
    true = np.linalg.norm(tip - (tip[0] + t * (tip[-1] - tip[0])), axis=1).max()
    assert true == pytest.approx(deviation, rel=1e-3)
    assert np.isnan(bound[0]) and true < bound[1] < 2.1 * true
