"""The 3-PRS head as a :class:`~prs3_post.kinematics.protocol.Kinematics`: strokes T1, T2, T3 (letters U, V, W)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from prs3_post.core.types import FloatArray
from prs3_post.kinematics import AxisMemo, FKResult, IKModel, IKResult, forward, inverse
from prs3_post.kinematics.protocol import LimitColumns, tilt_of
from prs3_post.machine.model import Geometry, Limits

__all__ = ["Prs3Kinematics"]


@dataclass(frozen=True, slots=True)
class Prs3Kinematics:
    """The 3-PRS head of :mod:`prs3_post.kinematics.prs3` (exact, head and paper IK; Newton FK)."""

    geometry: Geometry
    name: ClassVar[str] = "3-prs"
    joint_names: ClassVar[tuple[str, ...]] = ("T1", "T2", "T3")
    default_letters: ClassVar[tuple[str, ...]] = ("U", "V", "W")
    #: The guides are parallel and vertical: adding s to every stroke moves the head by −s along z.
    shift_direction: ClassVar[tuple[float, float, float] | None] = (0.0, 0.0, -1.0)

    @property
    def link_length(self) -> float:
        """mm, "U": the link length."""
        return self.geometry.link_length

    def inverse(self, tip: FloatArray, axis: FloatArray, *, model: IKModel = IKModel.EXACT,
                memo: AxisMemo | None = None) -> IKResult:
        """:func:`prs3_post.kinematics.inverse`."""
        return inverse(self.geometry, tip, axis, model=model, memo=memo)

    def forward(self, joints: FloatArray, stage: FloatArray | None = None) -> FKResult:
        """:func:`prs3_post.kinematics.forward`."""
        return forward(self.geometry, joints, stage)

    def condition(self, tip: FloatArray, axis: FloatArray) -> FloatArray:
        """The actuator Jacobian's condition number (exact IK)."""
        return inverse(self.geometry, tip, axis, model=IKModel.EXACT).condition

    def limit_columns(self, limits: Limits, ik: IKResult, axis: FloatArray) -> LimitColumns:
        """Each stroke and each link angle (one bound for all three legs), the tilt, the condition number."""
        return [
            (tuple(f"{name} stroke" for name in self.joint_names), "mm", *limits.stroke, ik.strokes),
            (tuple(f"θ{leg + 1} link angle" for leg in range(3)), "deg", *limits.link_angle, ik.link_angle),
            (("tilt",), "deg", -math.inf, limits.max_tilt, tilt_of(axis)[:, None]),
            (("condition number",), "", -math.inf, limits.max_condition, ik.condition[:, None]),
        ]
