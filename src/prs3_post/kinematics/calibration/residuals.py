"""The model's predictions of measured poses, their residuals and the scaled identification Jacobian.

A row's residual is its tip error (mm, 3 values) and, when axes are measured, its axis error times
:data:`AXIS_LEVER_MM` (the tip error the same turn of the axis makes that far from the tip: 3
values, mm), so that every residual is a length with the measurement's noise. The Jacobian is taken
by central differences in the scaled parameters (all rows at once) of the closed-form leg equations
around the one forward kinematics (:func:`jacobian`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prs3_post.core.types import BoolArray, FloatArray
from prs3_post.kinematics.calibration.parameters import ErrorModel, Observations
from prs3_post.kinematics.calibration.parameters import rotation as rotation_matrix
from prs3_post.kinematics.prs3_general.forward import forward_general

__all__ = ["AXIS_LEVER_MM", "Prediction", "jacobian", "predict", "residual_vector", "rigid_fit"]

#: mm: a measured axis counts as two points this far apart on the tool (its residual is the axis
#: error in rad times this): a laser tracker's target on the tool, or a probe's two touches.
AXIS_LEVER_MM = 100.0
#: Scaled units: the central-difference step of the Jacobian (a thousandth of an expected error).
JACOBIAN_STEP = 1e-3


@dataclass(frozen=True, slots=True)
class Prediction:
    """Where the model puts N rows' tool, in the measurement frame.

    Attributes
    ----------
    tip : (N, 3) float — mm (stage applied)
    axis : (N, 3) float — unit
    converged : (N,) bool — forward kinematics found the pose
    """

    tip: FloatArray
    axis: FloatArray
    converged: BoolArray


def predict(model: ErrorModel, scaled: FloatArray, obs: Observations) -> Prediction:
    """The tips and axes the head ``model.head(scaled)`` reaches at the rows' strokes, in the
    measurement frame ``model.frame(scaled)``."""
    head = model.head(scaled)
    rotation, translation = model.frame(scaled)
    n = len(obs)
    tip, axis, converged = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n, dtype=bool)
    lengths, group = np.unique(obs.tool_length, return_inverse=True)
    for k, length in enumerate(lengths):                      # one forward kinematics per tool
        rows = np.flatnonzero(group == k)
        general = head.with_tool_length(float(length)).general_geometry()
        fk = forward_general(general, obs.strokes[rows], obs.stage[rows])
        tip[rows], axis[rows], converged[rows] = fk.tip, fk.axis, fk.converged
    return Prediction(tip=tip @ rotation.T + translation, axis=axis @ rotation.T, converged=converged)


def residual_vector(prediction: Prediction, obs: Observations) -> FloatArray:
    """(3N,) or (6N,) mm: the rows' tip errors, then (axes measured) their axis errors × AXIS_LEVER_MM
    (predicted − measured); a row forward kinematics cannot place counts 1 m in each value."""
    parts = [prediction.tip - obs.tip]
    if obs.has_axis:
        parts.append((prediction.axis - obs.axis) * AXIS_LEVER_MM)
    out = np.concatenate([p.ravel() for p in parts])
    return np.where(np.isfinite(out), out, 1000.0)


def jacobian(model: ErrorModel, scaled: FloatArray, obs: Observations, columns: list[int] | None = None,
             *, step: float = JACOBIAN_STEP) -> FloatArray:
    """(M, K) mm per scaled unit: the residuals' derivatives in the parameters ``columns`` (default all)
    at ``scaled``, rows as :func:`residual_vector` lays them out (0 for a row forward kinematics cannot place).

    Implicit differentiation, so that forward kinematics runs once: with the platform pose x (its
    origin and a small rotation, 6 values), the leg constraints g(x, p) = 0 (|S_i − C_i| = U_i,
    (S_i − C_i)·r_i = 0) and the measured quantities h(x, p) (tip and axis in the measurement frame),
    dh/dp = ∂h/∂p − ∂h/∂x·(∂g/∂x)⁻¹·∂g/∂p, every partial a central difference of closed-form
    expressions (parameters by ``step`` scaled units, the pose by :data:`POSE_STEP`).
    """
    columns = list(range(len(model.parameters))) if columns is None else columns
    base = np.asarray(scaled, dtype=np.float64)
    n = len(obs)
    pose = _platform_poses(model, base, obs)
    arrays = _arrays(model, base)
    dg_dx, dh_dx = np.zeros((n, 6, 6)), np.zeros((n, 6, 6))
    for j in range(6):
        sides = [_equations(arrays, _moved_pose(pose, j, sign * POSE_STEP), obs) for sign in (1.0, -1.0)]
        dg_dx[:, :, j] = (sides[0][0] - sides[1][0]) / (2.0 * POSE_STEP)
        dh_dx[:, :, j] = (sides[0][1] - sides[1][1]) / (2.0 * POSE_STEP)
    dg_dp, dh_dp = np.zeros((n, 6, len(columns))), np.zeros((n, 6, len(columns)))
    for k, column in enumerate(columns):
        sides = []
        for sign in (1.0, -1.0):
            moved = base.copy()
            moved[column] += sign * step
            sides.append(_equations(_arrays(model, moved), pose, obs))
        dg_dp[:, :, k] = (sides[0][0] - sides[1][0]) / (2.0 * step)
        dh_dp[:, :, k] = (sides[0][1] - sides[1][1]) / (2.0 * step)
    ok = pose[2]
    dx_dp = np.zeros((n, 6, len(columns)))
    if ok.any():
        dx_dp[ok] = np.linalg.solve(dg_dx[ok], dg_dp[ok])
    total = dh_dp - dh_dx @ dx_dp                                 # (n, 6: tip, axis × lever, K)
    total[~ok] = 0.0
    parts = [total[:, :3].reshape(3 * n, -1)]                     # rows: tip x, y, z of row 0, 1, ...
    if obs.has_axis:
        parts.append(total[:, 3:].reshape(3 * n, -1))
    return np.concatenate(parts) if columns else np.zeros((3 * n * (1 + obs.has_axis), 0))


#: mm and rad: the central-difference step of the platform pose in :func:`jacobian`.
POSE_STEP = 1e-5

_Pose = tuple[FloatArray, FloatArray, BoolArray]
_Arrays = tuple[FloatArray, ...]


def _platform_poses(model: ErrorModel, scaled: FloatArray, obs: Observations) -> _Pose:
    """The platform's origin (N, 3), rotation (N, 3, 3) and ``converged`` (N,) at the rows' strokes
    (the stage and tool do not move the platform)."""
    fk = forward_general(model.head(scaled).general_geometry(), obs.strokes)
    centre = np.where(fk.converged[:, None], fk.centre, 0.0)
    rotation = np.where(fk.converged[:, None, None], fk.rotation, np.eye(3))
    return centre, rotation, fk.converged


def _arrays(model: ErrorModel, scaled: FloatArray) -> _Arrays:
    """The head's and the frame's values the equations use: rail points, directions, revolute axes
    (3, 3), link lengths (3,), platform joints (3, 3), stroke offsets (3,), tool tip, tool axis (3,),
    the nominal tool length (a 1-array), the frame's rotation (3, 3) and translation (3,)."""
    general = model.head(scaled).general_geometry()
    legs = general.legs
    rotation, translation = model.frame(scaled)
    return (np.array([leg.rail_point for leg in legs]), np.array([leg.rail_direction for leg in legs]),
            np.array([leg.revolute_axis for leg in legs]), np.array([leg.link_length for leg in legs]),
            np.array([leg.platform_joint for leg in legs]), np.array([leg.stroke_offset for leg in legs]),
            np.array(general.tool_tip), np.array(general.tool_axis), np.array([model.nominal.tool_length]),
            rotation, translation)


def _moved_pose(pose: _Pose, j: int, amount: float) -> _Pose:
    """The poses with coordinate ``j`` moved by ``amount``: 0-2 the origin (mm), 3-5 a rotation about
    the machine's x, y, z (rad) applied after the platform's."""
    centre, rotation, ok = pose
    if j < 3:
        centre = centre.copy()
        centre[:, j] += amount
        return centre, rotation, ok
    vector = np.zeros(3)
    vector[j - 3] = amount
    return centre, rotation_matrix(vector) @ rotation, ok


def _equations(arrays: _Arrays, pose: _Pose, obs: Observations) -> tuple[FloatArray, FloatArray]:
    """The leg constraints g (N, 6: |S_i − C_i| − U_i, (S_i − C_i)·r_i) and the measured quantities
    h (N, 6: tip mm, axis × AXIS_LEVER_MM) of the platform poses ``pose`` under the values ``arrays``."""
    point, direction, revolute, link, joint, offset, tool_tip, tool_axis, length0, f_rot, f_shift = arrays
    centre, rotation, _ = pose
    revolute_centre = point[None] + (obs.strokes + offset)[:, :, None] * direction[None]      # (n, 3, 3)
    spherical = centre[:, None, :] + np.einsum("nij,lj->nli", rotation, joint)
    link_vector = spherical - revolute_centre
    g = np.concatenate([np.sqrt(np.sum(link_vector**2, axis=2)) - link,
                        np.einsum("nli,li->nl", link_vector, revolute)], axis=1)
    tip_platform = tool_tip[None] - (obs.tool_length - length0[0])[:, None] * tool_axis[None]
    tip = centre + np.einsum("nij,nj->ni", rotation, tip_platform)
    tip[:, :2] += obs.stage
    axis = rotation @ tool_axis
    h = np.concatenate([tip @ f_rot.T + f_shift, (axis @ f_rot.T) * AXIS_LEVER_MM], axis=1)
    return g, h


def rigid_fit(source: FloatArray, target: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The rotation (3, 3) and translation (3,) that best carry the points ``source`` (N, 3) onto
    ``target`` (N, 3) in least squares (Kabsch): target ≈ source @ R.T + t."""
    mean_s, mean_t = source.mean(axis=0), target.mean(axis=0)
    h = (source - mean_s).T @ (target - mean_t)
    u, _, vt = np.linalg.svd(h)
    sign = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    rotation = vt.T @ np.diag([1.0, 1.0, sign]) @ u.T
    return rotation, mean_t - rotation @ mean_s
