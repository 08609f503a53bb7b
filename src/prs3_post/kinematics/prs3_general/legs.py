"""The constants of a general 3-PRS head that its kinematics use, as arrays (one row per leg).

Each leg's link moves in the plane through its revolute joint normal to the revolute axis r_i. In
that plane the link's direction is cos θ_i·u_i + sin θ_i·v_i, with v_i the rail direction d_i made
normal to r_i and u_i = r_i × v_i: θ_i is the link's angle from the plane normal to the rail. On
the ideal head d_i = −z and r_i = t_i, so u_i = −e_i, v_i = −z and θ_i is the link angle from
horizontal of DESIGN.md, S_i = (K − U cos θ_i)·e_i − (T_i + U sin θ_i)·z.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from prs3_post.core.types import FloatArray
from prs3_post.machine.model import GeneralGeometry

__all__ = ["LegArrays", "leg_arrays"]


@dataclass(frozen=True, slots=True)
class LegArrays:
    """A :class:`~prs3_post.machine.model.GeneralGeometry` as arrays; ``[i]`` is leg i + 1.

    Attributes
    ----------
    rail_point, rail_direction, revolute_axis : (3, 3) float — mm / unit, machine frame
    in_plane_u, in_plane_v : (3, 3) float — unit, the link's directions at θ = 0 and θ = 90° (u_i, v_i)
    link_length : (3,) float — mm
    platform_joint : (3, 3) float — mm, platform frame
    stroke_offset : (3,) float — mm
    rail_tilt : (3,) float — d_i·r_i, how far each rail leaves its leg's plane (0 on the ideal head)
    side : (3,) float — mm, |s_i − s_{i+1}|: the platform triangle's sides 12, 23, 31
    tool_tip, tool_axis : (3,) float — mm / unit, platform frame
    start_cos : (3,) float — cos θ_i of the untilted platform: where forward kinematics start
    """

    rail_point: FloatArray
    rail_direction: FloatArray
    revolute_axis: FloatArray
    in_plane_u: FloatArray
    in_plane_v: FloatArray
    link_length: FloatArray
    platform_joint: FloatArray
    stroke_offset: FloatArray
    rail_tilt: FloatArray
    side: FloatArray
    tool_tip: FloatArray
    tool_axis: FloatArray
    start_cos: FloatArray


#: Leg j of the pair that starts at leg i: the sides 12, 23, 31.
NEXT = [1, 2, 0]


@functools.lru_cache(maxsize=32)
def leg_arrays(general: GeneralGeometry) -> LegArrays:
    """The :class:`LegArrays` of ``general`` (kept for the last few heads: they are frozen).

    Raises
    ------
    ValueError
        A revolute axis parallel to its rail (the link's plane has no direction along the rail).
    """
    legs = general.legs
    point = np.array([leg.rail_point for leg in legs], dtype=np.float64)
    direction = np.array([leg.rail_direction for leg in legs], dtype=np.float64)
    axis = np.array([leg.revolute_axis for leg in legs], dtype=np.float64)
    tilt = np.einsum("ij,ij->i", direction, axis)
    along = direction - tilt[:, None] * axis
    norm = np.sqrt(np.einsum("ij,ij->i", along, along))
    if not (norm > 1e-6).all():
        raise ValueError("a revolute axis is parallel to its rail")
    v = along / norm[:, None]
    u = np.cross(axis, v)
    joint = np.array([leg.platform_joint for leg in legs], dtype=np.float64)
    link = np.array([leg.link_length for leg in legs], dtype=np.float64)
    side = np.sqrt(((joint - joint[NEXT]) ** 2).sum(axis=1))
    reach = np.hypot(point[:, 0], point[:, 1]) - np.hypot(joint[:, 0], joint[:, 1])
    start = np.clip(reach / link, -1.0, 1.0)
    return LegArrays(
        rail_point=point, rail_direction=direction, revolute_axis=axis, in_plane_u=u, in_plane_v=v,
        link_length=link, platform_joint=joint,
        stroke_offset=np.array([leg.stroke_offset for leg in legs], dtype=np.float64),
        rail_tilt=tilt, side=side,
        tool_tip=np.array(general.tool_tip, dtype=np.float64),
        tool_axis=np.array(general.tool_axis, dtype=np.float64),
        start_cos=np.where(np.isfinite(start), start, math.cos(math.radians(60.0))),
    )
