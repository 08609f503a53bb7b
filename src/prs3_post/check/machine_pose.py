"""The 3-PRS machine's bodies at N joint rows, for pictures: the HTML view, the PNG preview, vismach.

    joints (N, 3), stage (N, 2) ──► the machine's forward kinematics ──► MachinePose (head frame)

Head frame (DESIGN.md): the base centre at the origin, z up, the platform below the base. Every
point here is the head's own, without the stage: the stage's (X, Y) is the head's offset from the
table, so a picture in the table's frame (where the part sits still) adds ``(X, Y, 0)`` to every
point (:meth:`MachinePose.on_table`); one in the machine's frame (the base still, the table moving)
draws the table and the part shifted by ``(−X, −Y, 0)``.

The legs come from the machine's as-built geometry when it has one (``[[legs]]``), else from the
ideal head's (:func:`prs3_post.machine.model.general_from_ideal`): each rail runs from the revolute
joint's place at the lowest stroke to its place at the highest, a slider sits at the row's stroke,
the link goes from there to the spherical joint, and the platform is the spherical joints' triangle.
The tool, the holder and the spindle nose are the collision check's cylinders on the tool axis
(:func:`prs3_post.check.collision_bodies.body_cylinders`). Pure numpy: no I/O, no plotting library,
and it imports under the system Python LinuxCNC's vismach runs in (numpy only).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prs3_post.check.collision_bodies import BODY_NAMES, body_cylinders
from prs3_post.core.types import BoolArray, FloatArray
from prs3_post.kinematics.registry import kinematics_of
from prs3_post.machine.loading import Machine
from prs3_post.machine.model import Holder, general_from_ideal

__all__ = ["BODY_NAMES", "DEFAULT_HOLDER", "MachinePose", "machine_pose"]

#: The holder and spindle nose drawn for a machine without a ``[holder]`` table (mm).
DEFAULT_HOLDER = Holder(holder_diameter=32.0, holder_length=40.0, nose_diameter=80.0, nose_length=60.0)


@dataclass(frozen=True, slots=True)
class MachinePose:
    """The machine at N joint rows, head frame (mm); J = 3 legs.

    Attributes
    ----------
    rails : (J, 2, 3) float — each rail, from the slider's place at the lowest stroke to the highest
    sliders : (N, J, 3) float — the revolute joints' centres (where the link meets its slider)
    spherical : (N, J, 3) float — the spherical joints' centres (the platform's corners)
    centre : (N, 3) float — the platform's centre (the corners' mean)
    tip : (N, 3) float — the tool tip, without the stage
    axis : (N, 3) float — unit, tip → spindle
    bodies : (B, 3) float — radius, start and end along the axis from the tip of the tool, the
        holder and the spindle nose (:data:`BODY_NAMES`)
    stage : (N, 2) float — the stage's X, Y
    converged : (N,) bool — False where the joints give no pose (every point of the row is NaN)
    """

    rails: FloatArray
    sliders: FloatArray
    spherical: FloatArray
    centre: FloatArray
    tip: FloatArray
    axis: FloatArray
    bodies: FloatArray
    stage: FloatArray
    converged: BoolArray

    def body_segments(self) -> FloatArray:
        """(N, B, 2, 3) float: each body's axis segment, bottom to top, head frame."""
        along = self.bodies[None, :, 1:, None] * self.axis[:, None, None, :]          # (N, B, 2, 3)
        return self.tip[:, None, None, :] + along

    def on_table(self, points: FloatArray) -> FloatArray:
        """``points`` (N, ..., 3) of this pose's rows moved into the table's frame (+ stage X, Y)."""
        shift = np.zeros((len(self.stage), 3))
        shift[:, :2] = self.stage
        return points + shift.reshape((len(shift),) + (1,) * (points.ndim - 2) + (3,))


def machine_pose(machine: Machine, joints: FloatArray, stage: FloatArray | None = None, *,
                 tool_diameter: float = 6.0) -> MachinePose:
    """The machine's bodies at joint rows ``joints`` (N, 3) mm and stage ``stage`` (N, 2) mm.

    ``tool_diameter``: mm, the drawn tool's diameter; the tool's length is the machine's
    (``tool_length − gauge_offset``: give ``machine`` with the program's tool for another).

    >>> from prs3_post.machine.loading import load_machine
    >>> pose = machine_pose(load_machine("patel2020"), np.array([[300.0, 300.0, 300.0]]))
    >>> (pose.tip[0].round(3) + 0.0).tolist(), (pose.sliders[0, 2].round(3) + 0.0).tolist()
    ([0.0, 0.0, -904.473], [0.0, 392.013, -300.0])
    """
    joints = np.asarray(joints, dtype=np.float64).reshape(-1, 3)
    stage = np.zeros((len(joints), 2)) if stage is None else np.asarray(stage, dtype=np.float64).reshape(-1, 2)
    geometry = machine.geometry
    general = geometry.general or general_from_ideal(geometry)
    point = np.array([leg.rail_point for leg in general.legs])                    # (J, 3)
    direction = np.array([leg.rail_direction for leg in general.legs])
    offset = np.array([leg.stroke_offset for leg in general.legs])
    low, high = machine.limits.stroke
    travel = np.array([low, high])[None, :, None] + offset[:, None, None]        # (J, 2, 1)
    rails = point[:, None, :] + travel * direction[:, None, :]
    sliders = point[None] + (joints + offset)[:, :, None] * direction[None]
    fk = kinematics_of(machine).forward(joints)
    sliders[~fk.converged] = np.nan
    holder = machine.holder or DEFAULT_HOLDER
    bodies = body_cylinders(tool_diameter, geometry.tool_length - geometry.gauge_offset, holder)
    return MachinePose(rails=rails, sliders=sliders, spherical=fk.joints, centre=fk.joints.mean(axis=1),
                       tip=fk.tip, axis=fk.axis, bodies=bodies, stage=stage, converged=fk.converged)
