"""The paper's inverse kinematics (Patel & Patel 2020), kept for validation only.

The paper places the platform centre at M = tip + TL·a with no stage and computes each spherical
joint S_i on its own: the intersection of leg i's vertical plane {S·t_i = 0} with the circle of
radius r_p around M in the plane normal to a. Nothing ties the three S_i together, so they are not
r_p·√3 apart (288.7 / 307.4 / 303.0 mm in case 2a) and a rigid platform cannot take that pose. The
strokes and link angles then follow from eq. (1) of :mod:`prs3_post.kinematics.exact`.

Circle ∩ plane. The plane normal to a through M meets {S·t = 0} in a line with direction a × t. Its
point nearest to M is X0 = M − (t·M)·n/|n|², n = t − (t·a)·a (in the platform plane, ⊥ the line),
and S = X0 ± √(r_p² − |X0 − M|²)·(a × t)/|a × t|. Branch choice: the sign that puts S farther out
along e_i (the joint on the leg's own side of the platform). No intersection (|X0 − M| > r_p) or a
link that cannot reach makes the pose unreachable.
"""

from __future__ import annotations

import numpy as np

from prs3_post.config import Geometry
from prs3_post.kinematics.exact import IKResult, inverse_exact
from prs3_post.types import FloatArray


def paper_joints(geometry: Geometry, tip: FloatArray, axis: FloatArray) -> FloatArray:
    """The paper's spherical-joint centres, each leg on its own.

    Parameters
    ----------
    tip : (N, 3) float — mm, tool tip, machine frame (the paper has no stage)
    axis : (N, 3) float — unit tool axes

    Returns
    -------
    (N, 3, 3) float — mm, ``[:, i]`` is S_{i+1}; NaN where the circle misses leg i's plane
    """
    tip = np.asarray(tip, dtype=np.float64).reshape(-1, 3)
    axis = np.asarray(axis, dtype=np.float64).reshape(-1, 3)
    centre = tip + geometry.tool_length * axis
    joints = np.zeros((len(tip), 3, 3))
    for leg, alpha in enumerate(geometry.leg_azimuth):
        radial = np.array([np.cos(alpha), np.sin(alpha), 0.0])
        tangential = np.array([-np.sin(alpha), np.cos(alpha), 0.0])
        t_dot_a = axis @ tangential
        normal = tangential - t_dot_a[:, None] * axis                  # in platform plane, ⊥ line
        foot = centre - ((centre @ tangential) / (1.0 - t_dot_a**2))[:, None] * normal
        along = np.cross(axis, tangential)
        along /= np.linalg.norm(along, axis=1, keepdims=True)
        with np.errstate(invalid="ignore"):
            half_chord = np.sqrt(geometry.platform_radius**2 - np.sum((foot - centre) ** 2, axis=1))
        sign = np.where(along @ radial >= 0.0, 1.0, -1.0)                # farther out along e_i
        joints[:, leg] = foot + (sign * half_chord)[:, None] * along
    return joints


def inverse_paper(geometry: Geometry, tip: FloatArray, axis: FloatArray) -> IKResult:
    """The paper's IK: strokes and link angles from independently placed joints; stage X, Y = 0.

    ``condition`` is the exact model's at the same tip and axis (the paper's pose is not rigid).

    Parameters
    ----------
    tip : (N, 3) float — mm, tool tip, machine frame
    axis : (N, 3) float — unit tool axes

    Returns
    -------
    IKResult
    """
    joints = paper_joints(geometry, tip, axis)
    alpha = np.asarray(geometry.leg_azimuth)
    radial = joints[:, :, 0] * np.cos(alpha) + joints[:, :, 1] * np.sin(alpha)     # (N, 3)
    with np.errstate(invalid="ignore"):
        cos_t = (geometry.guide_radius - radial) / geometry.link_length
        reachable = np.all(np.abs(cos_t) <= 1.0, axis=1)
        link_angle = np.arccos(np.clip(cos_t, -1.0, 1.0))                      # clip: flagged above
        strokes = -joints[:, :, 2] - geometry.link_length * np.sin(link_angle)
    exact = inverse_exact(geometry, tip, axis)
    reachable &= exact.reachable
    stage = np.zeros((len(strokes), 2))
    for values in (stage, strokes, link_angle):
        values[~reachable] = np.nan
    return IKResult(
        stage=stage, strokes=strokes, link_angle=link_angle, condition=exact.condition, reachable=reachable
    )
